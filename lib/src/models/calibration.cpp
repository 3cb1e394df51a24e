#include "pcdp/models/calibration.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "pcdp/core/errors.hpp"

namespace pcdp {

RangeCalibration fit_range_calibration(const std::vector<double>& y, const std::vector<double>& z) {
  if (y.size() != z.size()) throw InputError("range calibration: as many true distances as measured ranges are needed");
  std::map<double, std::pair<double, std::size_t>> by_distance;  // y -> sum of z, count
  for (std::size_t i = 0; i < y.size(); ++i) {
    if (!std::isfinite(y[i]) || !std::isfinite(z[i]))
      throw InputError("range calibration: sample " + std::to_string(i + 1) + " is not finite");
    auto& e = by_distance[y[i]];
    e.first += z[i];
    ++e.second;
  }
  RangeCalibration c;
  c.samples = y.size();
  c.distances = by_distance.size();
  if (c.distances < 3)
    throw InputError("range calibration: needs samples at 3 or more distinct true distances, got " +
                     std::to_string(c.distances) + " (" + std::to_string(y.size()) +
                     " samples); with fewer the fit has no residual to estimate its errors from");
  std::vector<double> Y, M;
  for (const auto& [yi, e] : by_distance) {
    Y.push_back(yi);
    M.push_back(e.first / static_cast<double>(e.second));
  }
  const double n = static_cast<double>(Y.size());
  double ybar = 0, mbar = 0;
  for (std::size_t i = 0; i < Y.size(); ++i) {
    ybar += Y[i] / n;
    mbar += M[i] / n;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < Y.size(); ++i) {
    sxy += (Y[i] - ybar) * (M[i] - mbar);
    sxx += (M[i] - mbar) * (M[i] - mbar);
  }
  if (sxx <= 0) throw InputError("range calibration: the measured means do not vary");
  c.k = sxy / sxx;  // eq. 3
  c.b = ybar - c.k * mbar;
  double ss = 0;
  for (std::size_t i = 0; i < Y.size(); ++i) {
    const double res = Y[i] - (c.k * M[i] + c.b);
    ss += res * res;
    c.max_abs = std::max(c.max_abs, std::fabs(res));
  }
  c.rms = std::sqrt(ss / n);
  const double s2 = ss / (n - 2);
  c.se_k = std::sqrt(s2 / sxx);
  c.se_b = std::sqrt(s2 * (1.0 / n + mbar * mbar / sxx));
  return c;
}

namespace {
/// Least-squares plane through the points: unit normal n and offset d with n.p + d = 0.
void fit_plane(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::size_t>& idx, Eigen::Vector3d& n, double& d) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i : idx) c += pts[i];
  c /= static_cast<double>(idx.size());
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (std::size_t i : idx) S += (pts[i] - c) * (pts[i] - c).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(S);
  n = es.eigenvectors().col(0);
  d = -n.dot(c);
}
}  // namespace

MountCalibration calibrate_mount(const std::vector<Eigen::Vector3d>& pts, double yaw, RpyOrder order,
                                 const Eigen::Vector3d& expected_up_N, double max_tilt, double thr, double min_fraction) {
  MountCalibration m;
  m.points = pts.size();
  if (pts.size() < 100)
    throw InputError("calibrate-mount: no floor in view: only " + std::to_string(pts.size()) +
                     " valid returns (need at least 100 on the floor)");
  // RANSAC, deterministic.
  std::mt19937_64 rng(12345);
  std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
  std::size_t best = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0;
  for (int it = 0; it < 500; ++it) {
    const Eigen::Vector3d a = pts[pick(rng)], b = pts[pick(rng)], c = pts[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    const double d = -n.dot(a);
    std::size_t count = 0;
    for (const auto& p : pts) count += std::fabs(n.dot(p) + d) < thr;
    if (count > best) {
      best = count;
      best_n = n;
      best_d = d;
    }
  }
  std::vector<std::size_t> in;
  for (int pass = 0; pass < 3; ++pass) {  // refine: least squares on the inliers, twice re-selected
    in.clear();
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (std::fabs(best_n.dot(pts[i]) + best_d) < thr) in.push_back(i);
    if (in.size() < 3) break;
    fit_plane(pts, in, best_n, best_d);
  }
  m.inliers = in.size();
  if (static_cast<double>(in.size()) < min_fraction * static_cast<double>(pts.size()) || in.size() < 100)
    throw InputError("calibrate-mount: no floor in view: the largest plane holds " + std::to_string(in.size()) + " of " +
                     std::to_string(pts.size()) + " returns (need " + std::to_string(static_cast<int>(min_fraction * 100)) +
                     " % and 100); scan a flat floor with the vehicle on it");
  if (best_d < 0) {  // orient the normal up, towards the sensor: n.p + d = 0 with d = height > 0
    best_n = -best_n;
    best_d = -best_d;
  }
  if (best_d < 0.05)
    throw InputError("calibrate-mount: no floor in view: the largest plane passes through the sensor");
  const double tilt = std::acos(std::clamp(best_n.dot(expected_up_N.normalized()), -1.0, 1.0));
  if (tilt > max_tilt)
    throw InputError("calibrate-mount: no floor in view: the largest plane (" + std::to_string(in.size()) + " returns) is tilted " +
                     std::to_string(static_cast<int>(std::lround(tilt * 57.29577951308232))) +
                     " deg from the floor the configured mount implies (a wall?); scan a flat floor");
  double ss = 0;
  for (std::size_t i : in) ss += std::pow(best_n.dot(pts[i]) + best_d, 2);
  m.rms = std::sqrt(ss / static_cast<double>(in.size()));
  m.normal_N = best_n;
  m.height = best_d;
  // Roll and pitch such that R_VN n = e_z, with the given yaw.
  m.rpy.yaw = yaw;
  if (order == RpyOrder::kXyz) {  // R = Rx(f) Ry(t) Rz(p): with m = Rz(p) n, m_y = sin f, tan t = -m_x / m_z
    const Eigen::Vector3d q = rot_z(yaw) * best_n;
    m.rpy.roll = std::asin(std::clamp(q.y(), -1.0, 1.0));
    m.rpy.pitch = std::atan2(-q.x(), q.z());
  } else {  // R = Rz(p) Ry(t) Rx(f): Rx(f) n = (-sin t, 0, cos t)
    m.rpy.roll = std::atan2(best_n.y(), best_n.z());
    m.rpy.pitch = -std::asin(std::clamp(best_n.x(), -1.0, 1.0));
  }
  return m;
}

}  // namespace pcdp
