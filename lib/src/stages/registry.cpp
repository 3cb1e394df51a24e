// The one explicit list of built-in stages. Adding a stage: one header, one source, one line in
// PCDP_BUILTIN_STAGES below, one test file (docs/adding_a_stage.md). Each entry `name` stands for
// the function `StageInfo name_stage_info()` of the stage's source; the list's order is the
// order of `pcd_pipeline stages` and of docs/stages.md.
#include <algorithm>

#include "pcdp/pipeline/stage.hpp"

#define PCDP_BUILTIN_STAGES(X) \
  X(register)                  \
  X(reject_occlusion)          \
  X(reject_mixed_pixels)       \
  X(check_consistency)         \
  X(fuse_elevation)            \
  X(fuse_octomap)              \
  /* one line per stage, above this one */

namespace pcdp {

#define PCDP_DECLARE_STAGE(name) StageInfo name##_stage_info();
PCDP_BUILTIN_STAGES(PCDP_DECLARE_STAGE)
#undef PCDP_DECLARE_STAGE

const std::vector<StageInfo>& builtin_stages() {
#define PCDP_STAGE_INFO(name) name##_stage_info(),
  static const std::vector<StageInfo> stages = {PCDP_BUILTIN_STAGES(PCDP_STAGE_INFO)};
#undef PCDP_STAGE_INFO
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
