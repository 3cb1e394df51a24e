// Georeferenced poses: the map origin of a run (docs/data_contract.md "Coordinates").
//
// A pose file may give positions anywhere a map frame reaches (UTM: x ~ 5e5 m, y ~ 5e6 m). The
// pipeline keeps every coordinate in double; its float32 products (returns.pcd, cloud.pcd) and
// map.bt store coordinates relative to a local map origin, which report.json states
// (`map_origin`) and the PCD files carry as the header comment "# map_origin X Y Z". The GeoTIFF stays
// absolute. The origin is chosen from the pose file alone:
//   - (0, 0, 0) when every pose lies within kNearZero of 0 on every axis (local frames, the
//     simulator, the sample: their outputs are those of a run without an origin);
//   - otherwise the centre of the poses' bounding box, each axis rounded to a multiple of
//     kOriginStep (a round number, exact in float32 and as text).
// The run registers relative to it: the pose positions minus the origin, in double, before any
// return is placed.
#pragma once

#include <Eigen/Core>
#include <string>

#include "pcdp/core/transforms.hpp"

namespace pcdp {

/// Poses within this of 0 on every axis (m) keep the origin at 0. Well inside the OctoMap's key
/// reach around the origin (+-3,276 m at 0.1 m leaves, +-1,638 m at 0.05 m), so that a track
/// that starts at 0 and drives a few km gets a centred origin rather than rays beyond the keys.
inline constexpr double kNearZero = 1000.0;
/// The origin's axes are multiples of this (m).
inline constexpr double kOriginStep = 1000.0;
/// float32 keeps a step of at most 1 mm (2^-10 m) below 2^14 m: products keep 1 mm within this
/// distance of the map origin (m).
inline constexpr double kFloat32MillimetreReach = 16384.0;

/// The map origin of a run with these poses (zero for an empty track).
Eigen::Vector3d choose_map_origin(const PoseTrack& poses);

/// The same track with every position moved by -origin (in double; orientations unchanged).
PoseTrack shift_poses(const PoseTrack& poses, const Eigen::Vector3d& origin);

/// The largest distance along one axis (m) between a pose and the origin.
double farthest_pose_offset(const PoseTrack& poses, const Eigen::Vector3d& origin);

/// "(x, y, z)" in metres with millimetres, for messages.
std::string format_point(double x, double y, double z);

}  // namespace pcdp
