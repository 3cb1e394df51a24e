#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pcdp/models/calibration.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/register.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(CalibrateRange, RecoversKAndBOfSimulatedDataWithinTheirStandardErrors) {
  // Ye & Borenstein eq. 6: z = Int_mm(n y + c + xi), n = 0.9998, c = 3.6 mm, sigma = 5.3 mm, at
  // 20 mm steps from 0.212 m to 4.012 m, 50 samples each. The calibration inverts it:
  // k = 1 / n, b = -c / n.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> xi(0.0, 0.0053);
  std::vector<double> y, z;
  for (int i = 0; i < 191; ++i) {
    const double yi = 0.212 + 0.02 * i;
    for (int s = 0; s < 50; ++s) {
      y.push_back(yi);
      z.push_back(std::round((0.9998 * yi + 0.0036 + xi(rng)) * 1000.0) / 1000.0);
    }
  }
  const RangeCalibration c = fit_range_calibration(y, z);
  std::cout << "k = " << c.k << " +/- " << c.se_k << ", b = " << c.b << " +/- " << c.se_b << "\n";
  EXPECT_EQ(c.distances, 191u);
  EXPECT_LT(std::fabs(c.k - 1.0 / 0.9998), 3 * c.se_k);
  EXPECT_LT(std::fabs(c.b + 0.0036 / 0.9998), 3 * c.se_b);
  EXPECT_LT(c.se_k, 1e-4);
  EXPECT_LT(c.se_b, 2e-4);
  // The mean of 50 samples has sigma 0.75 mm: the residuals say so.
  EXPECT_NEAR(c.rms, 0.0053 / std::sqrt(50.0), 0.0003);
}

TEST(CalibrateRange, DegenerateInputGivesAClearError) {
  try {
    fit_range_calibration({2.0, 2.0, 2.0}, {2.001, 2.003, 2.002});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("needs samples at 3 or more distinct true distances, got 1"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(fit_range_calibration({1.0, 2.0}, {1.0}), InputError);
}

namespace {
std::vector<Eigen::Vector3d> floor_scan_in_nod_frame(const sim::SimConfig& c, const SensorParams& s) {
  const auto r = sim::simulate(c);
  std::vector<Eigen::Vector3d> pts;
  RegisterParams rp;
  rp.covariance = false;
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, rp, s, Eigen::Isometry3d::Identity(), nullptr);
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p.is_kept(i)) pts.emplace_back(p.x[i], p.y[i], p.z[i]);
  }
  return pts;
}
}  // namespace

TEST(CalibrateMount, RecoversTheRaptorsPitchAndHeightFromAFloorScan) {
  // Broten & Collier 7.4: mount pitch 11.33 deg, height 1.64 m; the vehicle stands on a flat pad.
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    sim::SimConfig c;
    c.rpy_order = order;
    c.mount_translation = {0.5, 0.0, 1.64};
    c.mount_rpy = {0.2 * kDeg, 11.33 * kDeg, 0.0};
    c.motion.speed = 0.0;
    c.scanner.nod_min = -0.5;
    c.scanner.nod_max = 0.1;
    c.scanner.encoder_resolution = 0.0012566;
    c.scanner.range_n = 0.9998;
    c.scanner.range_c = 0.0036;
    c.scanner.range_sigma = 0.0053;
    c.scanner.range_quantum = 0.001;
    c.lines_per_pass = 150;
    SensorParams s;
    s.range_k = 1.0 / 0.9998;
    s.range_b = -0.0036 / 0.9998;
    const auto pts = floor_scan_in_nod_frame(c, s);
    const MountCalibration m = calibrate_mount(pts, 0.0, order);
    std::cout << rpy_order_name(order) << ": pitch " << m.rpy.pitch / kDeg << " deg, roll " << m.rpy.roll / kDeg
              << " deg, height " << m.height << " m\n";
    EXPECT_NEAR(m.rpy.pitch / kDeg, 11.33, 0.05);
    EXPECT_NEAR(m.rpy.roll / kDeg, 0.2, 0.05);
    EXPECT_NEAR(m.height, 1.64, 0.005);
  }
}

TEST(CalibrateMount, NoFloorInViewGivesAClearError) {
  // Looking up at the sky: nothing returns.
  sim::SimConfig c;
  c.mount_translation = {0, 0, 1.0};
  c.mount_rpy = {0, -0.6, 0};  // tipped up
  c.scanner.nod_min = 0.0;
  c.scanner.nod_max = 0.3;
  c.lines_per_pass = 40;
  try {
    calibrate_mount(floor_scan_in_nod_frame(c, SensorParams{}), 0.0, RpyOrder::kXyz);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no floor in view"), std::string::npos) << e.what();
  }
  // A wall only: the largest plane stands far from the floor the mount implies.
  c.mount_rpy = {0, 0, 0};
  c.scanner.nod_min = 0.05;
  c.scanner.nod_max = 0.4;
  c.scene.boxes.push_back({{5.0, -50.0, -50.0}, {5.5, 50.0, 50.0}, 0.5});
  const auto pts = floor_scan_in_nod_frame(c, SensorParams{});
  ASSERT_GT(pts.size(), 1000u);
  try {
    calibrate_mount(pts, 0.0, RpyOrder::kXyz);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("deg from the floor the configured mount implies (a wall?)"), std::string::npos)
        << e.what();
  }
}
