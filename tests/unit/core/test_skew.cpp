#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/core/pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/core/skew.hpp"

using namespace pcdp;

TEST(Skew, RecoversTheTrueNodOfAConstantRateNodWithinTheEncoderResolution) {
  sim::SimConfig cfg;
  cfg.scanner.beams = 181;
  cfg.scanner.nod_rate = 1.5708;  // 90 deg/s, Broten & Collier's maximum rate
  cfg.scanner.nod_min = -0.6;
  cfg.scanner.nod_max = 0.2;
  cfg.scanner.encoder_resolution = 0.0012566;  // 0.072 deg
  cfg.lines_per_pass = 150;                    // 2 s: includes both nod reversals
  const auto run = sim::simulate(cfg);
  const Pass& p = run.passes[0].pass;
  const EncoderTrack track = encoder_track(p, 0.0);
  std::size_t hint = 0;
  double worst_corrected = 0.0, worst_raw = 0.0;
  std::size_t steady = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    // Away from the reversals, where the rate is constant between readings.
    const double t = p.stamp[i];
    const double half = (cfg.scanner.nod_max - cfg.scanner.nod_min) / cfg.scanner.nod_rate;  // reversals at k * half
    const double dist_to_rev = std::fabs(t - std::round(t / half) * half);
    const double corrected = track.angle_at(t, hint);
    const double err = std::fabs(corrected - run.passes[0].true_nod[i]);
    if (dist_to_rev > 0.03) {
      worst_corrected = std::max(worst_corrected, err);
      worst_raw = std::max(worst_raw, static_cast<double>(std::fabs(p.nod[i] - run.passes[0].true_nod[i])));
      ++steady;
    }
  }
  ASSERT_GT(steady, p.size() / 2);
  EXPECT_LE(worst_corrected, cfg.scanner.encoder_resolution);
  // Without correction the first return of a line lags by omega * tau (about 21 mrad here).
  EXPECT_GT(worst_raw, 10 * cfg.scanner.encoder_resolution);
}

TEST(Skew, LatencyShiftsTheReadingsBackInTime) {
  // Readings a(t) = 2 t at t = 1, 2, 3, but they describe the angle `latency` earlier.
  EncoderTrack track({1.0, 2.0, 3.0}, {2.0, 4.0, 6.0}, 0.25);
  std::size_t hint = 0;
  EXPECT_NEAR(track.angle_at(0.75, hint), 2.0, 1e-12);
  EXPECT_NEAR(track.angle_at(1.25, hint), 3.0, 1e-12);
  // Extrapolation at both ends with the local rate.
  EXPECT_NEAR(track.angle_at(0.25, hint), 1.0, 1e-12);
  EXPECT_NEAR(track.angle_at(3.25, hint), 7.0, 1e-12);
  // A single reading: no rate to use.
  EncoderTrack one({1.0}, {0.5}, 0.0);
  EXPECT_DOUBLE_EQ(one.angle_at(7.0, hint), 0.5);
}

TEST(Skew, ReversalsAreInterpolatedLocally) {
  // Up then down: the interpolated angle never exceeds the readings' peak.
  EncoderTrack track({0.0, 1.0, 2.0}, {0.0, 1.0, 0.0}, 0.0);
  std::size_t hint = 0;
  for (double t = 0.0; t <= 2.0; t += 0.05) EXPECT_LE(track.angle_at(t, hint), 1.0 + 1e-12);
  EXPECT_NEAR(track.angle_at(1.5, hint), 0.5, 1e-12);
}
