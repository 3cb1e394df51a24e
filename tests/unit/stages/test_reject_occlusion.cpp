#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_occlusion.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
struct Outcome {
  std::uint64_t occl = 0, occl_rejected = 0, low = 0, low_rejected = 0, valid = 0, valid_rejected = 0, repaired = 0;
};

Outcome run_setting(char which, std::uint64_t seed, const OcclusionParams& prm, int passes = 4) {
  bench::Setting st = bench::make_setting(which, seed);
  st.sim.passes = passes;
  const sim::SimResult r = sim::simulate(st.sim);
  const PoseTrack poses(r.poses);
  const Eigen::Isometry3d T_V_N = make_transform(st.sim.mount_translation, st.sim.mount_rpy, st.sim.rpy_order);
  Outcome o;
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, RegisterParams{}, st.sensor, T_V_N, &poses);
    std::vector<char> before(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) before[i] = p.is_kept(i);
    const OcclusionCounts c = reject_occlusion(p, prm, st.sensor);
    o.repaired += c.repaired;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (!before[i]) continue;
      const bool rej = !p.is_kept(i) || (p.flags[i] & kFlagRepaired);
      if (sp.truth[i] == Label::kOcclusion) {
        ++o.occl;
        o.occl_rejected += rej;
      } else if (sp.truth[i] == Label::kLowAmplitude) {
        ++o.low;
        o.low_rejected += rej;
      } else if (sp.truth[i] == Label::kKept) {
        ++o.valid;
        o.valid_rejected += rej;
      }
    }
  }
  return o;
}

}  // namespace

TEST(RejectOcclusion, MeetsRecallAndFalseRejectionOnTwoSensorSettings) {
  // The same seeds as bench/pcdp_occlusion_bench (which adds the baselines), aggregated: single
  // seeds hold only 15-25 occlusion false ranges each.
  for (char which : {'A', 'B'}) {
    Outcome o;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      const Outcome s = run_setting(which, seed, OcclusionParams{});
      o.occl += s.occl;
      o.occl_rejected += s.occl_rejected;
      o.low += s.low;
      o.low_rejected += s.low_rejected;
      o.valid += s.valid;
      o.valid_rejected += s.valid_rejected;
    }
    ASSERT_GT(o.occl, 10u) << which;
    EXPECT_GE(static_cast<double>(o.occl_rejected) / static_cast<double>(o.occl), 0.95) << which;
    EXPECT_LE(static_cast<double>(o.valid_rejected) / static_cast<double>(o.valid), 0.005) << which;
    EXPECT_GE(static_cast<double>(o.low_rejected) / static_cast<double>(o.low), 0.9) << which;
  }
}

TEST(RejectOcclusion, RepairReplacesFalseRangesAndFlagsThem) {
  OcclusionParams prm;
  prm.repair = true;
  const Outcome o = run_setting('A', 2, prm, 2);
  EXPECT_GT(o.repaired, 5u);
  EXPECT_GE(o.occl_rejected, o.occl * 9 / 10);  // repaired counts as handled
}

TEST(RejectOcclusion, NoisyNearThresholdValidReturnsAreKept) {
  // A far, weak, smooth surface: amplitudes scattered around the threshold, ranges consistent.
  std::vector<float> r, a;
  for (int i = 0; i < 40; ++i) {
    r.push_back(15.0f + 0.02f * static_cast<float>(i));
    a.push_back(static_cast<float>(18 + ((i * 7) % 9) - 4));  // 14 .. 22
  }
  Pass p = test::line_pass(r, a);
  SensorParams s;
  s.min_amplitude = 18;
  const OcclusionCounts c = reject_occlusion(p, OcclusionParams{}, s);
  EXPECT_GT(c.suspects, 20u);
  EXPECT_EQ(p.kept(), p.size());
}

/// Liu et al. Fig. 13's sensor: fixed transceiver angle, 2.9 cm separation, 3 mrad. The near side
/// of the test lines is at lower bearing; with theta = 0 the receiver (+bearing side) would be on
/// the far side (no dip); theta = pi puts it on the near side.
static SensorParams fig13_sensor() {
  SensorParams s;
  s.min_amplitude = 18;
  s.beam_divergence = 0.003;
  s.transceiver_separation = 0.029;
  s.transceiver_angle = TransceiverAngle::kFixed;
  s.transceiver_angle_offset = 3.14159265358979;
  return s;
}

TEST(RejectOcclusion, BelowTheThresholdOneFittingSideIsNotEnough) {
  // A step from 6 m to 12 m on a coaxial sensor (no dip). The suspect between the sides fits the
  // near side only, as a valid return at an edge would, and as a false range does by chance.
  std::vector<float> r = {6.0f, 6.0f, 6.0f, 6.0f, 6.02f, 12.0f, 12.0f, 12.0f, 12.0f};
  SensorParams s;
  s.min_amplitude = 18;
  s.transceiver_separation = 0.0;
  const auto label_at = [&](float amplitude) {
    std::vector<float> a(r.size(), 60.0f);
    a[4] = amplitude;
    Pass p = test::line_pass(r, a);
    reject_occlusion(p, OcclusionParams{}, s);
    return p.label[4];
  };
  // Reported at or above the threshold (noise put it near): one side is enough.
  EXPECT_EQ(label_at(18.0f), Label::kKept);
  EXPECT_EQ(label_at(23.0f), Label::kKept);
  // Reported below it, more likely false than not: two sides must fit, and only one does.
  EXPECT_EQ(label_at(17.0f), Label::kLowAmplitude);
  EXPECT_EQ(label_at(13.0f), Label::kLowAmplitude);
  // The same weak return inside a smooth surface: both sides lie on one line through it.
  for (std::size_t k = 5; k < r.size(); ++k) r[k] = 6.0f;
  EXPECT_EQ(label_at(13.0f), Label::kKept);
  // One return of the near surface on the right before the step: the nearest fits, both sides do.
  for (std::size_t k = 6; k < r.size(); ++k) r[k] = 12.0f;
  EXPECT_EQ(label_at(13.0f), Label::kKept);
}

TEST(RejectOcclusion, AtAPredictedDipOneFittingSideIsEnough) {
  // Near surface at 5 m, far at 12 m, the receiver on the near side (Liu et al. Fig. 13): a dip is
  // predicted. A return reported just below the threshold but on the near surface is a valid
  // return at the edge (it lies on one of the two surfaces); an arbitrary range there is not.
  std::vector<float> r = {5.0f, 5.0f, 5.0f, 5.0f, 5.0f, 12.0f, 12.0f, 12.0f, 12.0f, 12.0f};
  std::vector<float> a = {115, 115, 115, 115, 17, 50, 50, 50, 50, 50};
  const SensorParams s = fig13_sensor();
  Pass p = test::line_pass(r, a);
  reject_occlusion(p, OcclusionParams{}, s);
  EXPECT_EQ(p.label[4], Label::kKept);
  r[4] = 23.7f;  // fits neither side
  Pass q = test::line_pass(r, a);
  reject_occlusion(q, OcclusionParams{}, s);
  EXPECT_EQ(q.label[4], Label::kOcclusion);
}

TEST(RejectOcclusion, ADipAtAnEdgeIsOcclusionAndAWeakReturnElsewhereIsLowAmplitude) {
  // Near surface at 5 m (bright), a dip with a false range, far surface at 12 m; then, on the far
  // surface, an isolated weak return whose range is arbitrary.
  std::vector<float> r = {5.0f, 5.0f, 5.0f, 5.0f, 23.7f, 12.0f, 12.0f, 12.0f, 12.0f, 12.0f, 12.0f, 3.3f, 12.0f, 12.0f, 12.0f};
  std::vector<float> a = {115, 115, 115, 115, 4, 50, 50, 50, 50, 50, 50, 10, 50, 50, 50};
  SensorParams s = fig13_sensor();
  Pass p = test::line_pass(r, a);
  reject_occlusion(p, OcclusionParams{}, s);
  EXPECT_EQ(p.label[4], Label::kOcclusion);
  EXPECT_EQ(p.label[11], Label::kLowAmplitude);
  EXPECT_EQ(p.kept(), p.size() - 2);
  // A coaxial sensor predicts no dip: the same false range is only a weak return.
  s.transceiver_separation = 0.0;
  Pass q = test::line_pass(r, a);
  reject_occlusion(q, OcclusionParams{}, s);
  EXPECT_EQ(q.label[4], Label::kLowAmplitude);
  // Receiver on the far side: no occlusion either.
  s.transceiver_separation = 0.029;
  s.transceiver_angle_offset = 0.0;
  Pass w = test::line_pass(r, a);
  reject_occlusion(w, OcclusionParams{}, s);
  EXPECT_EQ(w.label[4], Label::kLowAmplitude);
}

TEST(RejectOcclusion, OptionsAreValidatedTogether) {
  try {
    test::stage_from_yaml("reject_occlusion", {"window: 2", "stable: 3"});
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("option 'stable' = 3 must not exceed 'window' = 2"), std::string::npos) << e.what();
  }
}

TEST(RejectOcclusion, TheAmplitudeMarginIsInTheSensorsUnits) {
  // A 16-bit amplitude channel sets a margin in its own units, above 255; a negative one is refused.
  const auto load = [](const std::string& margin) {
    return test::stage_from_yaml("reject_occlusion", {"amplitude_margin: " + margin},
                                 "{amplitude_saturation: 65535, min_amplitude: 1200}");
  };
  EXPECT_NE(load("400"), nullptr);
  EXPECT_THROW(load("-1"), ConfigError);
}

TEST(RejectOcclusion, UnmeasuredAmplitudeIsNeverJudgedWeak) {
  // A sensor without intensity (NaN amplitude, "not measured"): a range edge with a jump and a
  // far surface. Nothing may be labelled occlusion or low_amplitude on an amplitude it never had.
  std::vector<float> r, a;
  for (int i = 0; i < 40; ++i) {
    r.push_back(i < 20 ? 5.0f : 12.0f + 0.01f * static_cast<float>(i));
    a.push_back(NAN);
  }
  r[20] = 8.0f;  // a lone range between the surfaces, as a false range would be
  Pass p = test::line_pass(r, a);
  SensorParams s;
  s.min_amplitude = 18;
  const OcclusionCounts c = reject_occlusion(p, OcclusionParams{}, s);
  EXPECT_EQ(c.suspects, 0u);
  EXPECT_EQ(p.kept(), p.size());
}
