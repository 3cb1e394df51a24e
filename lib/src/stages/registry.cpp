// The one explicit list of built-in stages. Adding a stage: one header, one source, one line here,
// one test file (docs/adding_a_stage.md).
#include <algorithm>

#include "pcdp/pipeline/stage.hpp"
#include "pcdp/stages/check_consistency.hpp"
#include "pcdp/stages/fuse_elevation.hpp"
#include "pcdp/stages/fuse_octomap.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/stages/reject_occlusion.hpp"

namespace pcdp {

const std::vector<StageInfo>& builtin_stages() {
  static const std::vector<StageInfo> stages = {
      register_stage_info(),
      reject_occlusion_stage_info(),
      reject_mixed_pixels_stage_info(),
      check_consistency_stage_info(),
      fuse_elevation_stage_info(),
      fuse_octomap_stage_info(),
  };
  return stages;
}

const StageInfo* find_stage(const std::string& type) { return find_stage(type, builtin_stages()); }

const StageInfo* find_stage(const std::string& type, const std::vector<StageInfo>& s) {
  auto it = std::find_if(s.begin(), s.end(), [&](const StageInfo& i) { return i.type == type; });
  return it == s.end() ? nullptr : &*it;
}

std::vector<std::string> stage_type_names() {
  std::vector<std::string> names;
  for (const auto& s : builtin_stages()) names.push_back(s.type);
  return names;
}

}  // namespace pcdp
