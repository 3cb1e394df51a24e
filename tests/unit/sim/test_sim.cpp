// Each physical effect of the simulator in isolation.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "pcdp/sim/nodding_sim.hpp"

using namespace pcdp;
using namespace pcdp::sim;

namespace {
constexpr double kPi = 3.14159265358979323846;

/// A static scanner at the origin looking along +x (vehicle = map, mount = identity).
SimConfig static_scanner() {
  SimConfig c;
  c.mount_translation = {0, 0, 0};
  c.mount_rpy = {0, 0, 0};
  c.motion.speed = 0.0;
  c.scene.ground_z = -100.0;  // out of reach
  c.scanner.range_max = 30.0;
  return c;
}

struct Frame {
  Eigen::Vector3d d, u, v;
};
Frame beam_frame(double bearing, double eta = 0.0) {
  return {nod_frame_point(1.0, bearing, eta),
          Eigen::Vector3d(-std::sin(bearing) * std::cos(eta), std::cos(bearing), -std::sin(bearing) * std::sin(eta)),
          Eigen::Vector3d(-std::sin(eta), 0.0, std::cos(eta))};
}

/// Amplitude profile while the beam scans (bearing) across the left edge of a near target at
/// 5 m in front of a wall at 10 m.
std::vector<BeamResult> scan_edge(const SimConfig& c, double from, double to, int n) {
  std::vector<BeamResult> out;
  for (int i = 0; i < n; ++i) {
    const double b = from + (to - from) * i / (n - 1);
    const Frame f = beam_frame(b);
    out.push_back(cast_beam(c, Eigen::Vector3d::Zero(), f.d, f.u, f.v, b));
  }
  return out;
}

SimConfig edge_scene(double front_reflectivity, double separation, double theta) {
  SimConfig c = static_scanner();
  c.scanner.beam_divergence = 0.004;
  c.scanner.subrays = 61;
  c.scanner.transceiver_separation = separation;
  c.scanner.transceiver_angle_offset = theta;
  c.scanner.amplitude_scale = 1000.0;
  c.scanner.amplitude_range_exponent = 1.0;
  // Near target: x in [5, 5.2], y < 0 (right of the beam at bearing 0); the edge at y = 0.
  c.scene.boxes.push_back({{5.0, -2.0, -2.0}, {5.2, 0.0, 2.0}, front_reflectivity});
  c.scene.boxes.push_back({{10.0, -5.0, -5.0}, {10.5, 5.0, 5.0}, 0.3});  // wall
  return c;
}
}  // namespace

TEST(Sim, AFootprintStraddlingAnEdgeReturnsARangeBetweenTheSurfaces) {
  const SimConfig c = edge_scene(0.5, 0.0, 0.0);  // coaxial: no occlusion
  const auto prof = scan_edge(c, -0.004, 0.004, 81);
  int mixed = 0;
  for (const auto& b : prof) {
    ASSERT_TRUE(b.any_hit);
    EXPECT_GE(b.range, 5.0 - 1e-9);
    EXPECT_LE(b.range, 10.0 / std::cos(0.01));  // off-axis sub-rays reach the plane slightly farther
    if (b.range > 5.05 && b.range < 9.95) {
      ++mixed;
      EXPECT_GT(b.min_dev, 0.05);  // far from both surfaces: a mixed pixel
    }
  }
  EXPECT_GT(mixed, 10);
  EXPECT_NEAR(prof.front().range, 5.0, 0.01);  // fully on the near target
  EXPECT_NEAR(prof.back().range, 10.0, 0.01);  // fully on the wall
}

TEST(Sim, BehindADarkFrontTargetTheSeparatedConfigurationDipsBelowThresholdAndTheCoaxialDoesNot) {
  const double threshold = 18.0;
  // Separated in the scan plane (theta = 0), receiver on the near target's side (the target is to
  // the right, y < 0, and the receiver offset u points left: theta = pi puts it to the right).
  const auto separated = scan_edge(edge_scene(0.12, 0.03, kPi), -0.004, 0.006, 201);
  const auto coaxial = scan_edge(edge_scene(0.12, 0.0, 0.0), -0.004, 0.006, 201);
  const auto across = scan_edge(edge_scene(0.12, 0.03, kPi / 2), -0.004, 0.006, 201);  // theta = 90 deg
  const auto min_amp = [](const std::vector<BeamResult>& p) {
    double m = 1e9;
    for (const auto& b : p) m = std::min(m, b.amplitude);
    return m;
  };
  const double p1 = coaxial.front().amplitude, p2 = coaxial.back().amplitude;
  ASSERT_GT(p1, threshold);
  ASSERT_GT(p2, threshold);
  EXPECT_LT(min_amp(separated), threshold);
  EXPECT_GE(min_amp(coaxial), std::min(p1, p2) - 1e-9);  // no dip below min(P1, P2)
  EXPECT_GT(min_amp(across), threshold);
  // The energy is lost, not moved: the unoccluded amplitude never dips.
  for (const auto& b : separated) EXPECT_GE(b.amplitude_full, std::min(p1, p2) - 1e-9);
}

TEST(Sim, RangeNoiseMatchesSigmaWithinFivePercentAndFollowsYeBorensteinEq6) {
  SimConfig c = static_scanner();
  c.scene.boxes.push_back({{4.0, -50.0, -50.0}, {4.5, 50.0, 50.0}, 0.5});  // a wall at x = 4
  c.scanner.beams = 1;
  c.scanner.bearing_min = c.scanner.bearing_max = 0.0;
  c.scanner.nod_min = -1e-6;
  c.scanner.nod_max = 0.0;
  c.scanner.nod_rate = 0.0;
  c.scanner.range_sigma = 0.0053;
  c.scanner.range_quantum = 0.001;
  c.scanner.range_n = 0.9998;
  c.scanner.range_c = 0.0036;
  c.lines_per_pass = 20000;
  const auto r = simulate(c);
  const auto& p = r.passes[0].pass;
  double sum = 0, sum2 = 0;
  for (float v : p.range) {
    sum += v;
    sum2 += static_cast<double>(v) * v;
    EXPECT_NEAR(std::round(v * 1000.0), v * 1000.0, 1e-3);  // integer millimetres
  }
  const double n = static_cast<double>(p.size());
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.9998 * 4.0 + 0.0036, 3 * 0.0053 / std::sqrt(n) + 1e-4);
  EXPECT_NEAR(sd, 0.0053, 0.05 * 0.0053);
}

TEST(Sim, TheEncoderReadingLagsEarlierReturnsByOmegaTimesTheTimeDifference) {
  SimConfig c = static_scanner();
  c.scene.boxes.push_back({{4.0, -50.0, -50.0}, {4.5, 50.0, 50.0}, 0.5});
  c.scanner.nod_rate = 0.8;
  c.scanner.nod_min = -0.5;
  c.scanner.nod_max = 0.5;
  c.scanner.beams = 101;
  c.lines_per_pass = 40;  // 0.53 s: the nod only rises (no reversal before 1.25 s)
  const auto r = simulate(c);
  const auto& sp = r.passes[0];
  for (std::size_t k = 0; k < sp.pass.line_count(); ++k) {
    const std::size_t last = sp.pass.line_begin[k + 1] - 1;
    for (std::size_t i = sp.pass.line_begin[k]; i <= last; ++i) {
      const double lag = sp.pass.nod[i] - sp.true_nod[i];
      EXPECT_NEAR(lag, 0.8 * (sp.pass.stamp[last] - sp.pass.stamp[i]), 1e-6);
    }
  }
}

TEST(Sim, EncoderReadingsAreQuantized) {
  SimConfig c = static_scanner();
  c.scene.boxes.push_back({{4.0, -50.0, -50.0}, {4.5, 50.0, 50.0}, 0.5});
  c.scanner.encoder_resolution = 0.0012566;
  c.lines_per_pass = 50;
  const auto r = simulate(c);
  for (float v : r.passes[0].pass.nod) {
    const double counts = v / 0.0012566;
    EXPECT_NEAR(counts, std::round(counts), 1e-3);
  }
}

TEST(Sim, BelowTheThresholdTheSensorReadsNothingOrAFalseRange) {
  SimConfig c = static_scanner();
  c.scene.boxes.push_back({{20.0, -50.0, -50.0}, {20.5, 50.0, 50.0}, 0.05});  // dark and far
  c.scanner.amplitude_scale = 1000.0;  // 1000 * 0.05 / 20 = 2.5 < 18
  c.scanner.min_amplitude = 18.0;
  c.scanner.false_range_probability = 0.3;
  c.scanner.bearing_min = -0.5;  // every beam hits the wall within range_max
  c.scanner.bearing_max = 0.5;
  c.lines_per_pass = 200;
  const auto r = simulate(c);
  const auto& sp = r.passes[0];
  std::size_t zero = 0, falses = 0;
  for (std::size_t i = 0; i < sp.pass.size(); ++i) {
    if (sp.pass.range[i] == 0.0f) {
      EXPECT_EQ(sp.truth[i], Label::kNoReturn);
      ++zero;
    } else {
      EXPECT_EQ(sp.truth[i], Label::kLowAmplitude);  // not occlusion: nothing hid the footprint
      ++falses;
    }
  }
  const double frac = static_cast<double>(falses) / static_cast<double>(zero + falses);
  EXPECT_NEAR(frac, 0.3, 0.03);
}

TEST(Sim, UniformDistanceProfileSpacesGroundLinesEvenlyWithinTheMechanismsLimits) {
  SimConfig c;
  c.scene.ground_z = 0.0;
  c.mount_translation = {0, 0, 2.0};
  c.mount_rpy = {0, 0, 0};
  c.motion.speed = 0.0;
  c.scanner.profile = NodProfile::kUniformDistance;
  c.scanner.sample_distance = 0.2;
  c.scanner.nod_max = -0.1;
  c.scanner.nod_min = -1.2;
  c.scanner.max_nod_rate = 1.5708;
  c.scanner.encoder_resolution = 0.0;
  const NodTrajectory traj(c, 200);
  const auto& eta = traj.line_angles();
  int checked = 0;
  for (std::size_t k = 0; k + 1 < eta.size(); ++k) {
    const double x0 = 2.0 / std::tan(-eta[k]), x1 = 2.0 / std::tan(-eta[k + 1]);
    const double step = std::fabs(eta[k + 1] - eta[k]);
    if (step < 1.5708 * 0.0133 - 1e-9 && eta[k + 1] > -1.2 + 1e-9 && eta[k + 1] < -0.1 - 1e-9 && eta[k] > -1.2 + 1e-9 &&
        eta[k] < -0.1 - 1e-9) {
      EXPECT_NEAR(std::fabs(x1 - x0), 0.2, 1e-6) << k;
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
}

TEST(Sim, DeterministicForASeed) {
  SimConfig c = static_scanner();
  c.scene.boxes.push_back({{4.0, -50.0, -50.0}, {4.5, 50.0, 50.0}, 0.5});
  c.scanner.range_sigma = 0.005;
  c.lines_per_pass = 20;
  const auto a = simulate(c), b = simulate(c);
  c.seed = 2;
  const auto d = simulate(c);
  EXPECT_EQ(a.passes[0].pass.range, b.passes[0].pass.range);
  EXPECT_NE(a.passes[0].pass.range, d.passes[0].pass.range);
}

TEST(Sim, TheVehicleFollowsTheTerrain) {
  SimConfig c;
  c.scene.undulation_amplitude = 0.3;
  c.scene.undulation_wavelength = 8.0;
  c.motion.follow_terrain = true;
  c.motion.start = {0, 0, 0.5};
  c.motion.speed = 2.0;
  for (double t : {0.3, 1.1, 2.7}) {
    const Eigen::Isometry3d T = vehicle_pose(c, t);
    const double x = T.translation().x(), y = T.translation().y();
    EXPECT_NEAR(T.translation().z(), c.scene.terrain_height(x, y) + 0.5, 1e-9);
    // The vehicle's z axis is the terrain normal.
    const double e = 1e-4;
    const Eigen::Vector3d n(-(c.scene.terrain_height(x + e, y) - c.scene.terrain_height(x - e, y)) / (2 * e),
                            -(c.scene.terrain_height(x, y + e) - c.scene.terrain_height(x, y - e)) / (2 * e), 1.0);
    EXPECT_GT(T.linear().col(2).dot(n.normalized()), 1.0 - 1e-6);
  }
}
