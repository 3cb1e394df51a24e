#include "fuzz_common.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/poses.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz_file(data, size, ".csv");
  try {
    const pcdp::PoseTrack t = pcdp::io::read_pose_csv(path, pcdp::RpyOrder::kXyz);
    std::size_t hint = 0;
    if (!t.empty()) t.at(0.5 * (t.begin_stamp() + t.end_stamp()), hint);
    // The map origin of the track and the track relative to it (the pipeline's prepare).
    const pcdp::PoseTrack local = pcdp::shift_poses(t, pcdp::choose_map_origin(t));
    if (!local.empty()) local.at(0.5 * (local.begin_stamp() + local.end_stamp()), hint);
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
