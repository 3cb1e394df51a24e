#include "pcdp/core/georef.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace pcdp {

Eigen::Vector3d choose_map_origin(const PoseTrack& poses) {
  if (poses.empty()) return Eigen::Vector3d::Zero();
  Eigen::Vector3d lo = poses.samples().front().position, hi = lo;
  for (const PoseSample& s : poses.samples()) {
    lo = lo.cwiseMin(s.position);
    hi = hi.cwiseMax(s.position);
  }
  if (lo.minCoeff() >= -kNearZero && hi.maxCoeff() <= kNearZero) return Eigen::Vector3d::Zero();
  Eigen::Vector3d o;
  for (int a = 0; a < 3; ++a) o[a] = std::round((0.5 * lo[a] + 0.5 * hi[a]) / kOriginStep) * kOriginStep;
  return o + Eigen::Vector3d::Zero();  // (no -0.0)
}

PoseTrack shift_poses(const PoseTrack& poses, const Eigen::Vector3d& origin) {
  std::vector<PoseSample> s = poses.samples();
  for (PoseSample& p : s) p.position -= origin;
  return s.empty() ? PoseTrack{} : PoseTrack(std::move(s));
}

double farthest_pose_offset(const PoseTrack& poses, const Eigen::Vector3d& origin) {
  double far = 0.0;
  for (const PoseSample& s : poses.samples()) far = std::max(far, (s.position - origin).cwiseAbs().maxCoeff());
  return far;
}

std::string format_point(double x, double y, double z) {
  char b[128];
  std::snprintf(b, sizeof b, "(%.3f, %.3f, %.3f)", x, y, z);
  return b;
}

}  // namespace pcdp
