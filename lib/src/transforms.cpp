#include "pcdp/transforms.hpp"

#include <string>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>

#include "small_angle.hpp"

namespace pcdp {

const char* rpy_order_name(RpyOrder o) { return o == RpyOrder::kXyz ? "xyz" : "zyx"; }

RpyOrder rpy_order_from_name(const std::string& name) {
  if (name == "xyz") return RpyOrder::kXyz;
  if (name == "zyx") return RpyOrder::kZyx;
  throw std::invalid_argument("rpy_order must be 'xyz' or 'zyx', not '" + name + "'");
}

Eigen::Matrix3d rot_x(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d r;
  r << 1, 0, 0, 0, c, -s, 0, s, c;
  return r;
}

Eigen::Matrix3d rot_y(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d r;
  r << c, 0, s, 0, 1, 0, -s, 0, c;
  return r;
}

Eigen::Matrix3d rot_z(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return r;
}

Eigen::Matrix3d rpy_to_matrix(const Rpy& rpy, RpyOrder order) {
  if (order == RpyOrder::kXyz) return rot_x(rpy.roll) * rot_y(rpy.pitch) * rot_z(rpy.yaw);
  return rot_z(rpy.yaw) * rot_y(rpy.pitch) * rot_x(rpy.roll);
}

Rpy matrix_to_rpy(const Eigen::Matrix3d& r, RpyOrder order) {
  Rpy out;
  constexpr double kLock = 1e-12;
  if (order == RpyOrder::kXyz) {
    // R = Rx(f) Ry(t) Rz(p): R02 = sin t, R00 = ct cp, R01 = -ct sp, R12 = -sf ct, R22 = cf ct.
    const double st = std::clamp(r(0, 2), -1.0, 1.0);
    out.pitch = std::asin(st);
    if (std::hypot(r(0, 0), r(0, 1)) > kLock) {
      out.yaw = std::atan2(-r(0, 1), r(0, 0));
      out.roll = std::atan2(-r(1, 2), r(2, 2));
    } else {  // cos(pitch) = 0: with yaw = 0, R10 = sf st and R11 = cf.
      out.yaw = 0.0;
      out.roll = std::atan2(r(1, 0) * st, r(1, 1));
    }
  } else {
    // R = Rz(p) Ry(t) Rx(f): R20 = -st, R21 = ct sf, R22 = ct cf, R10 = sp ct, R00 = cp ct.
    const double st = std::clamp(-r(2, 0), -1.0, 1.0);
    out.pitch = std::asin(st);
    if (std::hypot(r(0, 0), r(1, 0)) > kLock) {
      out.yaw = std::atan2(r(1, 0), r(0, 0));
      out.roll = std::atan2(r(2, 1), r(2, 2));
    } else {  // yaw = 0: R = Ry(t) Rx(f), R11 = cf, R12 = -sf.
      out.yaw = 0.0;
      out.roll = std::atan2(-r(1, 2), r(1, 1));
    }
  }
  return out;
}

Eigen::Isometry3d make_transform(const Eigen::Vector3d& t, const Rpy& rpy, RpyOrder order) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rpy_to_matrix(rpy, order);
  T.translation() = t;
  return T;
}

PoseSample interpolate(const PoseSample& a, const PoseSample& b, double s) {
  PoseSample out;
  out.stamp = a.stamp + s * (b.stamp - a.stamp);
  out.position = a.position + s * (b.position - a.position);
  out.orientation = a.orientation.slerp(s, b.orientation);  // Eigen takes the shorter arc
  return out;
}

PoseTrack::PoseTrack(std::vector<PoseSample> samples) : samples_(std::move(samples)) {
  for (std::size_t i = 1; i < samples_.size(); ++i) {
    assert(samples_[i].stamp > samples_[i - 1].stamp);
  }
  for (auto& s : samples_) s.orientation.normalize();
  for (std::size_t k = 1; k < samples_.size(); ++k) add_segment(k);
}

void PoseTrack::append(PoseSample s) {
  if (!samples_.empty() && !(s.stamp > samples_.back().stamp))
    throw std::invalid_argument("pose stamp " + std::to_string(s.stamp) + " is not after the last one " +
                                std::to_string(samples_.back().stamp));
  s.orientation.normalize();
  samples_.push_back(std::move(s));
  if (samples_.size() > 1) add_segment(samples_.size() - 1);
}

void PoseTrack::add_segment(std::size_t k) {  // the segment from sample k - 1 to sample k
  Segment g;
  g.dot = samples_[k - 1].orientation.dot(samples_[k].orientation);
  const double absd = std::fabs(g.dot);
  if (absd < 1.0 - Eigen::NumTraits<double>::epsilon()) {
    g.theta = std::acos(absd);
    g.sin_theta = std::sin(g.theta);
  }
  seg_.push_back(g);
}

std::size_t PoseTrack::bracket(double stamp, std::size_t hint) const {
  const std::size_t n = samples_.size();
  // Fast path: the same or the next bracket as last time.
  for (std::size_t i = hint; i < std::min(hint + 2, n - 1); ++i) {
    if (stamp >= samples_[i].stamp && stamp <= samples_[i + 1].stamp) return i;
  }
  auto it = std::upper_bound(samples_.begin(), samples_.end(), stamp,
                             [](double t, const PoseSample& p) { return t < p.stamp; });
  std::size_t i = static_cast<std::size_t>(it - samples_.begin());
  return i == 0 ? 0 : std::min(i - 1, n - 2);
}

double PoseTrack::gap_at(double stamp, std::size_t& hint) const {
  if (samples_.size() < 2) return 0.0;
  hint = bracket(stamp, hint);
  return samples_[hint + 1].stamp - samples_[hint].stamp;
}

Eigen::Isometry3d PoseTrack::at(double stamp, std::size_t& hint) const {
  assert(covers(stamp));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (samples_.size() == 1) {
    T.linear() = samples_[0].orientation.toRotationMatrix();
    T.translation() = samples_[0].position;
    return T;
  }
  hint = bracket(stamp, hint);
  const PoseSample& a = samples_[hint];
  const PoseSample& b = samples_[hint + 1];
  const double s = (stamp - a.stamp) / (b.stamp - a.stamp);
  // interpolate(a, b, s) with the segment's angle cached: the same arithmetic as Eigen's slerp
  // (Quaternion::slerp, Eigen 3.4), with small angles' sines by their series: the same result to
  // rounding (tests/unit/test_transforms.cpp).
  const Segment& g = seg_[hint];
  double scale0, scale1;
  if (std::fabs(g.dot) >= 1.0 - Eigen::NumTraits<double>::epsilon()) {
    scale0 = 1.0 - s;
    scale1 = s;
  } else if (g.theta <= detail::kSmallAngle) {
    // Nearby poses (the usual case: theta is half the rotation between two samples): the sines
    // by their series, equal to std::sin to rounding and several times cheaper.
    scale0 = detail::sin_small((1.0 - s) * g.theta) / g.sin_theta;
    scale1 = detail::sin_small(s * g.theta) / g.sin_theta;
  } else {
    scale0 = std::sin((1.0 - s) * g.theta) / g.sin_theta;
    scale1 = std::sin(s * g.theta) / g.sin_theta;
  }
  if (g.dot < 0.0) scale1 = -scale1;
  const Eigen::Quaterniond q(scale0 * a.orientation.coeffs() + scale1 * b.orientation.coeffs());
  T.linear() = q.toRotationMatrix();
  T.translation() = a.position + s * (b.position - a.position);
  return T;
}

}  // namespace pcdp
