#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "pcdp/core/transforms.hpp"
#include "core/small_angle.hpp"

using namespace pcdp;

namespace {
constexpr double kPi = 3.14159265358979323846;

// The expanded RPY matrix exactly as printed in Broten & Collier 2005, section 6.2.
Eigen::Matrix3d broten_collier_expanded(double f, double t, double p) {
  const double cf = std::cos(f), sf = std::sin(f), ct = std::cos(t), st = std::sin(t), cp = std::cos(p), sp = std::sin(p);
  Eigen::Matrix3d r;
  r << ct * cp, -ct * sp, st,                                   //
      cf * sp + sf * st * cp, cf * cp - sf * st * sp, -sf * ct,  //
      sf * sp - cf * st * cp, sf * cp + cf * st * sp, cf * ct;
  return r;
}
}  // namespace

TEST(Transforms, XyzEqualsBrotenCollierExpandedMatrixForRandomAngles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> a(-kPi, kPi);
  for (int i = 0; i < 1000; ++i) {
    const double f = a(rng), t = a(rng), p = a(rng);
    const Eigen::Matrix3d r = rpy_to_matrix({f, t, p}, RpyOrder::kXyz);
    EXPECT_LT((r - broten_collier_expanded(f, t, p)).cwiseAbs().maxCoeff(), 1e-14) << f << " " << t << " " << p;
  }
}

TEST(Transforms, ZyxIsRep103AndDiffersFromXyz) {
  const Rpy rpy{0.3, -0.2, 1.1};
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_LT((rpy_to_matrix(rpy, RpyOrder::kZyx) - expected).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_GT((rpy_to_matrix(rpy, RpyOrder::kXyz) - expected).cwiseAbs().maxCoeff(), 1e-2);
}

TEST(Transforms, ElementaryRotationsAreRightHanded) {
  // Rot(z, 90 deg) takes x to y; Rot(x, 90) takes y to z; Rot(y, 90) takes z to x.
  EXPECT_TRUE((rot_z(kPi / 2) * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_TRUE((rot_x(kPi / 2) * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((rot_y(kPi / 2) * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
}

class RpyRoundTrip : public ::testing::TestWithParam<RpyOrder> {};

TEST_P(RpyRoundTrip, MatrixToRpyInvertsRpyToMatrix) {
  const RpyOrder order = GetParam();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> a(-kPi + 1e-6, kPi - 1e-6), b(-kPi / 2 + 1e-6, kPi / 2 - 1e-6);
  for (int i = 0; i < 1000; ++i) {
    const Rpy in{a(rng), b(rng), a(rng)};
    const Rpy out = matrix_to_rpy(rpy_to_matrix(in, order), order);
    EXPECT_NEAR(out.roll, in.roll, 1e-9);
    EXPECT_NEAR(out.pitch, in.pitch, 1e-9);
    EXPECT_NEAR(out.yaw, in.yaw, 1e-9);
    // And the matrix round trip, which holds for any angles.
    const Eigen::Matrix3d m = rpy_to_matrix(in, order);
    EXPECT_LT((rpy_to_matrix(matrix_to_rpy(m, order), order) - m).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST_P(RpyRoundTrip, GimbalLockStillReproducesTheMatrix) {
  const RpyOrder order = GetParam();
  for (double pitch : {kPi / 2, -kPi / 2}) {
    const Eigen::Matrix3d m = rpy_to_matrix({0.4, pitch, -0.7}, order);
    const Rpy out = matrix_to_rpy(m, order);
    EXPECT_NEAR(out.yaw, 0.0, 1e-12);
    EXPECT_LT((rpy_to_matrix(out, order) - m).cwiseAbs().maxCoeff(), 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Orders, RpyRoundTrip, ::testing::Values(RpyOrder::kXyz, RpyOrder::kZyx));

TEST(Transforms, NodFramePointConvention) {
  // docs/data_contract.md: nu > 0 to the left, eta > 0 above the horizon.
  const Eigen::Vector3d left = nod_frame_point(2.0, kPi / 2, 0.0);
  EXPECT_NEAR(left.y(), 2.0, 1e-12);
  const Eigen::Vector3d up = nod_frame_point(2.0, 0.0, 0.3);
  EXPECT_NEAR(up.z(), 2.0 * std::sin(0.3), 1e-12);
  EXPECT_GT(up.z(), 0.0);
  EXPECT_NEAR(nod_frame_point(3.0, 0.7, -0.4).norm(), 3.0, 1e-12);
  // The nod is Rot(y, -eta) of the in-plane point (see transforms.hpp).
  const Eigen::Vector3d inplane = 3.0 * Eigen::Vector3d(std::cos(0.7), std::sin(0.7), 0.0);
  EXPECT_TRUE((rot_y(0.4) * inplane).isApprox(nod_frame_point(3.0, 0.7, -0.4), 1e-12));
}

TEST(Transforms, SlerpEndpointsMidpointAndShortestArc) {
  PoseSample a, b;
  a.stamp = 0.0;
  b.stamp = 2.0;
  a.position = {0, 0, 0};
  b.position = {2, 4, -2};
  a.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
  b.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(interpolate(a, b, 0.0).orientation.isApprox(a.orientation, 1e-12));
  EXPECT_TRUE(interpolate(a, b, 1.0).orientation.isApprox(b.orientation, 1e-12));
  const PoseSample m = interpolate(a, b, 0.5);
  EXPECT_TRUE(m.position.isApprox(Eigen::Vector3d(1, 2, -1), 1e-12));
  EXPECT_DOUBLE_EQ(m.stamp, 1.0);
  EXPECT_NEAR(Eigen::AngleAxisd(m.orientation).angle(), 0.6, 1e-12);
  // Constant angular rate: the angle is linear in s (not so for a normalized lerp).
  for (double s : {0.1, 0.25, 0.8}) EXPECT_NEAR(Eigen::AngleAxisd(interpolate(a, b, s).orientation).angle(), 0.2 + 0.8 * s, 1e-12);
  // -q is the same rotation: slerp must take the short way (angle 0.6 at the middle, not pi-ish).
  PoseSample bn = b;
  bn.orientation.coeffs() = -b.orientation.coeffs();
  EXPECT_NEAR(Eigen::AngleAxisd(interpolate(a, bn, 0.5).orientation).angle(), 0.6, 1e-12);
}

TEST(Transforms, PoseTrackInterpolatesAndReportsCoverage) {
  std::vector<PoseSample> s(3);
  for (int i = 0; i < 3; ++i) {
    s[i].stamp = 10.0 + i;
    s[i].position = {static_cast<double>(i), 0, 0};
    s[i].orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitX()));
  }
  const PoseTrack track(s);
  EXPECT_TRUE(track.covers(10.0));
  EXPECT_TRUE(track.covers(12.0));
  EXPECT_FALSE(track.covers(9.999));
  EXPECT_FALSE(track.covers(12.001));
  std::size_t hint = 0;
  const Eigen::Isometry3d T = track.at(11.5, hint);
  EXPECT_NEAR(T.translation().x(), 1.5, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(T.linear()).angle(), 0.15, 1e-12);
  EXPECT_EQ(hint, 1u);
  // Queries out of order still work (the hint is only a hint).
  EXPECT_NEAR(track.at(10.25, hint).translation().x(), 0.25, 1e-12);
  EXPECT_DOUBLE_EQ(track.gap_at(11.2, hint), 1.0);
}

TEST(PoseTrack, CachedSlerpIsEigensSlerpToRounding) {
  // at() caches each segment's slerp angle and takes small angles' sines by their series; the
  // result must be interpolate()'s (Eigen's Quaternion::slerp) to rounding, for nearly equal
  // orientations (lerp branch), angles on both sides of the series' limit and opposite signs.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<PoseSample> v;
  for (int k = 0; k < 200; ++k) {
    PoseSample p;
    p.stamp = 0.01 * k;
    p.position = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const double step = k % 3 == 0 ? 1e-9 : (k % 3 == 1 ? 0.03 : 0.3);  // lerp, series, std::sin
    Eigen::Quaterniond q = k ? v.back().orientation * Eigen::Quaterniond(Eigen::AngleAxisd(step * u(rng), Eigen::Vector3d(u(rng), u(rng), 1).normalized()))
                             : Eigen::Quaterniond::Identity();
    if (k % 7 == 0) q.coeffs() = -q.coeffs();  // the same rotation, the other sign
    p.orientation = q.normalized();
    v.push_back(p);
  }
  const PoseTrack t(v);
  PoseTrack live;
  for (const auto& p : v) live.append(p);
  std::size_t hint = 0, hint2 = 0;
  for (int i = 0; i < 5000; ++i) {
    const double stamp = 0.01 * 199 * (i / 5000.0);
    const Eigen::Isometry3d a = t.at(stamp, hint), b = live.at(stamp, hint2);
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(stamp / 0.01), 198);
    const double s = (stamp - v[k].stamp) / (v[k + 1].stamp - v[k].stamp);
    PoseSample a0 = v[k], b0 = v[k + 1];
    a0.orientation.normalize();
    b0.orientation.normalize();
    const PoseSample e = interpolate(a0, b0, s);
    // A few units in the last place of entries of magnitude <= 1 (the series differs from
    // std::sin by rounding only; a wrong branch or coefficient would be off by far more).
    EXPECT_LT((a.linear() - e.orientation.toRotationMatrix()).cwiseAbs().maxCoeff(), 1e-15) << i;
    EXPECT_TRUE(a.translation() == e.position) << i;
    EXPECT_TRUE(a.matrix() == b.matrix()) << i;  // the live track computes the same thing
  }
}

TEST(PoseTrack, SegmentMotionIsAtToRounding) {
  // motion(k) (Rodrigues' form of the segment's slerp, used by register's hot loop) must give
  // at()'s pose to rounding, alone and with a fixed transform folded in (T_M_V(t) T_V_N), over
  // segments that turn by nothing, by small angles (both series) and by large ones (std::sin), both
  // quaternion signs, and at the segment ends.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<PoseSample> v;
  for (int k = 0; k < 120; ++k) {
    PoseSample p;
    p.stamp = 0.02 * k + (k % 7 == 0 ? 0.004 : 0.0);
    p.position = Eigen::Vector3d(3 * u(rng), 3 * u(rng), u(rng));
    // No turn; tiny, short-series (up to 1e-3 rad), series and std::sin turns.
    const double steps[5] = {0.0, 1e-7, 2e-3, 0.04, 0.9};
    const double step = steps[k % 5];
    Eigen::Quaterniond q = k ? v.back().orientation * Eigen::Quaterniond(Eigen::AngleAxisd(step * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()))
                             : Eigen::Quaterniond(Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()));
    if (k % 3 == 0) q.coeffs() = -q.coeffs();
    p.orientation = q.normalized();
    v.push_back(p);
  }
  const PoseTrack track(v);
  const Eigen::Isometry3d T_V_N = make_transform({0.3, -0.1, 0.8}, {0.02, -0.3, 0.1}, RpyOrder::kXyz);
  std::size_t hint = 0;
  double worst_r = 0.0, worst_t = 0.0;
  for (std::size_t k = 0; k + 1 < v.size(); ++k) {
    const SegmentMotion m = track.motion(k), mn = m.then(T_V_N);
    for (double f : {0.0, 0.013, 0.25, 0.5, 0.77, 1.0}) {
      const double stamp = v[k].stamp + f * (v[k + 1].stamp - v[k].stamp);
      hint = k;
      const Eigen::Isometry3d T = track.at(stamp, hint);
      const SegmentMotion::Weights w = m.weights(stamp);
      worst_r = std::max(worst_r, (m.rotation(w) - T.linear()).cwiseAbs().maxCoeff());
      worst_t = std::max(worst_t, (m.translation(w) - T.translation()).cwiseAbs().maxCoeff());
      const Eigen::Isometry3d TN = T * T_V_N;
      worst_r = std::max(worst_r, (mn.rotation(w) - TN.linear()).cwiseAbs().maxCoeff());
      worst_t = std::max(worst_t, (mn.translation(w) - TN.translation()).cwiseAbs().maxCoeff());
    }
  }
  // Entries of magnitude <= 1 and translations of a few metres: a few units in the last place.
  // A wrong axis sign, a missing (1 - cos) term or the longer arc would be off by 1e-3 or more.
  EXPECT_LT(worst_r, 2e-15);
  EXPECT_LT(worst_t, 1e-14);
  // A single pose is that pose, whatever the stamp.
  const PoseTrack one({v[3]});
  const SegmentMotion m1 = one.motion(0);
  const SegmentMotion::Weights w1 = m1.weights(123.0);
  EXPECT_TRUE(m1.rotation(w1).isApprox(v[3].orientation.toRotationMatrix(), 1e-15));
  EXPECT_TRUE(m1.translation(w1) == v[3].position);
}

TEST(SmallAngle, SeriesEqualTheLibraryFunctionsToRoundingUpToTheirLimit) {
  // sin_small and cos_small replace std::sin / std::cos below kSmallAngle in the hot loops
  // (slerp, the nod's step): they must agree to a few ulp over the whole range, including the
  // limit where the first omitted term is largest.
  double worst_sin = 0, worst_cos = 0, worst_vers = 0;
  for (int k = -20000; k <= 20000; ++k) {
    const double x = detail::kSmallAngle * k / 20000.0;
    if (x != 0.0) worst_sin = std::max(worst_sin, std::fabs(detail::sin_small(x) - std::sin(x)) / std::fabs(std::sin(x)));
    worst_cos = std::max(worst_cos, std::fabs(detail::cos_small(x) - std::cos(x)));
    // 1 - cos(x) = 2 sin^2(x / 2) without cancellation, relative: the series keeps full precision
    // where 1 - cos_small(x) would keep only a few digits.
    const double h = std::sin(0.5 * x), vers = 2.0 * h * h;
    if (x != 0.0) worst_vers = std::max(worst_vers, std::fabs(detail::vers_small(x) - vers) / vers);
  }
  EXPECT_LT(worst_sin, 4.5e-16);  // 2 ulp relative
  EXPECT_LT(worst_cos, 2.3e-16);  // 2 ulp of values near 1
  EXPECT_LT(worst_vers, 9e-16);   // 4 ulp relative (the reference itself rounds three times)
  EXPECT_EQ(detail::sin_small(0.0), 0.0);
  EXPECT_EQ(detail::cos_small(0.0), 1.0);
  // Odd and even, as the functions they replace.
  EXPECT_EQ(detail::sin_small(-0.07), -detail::sin_small(0.07));
  EXPECT_EQ(detail::cos_small(-0.07), detail::cos_small(0.07));
  EXPECT_EQ(detail::vers_small(0.0), 0.0);
  EXPECT_EQ(detail::vers_small(-0.07), detail::vers_small(0.07));
}
