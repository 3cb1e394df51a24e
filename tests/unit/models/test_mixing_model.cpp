// Property tests of the mixed-pixel model (models/mixing_model.hpp) and its agreement with the
// ray-traced simulator, which knows nothing of the formulas: it sums sub-ray powers and ranges.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "pcdp/models/mixing_model.hpp"
#include "pcdp/sim/nodding_sim.hpp"

using namespace pcdp;

namespace {
struct Surfaces {
  double d1, p1, d2, p2;
};
/// Two surfaces as scanners meet them: 0.3-30 m, the far one 1 cm-10 m behind, amplitudes 1-1000.
Surfaces random_surfaces(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double d1 = 0.3 + 30.0 * u(rng);
  return {d1, std::exp(std::log(1000.0) * u(rng)), d1 + 0.01 + 10.0 * u(rng), std::exp(std::log(1000.0) * u(rng))};
}
}  // namespace

TEST(MixingModel, RangeLiesBetweenTheSurfacesAndFallsAsTheNearShareGrows) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 5000; ++k) {
    const Surfaces s = random_surfaces(rng);
    EXPECT_NEAR(mixture_range(1.0, s.d1, s.p1, s.d2, s.p2), s.d1, 1e-9 * s.d2);
    EXPECT_NEAR(mixture_range(0.0, s.d1, s.p1, s.d2, s.p2), s.d2, 1e-9 * s.d2);
    const double f = u(rng), g = f + (1 - f) * u(rng) * 0.999 + 1e-6;
    const double rf = mixture_range(f, s.d1, s.p1, s.d2, s.p2), rg = mixture_range(g, s.d1, s.p1, s.d2, s.p2);
    EXPECT_GE(rf, s.d1 - 1e-12);
    EXPECT_LE(rf, s.d2 + 1e-12);
    EXPECT_LT(rg, rf + 1e-12) << k;  // more of the footprint on the near surface: nearer
    const double a = mixture_amplitude(f, s.p1, s.p2);
    EXPECT_GE(a, std::min(s.p1, s.p2) - 1e-9);
    EXPECT_LE(a, std::max(s.p1, s.p2) + 1e-9);
  }
}

TEST(MixingModel, TheRangeFixesTheShareAndTheAmplitude) {
  // r alone gives the footprint share; the amplitude then follows (the stage tests a return's
  // amplitude against it). Round trip over random surfaces and shares.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 5000; ++k) {
    const Surfaces s = random_surfaces(rng);
    const double f = u(rng);
    const double r = mixture_range(f, s.d1, s.p1, s.d2, s.p2);
    EXPECT_NEAR(mixture_share(r, s.d1, s.p1, s.d2, s.p2), f, 1e-6) << k;
    const double a = mixture_amplitude(f, s.p1, s.p2);
    EXPECT_NEAR(mixture_amplitude_at(r, s.d1, s.p1, s.d2, s.p2), a, 1e-6 * a) << k;
  }
}

TEST(MixingModel, AmplitudeAtRangeIsClampedAndRefusesNonsense) {
  const Surfaces s{5.0, 100.0, 8.0, 20.0};
  EXPECT_DOUBLE_EQ(mixture_amplitude_at(4.0, s.d1, s.p1, s.d2, s.p2), 100.0);  // in front: the near surface
  EXPECT_DOUBLE_EQ(mixture_amplitude_at(9.0, s.d1, s.p1, s.d2, s.p2), 20.0);   // behind: the far one
  // Halfway in range is far from halfway in amplitude: the bright surface pulls the range to it,
  // so a mixture halfway between is mostly (by area) on the dim far surface.
  EXPECT_NEAR(mixture_amplitude_at(6.5, s.d1, s.p1, s.d2, s.p2), 1.0 / (0.5 / 100 + 0.5 / 20), 1e-9);
  EXPECT_TRUE(std::isnan(mixture_amplitude_at(6.0, 8.0, 100, 5.0, 20)));  // far before near
  EXPECT_TRUE(std::isnan(mixture_amplitude_at(6.0, 5.0, 0.0, 8.0, 20)));
  EXPECT_TRUE(std::isnan(mixture_amplitude_at(NAN, 5.0, 100, 8.0, 20)));
  EXPECT_TRUE(std::isnan(mixture_share(9.0, 5.0, 100, 8.0, 20)));  // outside: no mixture of these two
  EXPECT_TRUE(std::isnan(mixture_share(6.0, 5.0, 100, 5.0, 20)));
}

TEST(MixingModel, PlaneModelIsExactOnPlanesWhereRangeExtrapolationIsNot) {
  // Three beams of one fan (equal angular steps) meet a random plane. The two outer returns
  // predict the third exactly; extrapolating the range linearly does not at grazing incidence.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int tested = 0, linear_off = 0;
  for (int k = 0; k < 3000; ++k) {
    const Eigen::Vector3d o(u(rng), u(rng), 1.0 + u(rng));
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const double c = n.dot(o) - (1.0 + 10.0 * std::fabs(u(rng)));  // plane n.x = c, 1-11 m from o
    const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d d0 = axis.unitOrthogonal();
    const double step = 0.002 + 0.02 * std::fabs(u(rng));
    double t[3];
    Eigen::Vector3d dir[3], p[3];
    bool ok = true;
    for (int j = 0; j < 3; ++j) {
      dir[j] = Eigen::AngleAxisd(step * j, axis) * d0;
      const double den = n.dot(dir[j]);
      t[j] = (c - n.dot(o)) / den;
      ok = ok && std::fabs(den) > 0.05 && t[j] > 0 && t[j] < 60;  // in front, incidence below 87 deg
      p[j] = o + t[j] * dir[j];
    }
    if (!ok) continue;
    ++tested;
    double miss = -1;
    EXPECT_NEAR(range_on_line(o, dir[2], p[1], p[0], &miss), t[2], 1e-6 * t[2]) << k;
    EXPECT_NEAR(miss, 0.0, 1e-6 * t[2]) << k;  // one fan: the ray meets the line
    linear_off += std::fabs((2 * t[1] - t[0]) - t[2]) > 0.01;
  }
  EXPECT_GT(tested, 300);
  EXPECT_GT(linear_off, 0);  // a linear range trend misses grazing planes by centimetres
}

TEST(MixingModel, PlaneModelRefusesDegenerateLines) {
  const Eigen::Vector3d o(0, 0, 0), d(1, 0, 0);
  EXPECT_TRUE(std::isnan(range_on_line(o, d, {2, 1, 0}, {2, 1, 0})));  // one point
  EXPECT_TRUE(std::isnan(range_on_line(o, d, {2, 1, 0}, {5, 1, 0})));  // parallel to the beam
  EXPECT_NEAR(range_on_line(o, d, {3, -1, 0}, {3, 1, 0}), 3.0, 1e-12);  // a wall across it
  double miss = -1;
  EXPECT_NEAR(range_on_line(o, d, {3, -1, 0.5}, {3, 1, 0.5}, &miss), 3.0, 1e-12);  // passes 0.5 m above the beam
  EXPECT_NEAR(miss, 0.5, 1e-12);
  EXPECT_TRUE(std::isnan(range_on_line(o, d, {2, 1, 0}, {2, 1, 0}, &miss)));
  EXPECT_TRUE(std::isnan(miss));
}

TEST(MixingModel, PlanePredictionMeetsThePlaneAndAgreesWithTheLineModel) {
  // Random planes and rays: the predicted point lies on the plane; for two returns a, b on the
  // plane in the ray's own fan (one scan line), the line model predicts the same range; a ray
  // parallel to the plane predicts nothing.
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int tested = 0;
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector3d o(u(rng), u(rng), 1.0 + u(rng));
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d q = o + Eigen::Vector3d(6 * u(rng), 6 * u(rng), 6 * u(rng));  // a point on the plane
    const Eigen::Vector3d d0 = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d axis = d0.unitOrthogonal();
    Eigen::Vector3d dir[3];
    double t[3];
    bool ok = true;
    for (int j = 0; j < 3; ++j) {
      dir[j] = Eigen::AngleAxisd(0.01 * j, axis) * d0;
      t[j] = range_on_plane(o, dir[j], q, n);
      ok = ok && std::isfinite(t[j]) && t[j] > 0 && t[j] < 60 && std::fabs(n.dot(dir[j])) > 0.05;
    }
    if (!ok) continue;
    ++tested;
    EXPECT_NEAR(n.dot(o + t[0] * dir[0] - q), 0.0, 1e-9 * t[0]) << k;
    EXPECT_NEAR(t[0], range_on_line(o, dir[0], o + t[1] * dir[1], o + t[2] * dir[2]), 1e-6 * t[0]) << k;
  }
  EXPECT_GT(tested, 100);
  const Eigen::Vector3d o(0, 0, 1), n(0, 0, 1);
  EXPECT_TRUE(std::isnan(range_on_plane(o, {1, 0, 0}, {5, 0, 0}, n)));                      // parallel: nothing
  EXPECT_NEAR(range_on_plane(o, Eigen::Vector3d(1, 0, -1).normalized(), {5, 3, 0}, n), std::sqrt(2.0), 1e-12);  // ground, 45 deg
  EXPECT_LT(range_on_plane(o, {0, 0, 1}, {0, 0, 0}, n), 0.0);                                // the plane is behind
}

TEST(MixingModel, AgreesWithTheRayTracedSimulator) {
  // A coaxial beam (nothing hidden from the receiver) straddling the vertical edge of a near box
  // in front of a far wall: the simulator's range and amplitude must be a mixture of the model's,
  // with P1 and P2 read from beams fully on each surface.
  sim::SimConfig c;
  c.scene.ground_z = -100;
  c.scanner.beam_divergence = 0.01;
  c.scanner.subrays = 4000;
  c.scanner.transceiver_separation = 0.0;
  c.scanner.amplitude_range_exponent = 2.0;
  c.scanner.amplitude_scale = 4000.0;
  c.scene.boxes.push_back({{4.0, -3.0, -3.0}, {4.2, 0.0, 3.0}, 0.8});   // near, bright, edge at y = 0
  c.scene.boxes.push_back({{9.0, -6.0, -6.0}, {9.4, 6.0, 6.0}, 0.1});   // far, dark
  const auto beam = [&](double bearing) {
    const Eigen::Vector3d d(std::cos(bearing), std::sin(bearing), 0.0), uu(-std::sin(bearing), std::cos(bearing), 0.0),
        v(0, 0, 1);
    return sim::cast_beam(c, Eigen::Vector3d::Zero(), d, uu, v, bearing);
  };
  const auto near = beam(-0.05), far = beam(0.05);
  ASSERT_NEAR(near.range, 4.0 / std::cos(0.05), 1e-3);
  ASSERT_NEAR(far.range, 9.0 / std::cos(0.05), 2e-3);
  int mixtures = 0;
  for (double b = -0.006; b <= 0.006; b += 0.0005) {
    const auto m = beam(b);
    const double d1 = 4.0 / std::cos(b), d2 = 9.0 / std::cos(b);
    if (!(m.range > d1 + 0.05 && m.range < d2 - 0.05)) continue;
    ++mixtures;
    // P1, P2 at this bearing: the cos and range terms of the full beams, scaled to this bearing.
    const double p1 = near.amplitude * std::pow(std::cos(b) / std::cos(0.05), 3.0);
    const double p2 = far.amplitude * std::pow(std::cos(b) / std::cos(0.05), 3.0);
    EXPECT_NEAR(m.amplitude, mixture_amplitude_at(m.range, d1, p1, d2, p2), 0.02 * m.amplitude) << b;
  }
  EXPECT_GT(mixtures, 5);
}
