// The pose CSV of docs/data_contract.md ("Input 2"): header  stamp,x,y,z,roll,pitch,yaw  (s, m, rad in the
// pipeline's rpy_order), strictly increasing stamps, finite values, positions within +-1e8 m.
#pragma once

#include <string>

#include "pcdp/core/transforms.hpp"

namespace pcdp::io {

/// Throws InputError naming the file, the line (1-based, counting the header) and the column.
PoseTrack read_pose_csv(const std::string& path, RpyOrder order);

}  // namespace pcdp::io
