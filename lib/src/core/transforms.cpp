#include "pcdp/core/transforms.hpp"

#include <string>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>

#include "core/small_angle.hpp"

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

std::size_t PoseTrack::bracket_search(double stamp, std::size_t hint) const {
  const std::size_t n = samples_.size();
  // The same (checked inline by bracket()) or the next bracket as last time, else a search.
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
  // rounding (tests/unit/core/test_transforms.cpp).
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

void SegmentMotion::turn(double a, Weights& w) {
  if (std::fabs(a) <= detail::kSmallAngle) {
    w.sin_a = detail::sin_small(a);
    w.vers_a = detail::vers_small(a);
  } else {
    const double h = std::sin(0.5 * a);
    w.sin_a = std::sin(a);
    w.vers_a = 2.0 * h * h;  // 1 - cos(a) without cancellation
  }
}

SegmentMotion SegmentMotion::then(const Eigen::Isometry3d& T) const {
  SegmentMotion m = *this;
  m.R0 = R0 * T.linear();
  m.B = B * T.linear();
  m.C = C * T.linear();
  m.t0 = R0 * T.translation() + t0;
  m.tB = B * T.translation() + tB;
  m.tC = C * T.translation() + tC;
  return m;
}

SegmentMotion PoseTrack::motion(std::size_t k) const {
  assert(!samples_.empty());
  SegmentMotion m;
  const PoseSample& a = samples_[std::min(k, samples_.size() - 1)];
  m.stamp0 = a.stamp;
  m.R0 = a.orientation.toRotationMatrix();
  m.t0 = a.position;
  if (samples_.size() < 2) return m;  // one pose: fixed (duration 1, angle 0, no motion)
  const PoseSample& b = samples_[k + 1];
  m.duration = b.stamp - a.stamp;
  m.inv_duration = 1.0 / m.duration;
  m.dt = b.position - a.position;
  // The rotation from a to b, the shorter way round (as slerp takes it): axis n, angle phi.
  Eigen::Quaterniond rel = a.orientation.conjugate() * b.orientation;
  if (rel.w() < 0.0) rel.coeffs() = -rel.coeffs();
  const double nv = rel.vec().norm();
  if (nv > 0.0) {
    m.angle = 2.0 * std::atan2(nv, rel.w());
    const Eigen::Vector3d n = rel.vec() / nv;
    Eigen::Matrix3d K;
    K << 0.0, -n.z(), n.y(), n.z(), 0.0, -n.x(), -n.y(), n.x(), 0.0;
    m.B = m.R0 * K;
    m.C = m.B * K;
  }
  return m;
}

std::optional<Eigen::Quaterniond> unit_quaternion(double w, double x, double y, double z, double* norm) {
  const Eigen::Vector4d c(x, y, z, w);  // Eigen's coefficient order
  const double n = c.stableNorm();
  if (norm) *norm = n;
  if (!(n > 1e-9 && std::isfinite(n))) return std::nullopt;
  return Eigen::Quaterniond(Eigen::Vector4d(c / n));
}

}  // namespace pcdp
