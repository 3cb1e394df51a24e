// Frames, roll-pitch-yaw and pose interpolation. This header owns the RPY convention: every
// rotation built from roll/pitch/yaw in the project goes through rpy_to_matrix().
//
// Frames (docs/data_contract.md): nod frame N (the laser on its nodding mount), vehicle frame V,
// map frame M (z against gravity). Transforms are named by frames: T_M_V maps vehicle
// coordinates into the map frame, so  p_M = T_M_V * T_V_N * p_N.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace pcdp {

/// Order of the elementary rotations in a roll-pitch-yaw triple.
enum class RpyOrder {
  /// R = Rx(roll) * Ry(pitch) * Rz(yaw): Broten & Collier 2005, section 6.2 (after Paul 1981).
  kXyz,
  /// R = Rz(yaw) * Ry(pitch) * Rx(roll): ROS REP 103, aerospace convention.
  kZyx,
};

const char* rpy_order_name(RpyOrder o);
/// "xyz" or "zyx"; throws std::invalid_argument otherwise.
RpyOrder rpy_order_from_name(const std::string& name);

/// Right-handed elementary rotations, exactly as printed in Broten & Collier section 6.2.
Eigen::Matrix3d rot_x(double angle);
Eigen::Matrix3d rot_y(double angle);
Eigen::Matrix3d rot_z(double angle);

struct Rpy {
  double roll = 0.0;
  double pitch = 0.0;
  double yaw = 0.0;
};

Eigen::Matrix3d rpy_to_matrix(const Rpy& rpy, RpyOrder order);
/// Inverse of rpy_to_matrix with pitch in [-pi/2, pi/2], roll and yaw in (-pi, pi]. At gimbal
/// lock (|pitch| = pi/2) yaw is set to 0 and roll absorbs the remaining rotation.
Rpy matrix_to_rpy(const Eigen::Matrix3d& r, RpyOrder order);

/// Rigid transform from a translation and roll-pitch-yaw in the given order.
Eigen::Isometry3d make_transform(const Eigen::Vector3d& t, const Rpy& rpy, RpyOrder order);

/// A return in the nod frame N (docs/data_contract.md): bearing nu > 0 to the left, nod eta > 0 above the
/// horizon:  p_N = r * (cos nu cos eta, sin nu, cos nu sin eta).
/// This is Broten & Collier's section 6.2 (p = d(cos psi, -sin psi) then the nod), with the in-plane
/// angle measured counter-clockwise. Note the nod is a rotation about y by -eta: with the
/// right-handed Rot(y, a) of section 6.2 a positive angle tips the x axis *down*, whereas the
/// encoder (footnote 6) reads positive *above* the horizon.
inline Eigen::Vector3d nod_frame_point(double range, double bearing, double nod) {
  const double cn = std::cos(bearing), sn = std::sin(bearing);
  const double ce = std::cos(nod), se = std::sin(nod);
  return {range * cn * ce, range * sn, range * cn * se};
}

/// One row of a pose file: T_M_V at `stamp`.
struct PoseSample {
  double stamp = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

/// Linear in position, spherical (slerp, shortest arc) in orientation; s in [0, 1].
PoseSample interpolate(const PoseSample& a, const PoseSample& b, double s);

/// The motion of one pose segment in closed form, for loops that evaluate it at many stamps:
///   R(s) = R0 + sin(a) B + (1 - cos(a)) C,   t(s) = t0 + s dt + sin(a) tB + (1 - cos(a)) tC,
/// with s = (stamp - stamp0) / duration (as a product with inv_duration) and a = s * angle. Slerp between two orientations turns
/// about one fixed axis n at a constant rate, so Rodrigues' formula gives it with B = R0 [n]x and
/// C = R0 [n]x^2: per stamp two sines by their series and 18 multiply-adds, instead of a slerp, a
/// quaternion-to-matrix conversion and (for T_M_V T_V_N) a matrix product. A fixed transform on
/// the right folds into the matrices (then()). Equal to PoseTrack::at() to rounding
/// (tests/unit/core/test_transforms.cpp).
struct SegmentMotion {
  double stamp0 = 0.0, duration = 1.0, inv_duration = 1.0, angle = 0.0;
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity(), B = Eigen::Matrix3d::Zero(), C = Eigen::Matrix3d::Zero();
  Eigen::Vector3d t0 = Eigen::Vector3d::Zero(), dt = Eigen::Vector3d::Zero(), tB = Eigen::Vector3d::Zero(),
                  tC = Eigen::Vector3d::Zero();

  /// The weights of a stamp: the segment fraction s, sin(a) and 1 - cos(a).
  struct Weights {
    double s = 0.0, sin_a = 0.0, vers_a = 0.0;
  };
  Weights weights(double stamp) const {
    Weights w;
    w.s = (stamp - stamp0) * inv_duration;
    const double a = w.s * angle;
    if (std::fabs(a) <= kSmallTurn) {
      small_turn(a, w.sin_a, w.vers_a);
      return w;
    }
    turn(a, w);
    return w;
  }
  /// Nearby poses (the usual case) turn by far less than kSmallAngle: up to this angle three
  /// terms of each series suffice, the first omitted term being under 2e-22 of the result
  /// (a^6 / 7!, a^6 / 20160).
  static constexpr double kSmallTurn = 1e-3;
  /// sin(a) and 1 - cos(a) for |a| <= kSmallTurn (inline: it runs for every return).
  static void small_turn(double a, double& sin_a, double& vers_a) {
    const double a2 = a * a;
    sin_a = a * (1.0 - a2 * (1.0 / 6.0) * (1.0 - a2 * (1.0 / 20.0)));
    vers_a = a2 * 0.5 * (1.0 - a2 * (1.0 / 12.0) * (1.0 - a2 * (1.0 / 30.0)));
  }
  /// sin(a) and 1 - cos(a) of a larger turn (weights' other cases).
  static void turn(double a, Weights& w);
  Eigen::Matrix3d rotation(const Weights& w) const { return R0 + w.sin_a * B + w.vers_a * C; }
  Eigen::Vector3d translation(const Weights& w) const { return t0 + w.s * dt + w.sin_a * tB + w.vers_a * tC; }
  /// The motion of T(stamp) * T_fixed (e.g. T_M_N = T_M_V(stamp) T_V_N).
  SegmentMotion then(const Eigen::Isometry3d& T_fixed) const;
};

/// A time-ordered sequence of poses T_M_V(t), interpolated at any stamp inside its span.
class PoseTrack {
 public:
  PoseTrack() = default;
  /// Samples must have strictly increasing stamps (checked by the reader; asserted here).
  explicit PoseTrack(std::vector<PoseSample> samples);
  /// Adds a sample after the last one (live poses); throws std::invalid_argument if its stamp is not later.
  void append(PoseSample s);

  bool empty() const { return samples_.empty(); }
  std::size_t size() const { return samples_.size(); }
  double begin_stamp() const { return samples_.front().stamp; }
  double end_stamp() const { return samples_.back().stamp; }
  bool covers(double stamp) const {
    return !samples_.empty() && stamp >= begin_stamp() && stamp <= end_stamp();
  }
  const std::vector<PoseSample>& samples() const { return samples_; }

  /// T_M_V at `stamp`, which must be covered. `hint` is the index of the bracket used last
  /// (pass the same variable for a sequence of near-monotonic stamps: O(1) per query).
  Eigen::Isometry3d at(double stamp, std::size_t& hint) const;
  /// Index k of the samples bracketing a covered `stamp`: samples[k].stamp <= stamp <= samples[k+1].stamp.
  std::size_t bracket(double stamp, std::size_t hint) const {
    // Inline for the usual case, the hint's own bracket (every return between two poses).
    if (hint + 1 < samples_.size() && stamp >= samples_[hint].stamp && stamp <= samples_[hint + 1].stamp) return hint;
    return bracket_search(stamp, hint);
  }
  /// Time between the two samples bracketing a covered `stamp` (0 with a single sample).
  double gap_at(double stamp, std::size_t& hint) const;
  /// Segment k (samples k and k + 1) in closed form; with a single sample, that pose, fixed.
  SegmentMotion motion(std::size_t k) const;

 private:
  std::size_t bracket_search(double stamp, std::size_t hint) const;
  std::vector<PoseSample> samples_;
  /// Per segment [k, k+1]: the slerp angle and its sine (Eigen's slerp recomputes both, with an
  /// acos and a sin, at every call; at() does the same arithmetic with these).
  struct Segment {
    double dot = 1.0, theta = 0.0, sin_theta = 0.0;
  };
  std::vector<Segment> seg_;
  void add_segment(std::size_t k);
};

/// A rotation given as a quaternion w, x, y, z at any scale (a PCD VIEWPOINT, an option),
/// normalized; none when it gives no direction: its norm (returned in `norm`, computed without
/// overflow) is below 1e-9 or not finite.
std::optional<Eigen::Quaterniond> unit_quaternion(double w, double x, double y, double z, double* norm = nullptr);

}  // namespace pcdp
