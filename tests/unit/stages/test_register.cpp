#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/core/pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/core/skew.hpp"
#include "pcdp/core/uncertainty.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
struct Errors {
  double median = 0, max = 0;
  std::size_t compared = 0;
};

Errors compare(const Pass& p, const sim::SimPass& truth) {
  std::vector<double> e;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!p.is_kept(i)) continue;
    const Eigen::Vector3d got(p.x[i], p.y[i], p.z[i]);
    e.push_back((got - truth.true_point[i]).norm());
  }
  Errors out;
  out.compared = e.size();
  out.median = test::median(e);
  for (double v : e) out.max = std::max(out.max, v);
  return out;
}

// The sigmas register should use for a return (without encoder latency: no rate term).
PointSigmas expected_sigmas(const SensorParams& sensor, const PoseSigma& ps) {
  PointSigmas s;
  s.range = sensor.range_k * sensor.range_sigma;
  s.bearing = quantization_sigma(sensor.bearing_resolution);
  s.nod = quantization_sigma(sensor.encoder_resolution);
  s.position = Eigen::Vector3d::Constant(ps.position);
  s.rpy = Eigen::Vector3d::Constant(ps.rpy);
  return s;
}

struct Fixture {
  sim::SimConfig cfg = test::small_sim_config();
  sim::SimResult run;
  PoseTrack poses;
  SensorParams sensor;
  Eigen::Isometry3d T_V_N;
  explicit Fixture(RpyOrder order = RpyOrder::kXyz) {
    cfg.passes = 1;
    cfg.rpy_order = order;
    run = sim::simulate(cfg);
    poses = PoseTrack(run.poses);
    sensor.range_max = cfg.scanner.range_max;
    T_V_N = make_transform(cfg.mount_translation, cfg.mount_rpy, cfg.rpy_order);
  }
};
}  // namespace

TEST(Register, NoiseFreePassRegistersToTheTruth) {
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    Fixture f(order);
    Pass p = f.run.passes[0].pass;
    register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, &f.poses);
    const Errors e = compare(p, f.run.passes[0]);
    EXPECT_GT(e.compared, p.size() / 2);
    EXPECT_LT(e.median, 2e-4) << rpy_order_name(order);  // pose interpolation at 100 Hz is the only approximation
    // The sensor origin is the nod-axis position.
    const Eigen::Isometry3d T = sim::vehicle_pose(f.cfg, p.stamp[0]) * f.T_V_N;
    EXPECT_LT((Eigen::Vector3d(p.ox[0], p.oy[0], p.oz[0]) - T.translation()).norm(), 1e-4);
  }
}

TEST(Register, SkewCorrectionOffIsMeasurablyWorse) {
  Fixture f;
  Pass on = f.run.passes[0].pass, off = on;
  register_pass(on, RegisterParams{true, 1.0}, f.sensor, f.T_V_N, &f.poses);
  register_pass(off, RegisterParams{false, 1.0}, f.sensor, f.T_V_N, &f.poses);
  const Errors a = compare(on, f.run.passes[0]), b = compare(off, f.run.passes[0]);
  EXPECT_GT(b.median, 20 * a.median);
  EXPECT_GT(b.median, 0.01);  // centimetres: omega * tau * r / 2 at a few metres
}

TEST(Register, LabelsNoReturnOutOfRangeAndNoPose) {
  Fixture f;
  Pass p = f.run.passes[0].pass;
  p.range[0] = 0.0f;
  p.range[1] = std::numeric_limits<float>::quiet_NaN();
  p.range[2] = 0.05f;  // below range_min
  p.range[3] = 45.0f;  // above range_max
  // A pose track that ends half way through the pass.
  std::vector<PoseSample> half;
  const double t_mid = p.stamp[p.size() / 2];
  for (const auto& s : f.run.poses)
    if (s.stamp <= t_mid) half.push_back(s);
  const PoseTrack short_track(half);
  register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, &short_track);
  EXPECT_EQ(p.label[0], Label::kNoReturn);
  EXPECT_EQ(p.label[1], Label::kNoReturn);
  EXPECT_EQ(p.label[2], Label::kOutOfRange);
  EXPECT_EQ(p.label[3], Label::kOutOfRange);
  EXPECT_TRUE(std::isnan(p.x[0]));
  EXPECT_FALSE(std::isnan(p.x[3]));  // out of range still has its point
  std::size_t no_pose = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.stamp[i] > short_track.end_stamp() && p.range[i] > 0.1f && p.range[i] < 30.0f) {
      EXPECT_EQ(p.label[i], Label::kNoPose) << i;
      EXPECT_TRUE(std::isnan(p.x[i]));
      ++no_pose;
    }
  }
  EXPECT_GT(no_pose, 100u);
}

TEST(Register, PoseGapsLongerThanTheLimitGiveNoPose) {
  Fixture f;
  std::vector<PoseSample> gappy;
  const double t_mid = f.run.passes[0].pass.stamp[f.run.passes[0].pass.size() / 2];
  for (const auto& s : f.run.poses)
    if (std::fabs(s.stamp - t_mid) > 0.2) gappy.push_back(s);  // a 0.4 s hole
  const PoseTrack track(gappy);
  Pass p = f.run.passes[0].pass;
  register_pass(p, RegisterParams{true, 0.25}, f.sensor, f.T_V_N, &track);
  std::size_t in_gap = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    if (std::fabs(p.stamp[i] - t_mid) < 0.19 && p.range[i] > 0.1f) {
      EXPECT_EQ(p.label[i], Label::kNoPose);
      ++in_gap;
    }
  EXPECT_GT(in_gap, 0u);
  Pass q = f.run.passes[0].pass;
  register_pass(q, RegisterParams{true, 0.0}, f.sensor, f.T_V_N, &track);  // 0 disables the gap check
  EXPECT_EQ(std::count(q.label.begin(), q.label.end(), Label::kNoPose), 0);
}

TEST(Register, RangeCalibrationIsAppliedBeforeProjection) {
  Fixture f;
  f.sensor.range_k = 1.01;
  f.sensor.range_b = -0.02;
  Pass p = f.run.passes[0].pass;
  register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, &f.poses);
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!p.is_kept(i)) continue;
    EXPECT_NEAR(p.range_cal[i], 1.01 * p.range[i] - 0.02, 1e-5);
    const Eigen::Vector3d d = Eigen::Vector3d(p.x[i], p.y[i], p.z[i]) - Eigen::Vector3d(p.ox[i], p.oy[i], p.oz[i]);
    EXPECT_NEAR(d.norm(), p.range_cal[i], 1e-5);
  }
}

TEST(Register, WithoutPosesTheVehicleFrameIsTheMapFrame) {
  Fixture f;
  Pass p = f.run.passes[0].pass;
  register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, nullptr);
  EXPECT_EQ(std::count(p.label.begin(), p.label.end(), Label::kNoPose), 0);
  EXPECT_NEAR(p.ox[0], f.cfg.mount_translation.x(), 1e-12);
  EXPECT_NEAR(p.oz[0], f.cfg.mount_translation.z(), 1e-12);
}

TEST(Register, ABlindedSensorIsReportedWithItsLineRange) {
  Fixture f;
  Pass p = f.run.passes[0].pass;
  const std::size_t first = 10, last = 17;  // lines 10..17 return nothing (sunlight, Broten & Collier 7.5)
  for (std::size_t k = first; k <= last; ++k)
    for (std::size_t i = p.line_begin[k]; i < p.line_begin[k + 1]; ++i) p.range[i] = 0.0f;
  const auto w = blind_runs(p, 5);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("lines " + std::to_string(p.line[p.line_begin[first]]) + "-" + std::to_string(p.line[p.line_begin[last]]) +
                      " (8 lines) returned nothing"),
            std::string::npos)
      << w[0];
  EXPECT_TRUE(blind_runs(p, 9).empty());  // shorter than the threshold
  EXPECT_TRUE(blind_runs(f.run.passes[0].pass, 5).empty());
}

TEST(Register, StoredCovarianceIsTheAnglePathCovarianceAtEachReturnsOwnPoseAndNod) {
  // register computes the covariance from what it already has (R_MN, the point, the nod's sines
  // by angle addition); it must equal point_covariance (roll, pitch, yaw and elementary
  // rotations) at the return's own interpolated pose, skew-corrected nod and calibrated range,
  // for both RPY orders, to the float precision it is stored in.
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    Fixture f(order);
    f.sensor.range_k = 1.0003;
    f.sensor.bearing_resolution = 0.0087;
    PoseSigma ps;
    ps.position = 0.02;
    ps.rpy = 0.002;
    Pass p = f.run.passes[0].pass;
    register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, &f.poses, ps, order);
    const EncoderTrack track = encoder_track(p, f.sensor.encoder_latency);
    const PointSigmas s = expected_sigmas(f.sensor, ps);
    std::size_t checked = 0, hint = 0, enc_hint = 0;
    for (std::size_t i = 0; i < p.size(); i += 7) {
      if (!std::isfinite(p.x[i])) continue;
      const double eta = track.angle_at(p.stamp[i], enc_hint);
      EXPECT_NEAR(p.nod_at_return[i], eta, 1e-6);
      const Eigen::Isometry3d T_M_V = f.poses.at(p.stamp[i], hint);
      const Eigen::Matrix3d C = point_covariance(f.sensor.calibrated_range(p.range[i]), p.bearing[i], eta, f.T_V_N,
                                                 matrix_to_rpy(T_M_V.linear(), order), order, s);
      const float* c = &p.cov[6 * i];
      const double got[6] = {c[0], c[1], c[2], c[3], c[4], c[5]};
      const double want[6] = {C(0, 0), C(0, 1), C(0, 2), C(1, 1), C(1, 2), C(2, 2)};
      for (int k = 0; k < 6; ++k) ASSERT_NEAR(got[k], want[k], 1e-5 * C.norm()) << rpy_order_name(order) << " return " << i << " entry " << k;
      ++checked;
    }
    EXPECT_GT(checked, p.size() / 20);
  }
}

namespace {
// Where register put return i: T_M_V(stamp) T_V_N p_N, from PoseTrack::at (slerp) and std::sin/cos.
// (The nod in double from the encoder track: nod_at_return is stored as float.)
Eigen::Vector3d expected_point(const Pass& p, std::size_t i, const PoseTrack& poses, const Eigen::Isometry3d& T_V_N,
                               const SensorParams& sensor, const EncoderTrack& enc, std::size_t& hint,
                               std::size_t& enc_hint) {
  const Eigen::Isometry3d T_M_N = poses.at(p.stamp[i], hint) * T_V_N;
  return T_M_N * nod_frame_point(sensor.calibrated_range(p.range[i]), p.bearing[i], enc.angle_at(p.stamp[i], enc_hint));
}
}  // namespace

TEST(Register, LargeAndSmallTurnsRegisterAsTheInterpolatedPose) {
  // Three poses: the first half of the pass turns 0.6 rad in yaw and 0.2 in pitch (beyond
  // SegmentMotion::kSmallTurn for all but its first returns: the full sine), the second half
  // turns 0.5 mrad (the inline three-term series, which would be millimetres off at 0.6 rad).
  // register's chunks then hold runs of both kinds, split mid-chunk. Every point and origin must
  // be the slerped pose's, to rounding.
  Fixture f;
  Pass p = f.run.passes[0].pass;
  PoseSample a, b, c;
  a.stamp = p.stamp.front() - 1e-4;
  b.stamp = p.stamp[p.size() / 2];
  c.stamp = p.stamp.back() + 1e-4;
  a.position = Eigen::Vector3d(1.0, -2.0, 0.3);
  b.position = Eigen::Vector3d(3.0, 1.0, 0.1);
  c.position = Eigen::Vector3d(3.5, 1.2, 0.1);
  b.orientation = Eigen::Quaterniond(rpy_to_matrix({0.0, 0.2, 0.6}, RpyOrder::kXyz));
  c.orientation = Eigen::Quaterniond(rpy_to_matrix({0.0, 0.2, 0.6005}, RpyOrder::kXyz));
  const PoseTrack track({a, b, c});
  ASSERT_GT(track.motion(0).angle, 0.5);
  ASSERT_LT(track.motion(1).angle, SegmentMotion::kSmallTurn);
  register_pass(p, RegisterParams{}, f.sensor, f.T_V_N, &track);
  const EncoderTrack enc = encoder_track(p, f.sensor.encoder_latency);
  std::size_t small = 0, large = 0, hint = 0, enc_hint = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p.x[i])) continue;
    const std::size_t k = track.bracket(p.stamp[i], 0);
    const SegmentMotion m = track.motion(k);
    const double turn = std::fabs((p.stamp[i] - m.stamp0) / m.duration * m.angle);
    (turn <= SegmentMotion::kSmallTurn ? small : large) += 1;
    const Eigen::Vector3d want = expected_point(p, i, track, f.T_V_N, f.sensor, enc, hint, enc_hint);
    worst = std::max(worst, (Eigen::Vector3d(p.x[i], p.y[i], p.z[i]) - want).norm());
    const Eigen::Vector3d o = (track.at(p.stamp[i], hint) * f.T_V_N).translation();
    worst = std::max(worst, (Eigen::Vector3d(p.ox[i], p.oy[i], p.oz[i]) - o).norm());
  }
  EXPECT_GT(small, p.size() / 4);
  EXPECT_GT(large, p.size() / 4);
  EXPECT_LT(worst, 1e-9);  // metres; a wrong weight is off by millimetres or more
}

TEST(Register, CovarianceAtGimbalLockTakesTheAnglePathAndStaysFinite) {
  // A vehicle pitched straight up (xyz order, pitch 90 degrees): the middle pose axis is
  // undefined, the vectorised kernel cannot be used, and register must fall back to the angle
  // path for those returns: the covariance is point_covariance's, finite, at every return.
  Fixture f;
  Pass p = f.run.passes[0].pass;
  const Eigen::Quaterniond up(rpy_to_matrix({0.2, 1.5707963267948966, 0.1}, RpyOrder::kXyz));
  PoseSample a, b;
  a.stamp = p.stamp.front() - 1.0;
  b.stamp = p.stamp.back() + 1.0;
  a.orientation = b.orientation = up;
  b.position = Eigen::Vector3d(0.5, 0.0, 0.0);
  const PoseTrack track({a, b});
  PoseSigma ps;
  ps.position = 0.01;
  ps.rpy = 0.002;
  register_pass(p, RegisterParams{true, 0.0}, f.sensor, f.T_V_N, &track, ps, RpyOrder::kXyz);
  const EncoderTrack enc = encoder_track(p, f.sensor.encoder_latency);
  const PointSigmas s = expected_sigmas(f.sensor, ps);
  std::size_t checked = 0, hint = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!std::isfinite(p.x[i])) continue;
    const double eta = enc.angle_at(p.stamp[i], hint);
    const Eigen::Matrix3d C = point_covariance(f.sensor.calibrated_range(p.range[i]), p.bearing[i], eta, f.T_V_N,
                                               matrix_to_rpy(up.toRotationMatrix(), RpyOrder::kXyz), RpyOrder::kXyz, s);
    const float* c = &p.cov[6 * i];
    const double want[6] = {C(0, 0), C(0, 1), C(0, 2), C(1, 1), C(1, 2), C(2, 2)};
    for (int k = 0; k < 6; ++k) {
      ASSERT_TRUE(std::isfinite(c[k])) << "return " << i;
      ASSERT_NEAR(c[k], want[k], 1e-6 * C.norm()) << "return " << i << " entry " << k;
    }
    ++checked;
  }
  EXPECT_GT(checked, p.size() / 2);
}
