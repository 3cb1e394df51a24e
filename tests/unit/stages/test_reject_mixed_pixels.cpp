#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/stage.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/import/3dtk.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/models/mixing_model.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/stages/reject_occlusion.hpp"
#include "pcdp_test_paths.hpp"
#include "kurt3d_reference.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
SensorParams coaxial_sensor() {
  SensorParams s;
  s.transceiver_separation = 0.0;
  return s;
}

/// An organized pass: one line per row of ranges (bearing 0.01 rad apart), lines 0.01 rad apart
/// in nod (or at `nods`), amplitude 100 everywhere.
Pass grid_pass(const std::vector<std::vector<float>>& rows, const std::vector<float>& nods = {}) {
  Pass p;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    p.line_begin.push_back(p.range.size());
    for (std::size_t b = 0; b < rows[k].size(); ++b) {
      p.line.push_back(static_cast<std::uint32_t>(k));
      p.beam.push_back(static_cast<std::uint32_t>(b));
      p.range.push_back(rows[k][b]);
      p.bearing.push_back(0.01f * static_cast<float>(b));
      p.amplitude.push_back(100.0f);
      p.nod.push_back(nods.empty() ? 0.01f * static_cast<float>(k) : nods[k]);
      p.stamp.push_back(1e-2 * static_cast<double>(k) + 1e-4 * static_cast<double>(b));
    }
  }
  p.line_begin.push_back(p.range.size());
  p.label.assign(p.range.size(), Label::kKept);
  p.flags.assign(p.range.size(), 0);
  register_pass(p, RegisterParams{}, SensorParams{}, Eigen::Isometry3d::Identity(), nullptr);
  return p;
}

/// Rows of a wall at 10 m, 21 beams wide, with one return in front of it at beam 10 per line.
std::vector<std::vector<float>> spike_in_wall(const std::vector<float>& spike) {
  std::vector<std::vector<float>> rows;
  for (float c : spike) {
    std::vector<float> row(21, 10.0f);
    row[10] = c;
    rows.push_back(row);
  }
  return rows;
}

/// Which lines' return at beam 10 the stage flags (coaxial sensor).
std::vector<bool> flagged_at_beam_10(Pass p, const MixedPixelParams& mp) {
  reject_mixed_pixels(p, mp, coaxial_sensor());
  std::vector<bool> f;
  for (std::size_t k = 0; k < p.line_count(); ++k) f.push_back(p.label[p.line_begin[k] + 10] == Label::kMixedPixel);
  return f;
}
/// How many returns of `raw` the pipeline stage labels otherwise than `batch` (the whole pass
/// through reject_mixed_pixels) when each line is labelled in a window of the stage's reach on
/// each side, as `LineStream` does.
std::size_t labels_streamed_otherwise(const Pass& raw, const Pass& batch, const SensorParams& s) {
  PipelineConfig cfg;
  cfg.sensor = s;
  RunContext ctx;
  ctx.config = &cfg;
  const auto stage = reject_mixed_pixels_stage_info().create(StageConfig{"reject_mixed_pixels", "reject_mixed_pixels", "test", {}}, ctx);
  const std::size_t reach = static_cast<std::size_t>(stage->reach());
  // The window of 8 past up to 16 returns read past a footprint, one line for a nod reversal, two
  // rounds of 3 (docs/mixed_pixels.md, "Streaming").
  EXPECT_EQ(reach, 31u);
  std::size_t differ = 0;
  for (std::size_t k = 0; k < raw.line_count(); ++k) {
    const std::size_t from = k >= reach ? k - reach : 0, to = std::min(raw.line_count(), k + reach + 1);
    Pass w = lines_of(raw, from, to);
    StageReport report;
    stage->label(w, report);
    for (std::size_t i = raw.line_begin[k]; i < raw.line_begin[k + 1]; ++i)
      differ += w.label[i - raw.line_begin[from]] != batch.label[i];
  }
  return differ;
}
}  // namespace

TEST(RejectMixedPixels, AVeilBetweenTwoSurfacesIsFlaggedAndTheSurfacesAreNot) {
  std::vector<float> r(10, 5.0f), a(10, 100.0f);
  r.push_back(7.5f);  // half and half: f = 0.5 with P1 = 100, P2 = 100 -> amplitude 100
  a.push_back(100.0f);
  for (int i = 0; i < 10; ++i) {
    r.push_back(10.0f);
    a.push_back(100.0f);
  }
  Pass p = test::line_pass(r, a);
  EXPECT_EQ(reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor()), 1u);
  EXPECT_EQ(p.label[10], Label::kMixedPixel);
  EXPECT_EQ(p.flags[10], kFlagMixedAlong);  // its evidence: the tests along its line, both sides seen
  // Only the return itself, never a window of neighbours.
  EXPECT_EQ(p.label[9], Label::kKept);
  EXPECT_EQ(p.label[11], Label::kKept);
}

TEST(RejectMixedPixels, AMuchBrighterReturnBetweenTheSurfacesIsARealObject) {
  std::vector<float> r(10, 5.0f), a(10, 40.0f);
  r.push_back(7.5f);
  a.push_back(250.0f);  // the mixture of 40 and 40 cannot be this bright
  for (int i = 0; i < 10; ++i) {
    r.push_back(10.0f);
    a.push_back(40.0f);
  }
  Pass p = test::line_pass(r, a);
  EXPECT_EQ(reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor()), 0u);
}

TEST(RejectMixedPixels, TheClippingLevelIsTheSensors) {
  // A 16-bit amplitude channel: surfaces at 4000, a return between them at 20000 (five times
  // the brightest mixture: a real object). Told that the sensor clips at 255, the stage takes
  // every amplitude for clipped, cannot use them, and flags it; told the real level, it keeps it.
  std::vector<float> r(10, 5.0f), a(10, 4000.0f);
  r.push_back(7.5f);
  a.push_back(20000.0f);
  for (int i = 0; i < 10; ++i) {
    r.push_back(10.0f);
    a.push_back(4000.0f);
  }
  SensorParams s = coaxial_sensor();
  Pass clipped = test::line_pass(r, a), wide = clipped;
  EXPECT_EQ(reject_mixed_pixels(clipped, MixedPixelParams{}, s), 1u);
  s.amplitude_saturation = 65535;
  EXPECT_EQ(reject_mixed_pixels(wide, MixedPixelParams{}, s), 0u);
}

TEST(RejectMixedPixels, TheAmplitudeSlackIsInTheSensorsUnits) {
  // A 16-bit amplitude channel needs a slack in its own units, far above 255 (the bound of an
  // 8-bit channel); a negative slack is still refused, naming the stage, the key and the rule.
  const auto load = [](const std::string& slack) {
    return test::stage_from_yaml("reject_mixed_pixels", {"amplitude_slack: " + slack}, "{amplitude_saturation: 65535}");
  };
  EXPECT_NE(load("2000"), nullptr);
  try {
    load("-1");
    FAIL() << "a negative slack was accepted";
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("amplitude_slack"), std::string::npos) << m;
    EXPECT_NE(m.find("reject_mixed_pixels"), std::string::npos) << m;
  }
}

TEST(RejectMixedPixels, AThinPostAndASmoothSlopeAreKept) {
  std::vector<float> r(21, 10.0f), a(21, 60.0f);
  r[10] = 5.0f;  // a post one return wide
  Pass p = test::line_pass(r, a);
  EXPECT_EQ(reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor()), 0u);
  std::vector<float> slope;
  for (int i = 0; i < 30; ++i) slope.push_back(6.0f + 0.4f * static_cast<float>(i) + 0.01f * static_cast<float>(i * i));
  Pass q = test::line_pass(slope, std::vector<float>(30, 60.0f));
  EXPECT_EQ(reject_mixed_pixels(q, MixedPixelParams{}, coaxial_sensor()), 0u);
}

TEST(RejectMixedPixels, BesideAVoidAReturnThatBreaksFromItsOneSurfaceIsAMixture) {
  // Ground at grazing incidence (1 m below the sensor): ranges grow hyperbolically. Before it, a
  // void (a surface too dark to return on its own); next to the void, the return whose footprint
  // straddled the two.
  const auto ground = [](int k) { return static_cast<float>(1.0 / std::sin(0.2 - 0.008 * k)); };
  const auto scan = [&](float first, int voids) {
    std::vector<float> r(static_cast<std::size_t>(voids), 0.0f);  // 0: no return
    r.push_back(first);
    for (int k = 1; k <= 12; ++k) r.push_back(ground(k));
    Pass p = test::line_pass(r, std::vector<float>(r.size(), 100.0f));
    reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor());
    const std::size_t i = static_cast<std::size_t>(voids);
    // Its evidence says so: along the line, beside a void.
    EXPECT_EQ(p.flags[i], p.label[i] == Label::kMixedPixel ? kFlagMixedAlong | kFlagBesideVoid : 0);
    return p.label[i];
  };
  // 0.4 m short of the ground's quadratic trend (its step there is 0.2 m): a mixture.
  EXPECT_EQ(scan(ground(0) - 0.4f, 5), Label::kMixedPixel);
  // On the trend: the first ground return after the void is valid.
  EXPECT_EQ(scan(ground(0), 5), Label::kKept);
  // The same return at the start of the scan line: the end of the field of view is not a void.
  EXPECT_EQ(scan(ground(0) - 0.4f, 0), Label::kKept);
  // Beside a void with ground beyond it, a return that continues that ground is valid.
  std::vector<float> r;
  for (int k = -8; k <= -3; ++k) r.push_back(ground(k));
  r.push_back(0.0f);
  r.push_back(0.0f);
  r.push_back(ground(0) - 0.1f);  // off the right-hand trend, on the left-hand one across the void
  for (int k = 1; k <= 12; ++k) r.push_back(ground(k) - 0.1f);
  Pass p = test::line_pass(r, std::vector<float>(r.size(), 100.0f));
  reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor());
  EXPECT_EQ(p.label[8], Label::kKept);
}

TEST(RejectMixedPixels, BesideAVoidAFewCentimetresPastTheSurfaceIsEnough) {
  // A wall 8 m ahead, then a void (a background too dark to return alone). A footprint mostly on
  // the wall is pulled only share x gap past it: a few centimetres, less than an edge jump
  // (max(jump_min, jump_ratio * r) = 0.12 m here). The far depth is unknown, so the tolerance
  // (0.01 + 0.002 r + 3 sigma = 0.042 m at 8 m) is the bar.
  const auto last = [](float past) {
    std::vector<float> r(12, 8.0f);
    r.push_back(8.0f + past);
    for (int k = 0; k < 5; ++k) r.push_back(0.0f);  // no return
    Pass p = test::line_pass(r, std::vector<float>(r.size(), 100.0f));
    reject_mixed_pixels(p, MixedPixelParams{}, coaxial_sensor());
    return p.label[12];
  };
  EXPECT_EQ(last(0.10f), Label::kMixedPixel);
  EXPECT_EQ(last(0.07f), Label::kMixedPixel);
  // The step must still run along the beam within max_angle (test 3's geometry): beams 0.08 m
  // apart at 8 m make a 0.05 m step a surface turned 58 degrees from the beam, not a veil.
  EXPECT_EQ(last(0.05f), Label::kKept);
  EXPECT_EQ(last(0.02f), Label::kKept);  // within the range noise of the wall
  EXPECT_EQ(last(0.0f), Label::kKept);
}

TEST(RejectMixedPixels, AtACornerTheVeilIsFlaggedAndAFaceSeenEdgeOnIsNot) {
  // Along each line: a wall at 10 m, the return at the corner, one return on a box's side face
  // seen edge-on (9.2 m) and then the box's front (8.6 m). The side's next step is itself an edge,
  // so that side's rate says nothing; the other direction decides.
  const auto lines = [](const std::vector<float>& corner) {
    std::vector<std::vector<float>> rows;
    for (float c : corner) {
      std::vector<float> row(10, 10.0f);
      row.push_back(c);
      row.push_back(9.2f);
      for (int b = 0; b < 9; ++b) row.push_back(8.6f);
      rows.push_back(row);
    }
    return rows;
  };
  // A veil: its range changes from line to line with the split of the footprint.
  Pass veil = grid_pass(lines({9.30f, 9.39f, 9.48f, 9.57f, 9.66f}));
  reject_mixed_pixels(veil, MixedPixelParams{}, coaxial_sensor());
  std::size_t flagged = 0;
  for (std::size_t k = 0; k < veil.line_count(); ++k) {
    flagged += veil.label[veil.line_begin[k] + 10] == Label::kMixedPixel;
    EXPECT_EQ(veil.label[veil.line_begin[k] + 11], Label::kKept) << "the side face, line " << k;
  }
  // The first and last lines have one neighbour across only, and keep its range within an edge
  // jump (0.09 m from line to line): from one neighbour, that is what a face seen edge-on does too.
  // Kept.
  EXPECT_EQ(flagged, 3u);
  // A veil whose range changes faster: the first and last lines do not keep their one neighbour's
  // range, so they are not flat across, and are flagged too.
  Pass fast = grid_pass(lines({9.30f, 9.50f, 9.70f, 9.50f, 9.30f}));
  reject_mixed_pixels(fast, MixedPixelParams{}, coaxial_sensor());
  for (std::size_t k = 0; k < fast.line_count(); ++k) {
    EXPECT_EQ(fast.label[fast.line_begin[k] + 10], Label::kMixedPixel) << "line " << k;
    EXPECT_EQ(fast.label[fast.line_begin[k] + 11], Label::kKept) << "the side face, line " << k;
  }
  // A second face seen edge-on keeps its range from line to line: a surface, not a veil.
  Pass face = grid_pass(lines(std::vector<float>(5, 9.6f)));
  EXPECT_EQ(reject_mixed_pixels(face, MixedPixelParams{}, coaxial_sensor()), 0u);
}

TEST(RejectMixedPixels, AOneBeamSpikeWhoseRangeChangesAcrossLinesIsAMixtureWithAThinObject) {
  // A wall at 10 m; at beam 10, something one return wide in front of it in every line. Both
  // along-line neighbours are the wall, so along the line a thin post and a mixture of a post
  // with the wall look alike; across lines they do not.
  const auto flagged = [](Pass p, bool spikes) {
    MixedPixelParams mp;
    mp.spikes = spikes;
    return flagged_at_beam_10(p, mp);
  };
  // A mixture: the range follows the share of the footprint on the thin object, which changes
  // from line to line. Every line is flagged, the first and last too (one neighbour across is
  // enough: the return is on neither); nothing else is.
  const Pass mixture = grid_pass(spike_in_wall({8.0f, 8.6f, 9.2f, 8.3f, 7.7f, 8.9f}));
  EXPECT_EQ(flagged(mixture, true), std::vector<bool>(6, true));
  Pass all = mixture;
  EXPECT_EQ(reject_mixed_pixels(all, MixedPixelParams{}, coaxial_sensor()), 6u);
  // Without it, the across-line edge tests find some of them, not the first and last lines.
  const std::vector<bool> without = flagged(mixture, false);
  EXPECT_LT(std::count(without.begin(), without.end(), true), 6);
  EXPECT_FALSE(without.front());
  EXPECT_FALSE(without.back());
  // A thin post keeps its range from line to line; its top return has the post below it.
  EXPECT_EQ(flagged(grid_pass(spike_in_wall({6.0f, 6.0f, 6.01f, 6.0f, 6.0f, 6.0f})), true), std::vector<bool>(6, false));
  EXPECT_EQ(flagged(grid_pass(spike_in_wall({6.0f, 6.0f, 6.0f, 10.0f, 10.0f, 10.0f})), true), std::vector<bool>(6, false));
}

TEST(RejectMixedPixels, ASpikeUpToSpikeWidthReturnsWideIsTestedLikeAOneBeamSpike) {
  // A wall at 10 m; from beam 10, a run of `width` returns in front of it in every line: a post
  // one to three beams wide, or the post with the mixtures on its sides. Each return of the run
  // has its own range, varying from line to line (a mixture) or not (the post itself).
  const auto pass = [](std::size_t width, const std::vector<float>& front, float step) {
    std::vector<std::vector<float>> rows;
    for (float c : front) {
      std::vector<float> row(24, 10.0f);
      for (std::size_t q = 0; q < width; ++q) row[10 + q] = c + step * static_cast<float>(q);
      rows.push_back(row);
    }
    return grid_pass(rows);
  };
  // Which returns of the run the stage flags, in the first and last line (where the across-line
  // edge tests have one side only, so only the spike test can find them) and in all lines.
  struct Count {
    std::size_t ends = 0, all = 0, outside = 0;
  };
  const auto flagged = [](Pass p, std::size_t width, int spike_width) {
    MixedPixelParams mp;
    mp.spike_width = spike_width;
    reject_mixed_pixels(p, mp, coaxial_sensor());
    Count c;
    for (std::size_t k = 0; k < p.line_count(); ++k)
      for (std::size_t b = 0; b < p.line_begin[k + 1] - p.line_begin[k]; ++b) {
        const bool f = p.label[p.line_begin[k] + b] == Label::kMixedPixel;
        if (b < 10 || b >= 10 + width) {
          c.outside += f;
          continue;
        }
        c.all += f;
        c.ends += f && (k == 0 || k + 1 == p.line_count());
      }
    return c;
  };
  const std::vector<float> mixture{8.0f, 8.6f, 9.2f, 8.3f, 7.7f, 8.9f};
  for (std::size_t width = 1; width <= 4; ++width) {
    // Mixtures: every return of a run up to spike_width (3) wide, the end lines too; nothing beside it.
    const Count wide = flagged(pass(width, mixture, 0.02f), width, 3);
    EXPECT_EQ(wide.outside, 0u) << "width " << width;
    if (width <= 3) {
      EXPECT_EQ(wide.all, 6 * width) << "width " << width;
    } else {  // a run wider than spike_width: the end lines are not flagged
      EXPECT_EQ(wide.ends, 0u) << "width " << width;
    }
    // With spike_width 1 only one-beam runs are spikes.
    EXPECT_EQ(flagged(pass(width, mixture, 0.02f), width, 1).ends, width == 1 ? 2u : 0u) << "width " << width;
    // A post keeps its range from line to line: nothing flagged, whatever its width.
    EXPECT_EQ(flagged(pass(width, std::vector<float>(6, 6.0f), 0.0f), width, 3).all, 0u) << "width " << width;
  }
  // The run must stand in front of both flanks by an edge jump: a step down to a nearer surface
  // (the wall goes on at 6 m after the run) is not a spike.
  std::vector<std::vector<float>> rows;
  for (float c : mixture) {
    std::vector<float> row(24, 10.0f);
    for (std::size_t b = 10; b < 24; ++b) row[b] = b < 12 ? c : 6.0f;
    rows.push_back(row);
  }
  EXPECT_EQ(flagged(grid_pass(rows), 0, 3).outside - flagged(grid_pass(rows), 0, 1).outside, 0u);
}

TEST(RejectMixedPixels, ASpikeThatKeepsItsRangeAcrossLinesIsAMixtureWhereItsAmplitudeSaysSo) {
  // A dim wall (amplitude 30) at 10 m; at beam 10 a bright post (amplitude 180) at 8 m in lines 3-5
  // and, in lines 0-2, mixtures of post and wall as at the top of a post while the nod turns: their
  // ranges differ by 2 cm from line to line (within the tolerance, so the range test across lines
  // cannot tell them from the post), but their amplitudes follow the mixing model. With a share f
  // of the footprint on the post, r = (180 f 8 + 30 (1 - f) 10) / A and A = 180 f + 30 (1 - f):
  // f = 0.723, 0.76, 0.8 give r = 8.12, 8.10, 8.08 m and A = 138.5, 144, 150.
  const std::vector<float> range{8.12f, 8.10f, 8.08f, 8.0f, 8.0f, 8.0f};
  const auto flagged = [&](const std::vector<float>& spike_amp, float wall_amp, double dim_ratio) {
    Pass p = grid_pass(spike_in_wall(range));
    for (std::size_t k = 0; k < p.line_count(); ++k)
      for (std::size_t b = 0; b < 21; ++b) p.amplitude[p.line_begin[k] + b] = b == 10 ? spike_amp[k] : wall_amp;
    MixedPixelParams mp;
    mp.spike_dim_ratio = dim_ratio;
    return flagged_at_beam_10(p, mp);
  };
  const std::vector<float> mixed_amp{138.5f, 144.0f, 150.0f, 180.0f, 180.0f, 180.0f};
  const std::vector<bool> mixtures{true, true, true, false, false, false};
  EXPECT_EQ(flagged(mixed_amp, 30.0f, 0.9), mixtures);
  // Off (spike_dim_ratio 0), nothing: each return keeps the range of a neighbour across lines.
  EXPECT_EQ(flagged(mixed_amp, 30.0f, 0.0), std::vector<bool>(6, false));
  // As bright as the post: the same object, 8-12 cm deeper (a round post's flank), not a mixture.
  EXPECT_EQ(flagged(std::vector<float>(6, 180.0f), 30.0f, 0.9), std::vector<bool>(6, false));
  // Within spike_dim_ratio of the post (165 > 0.9 x 180 = 162): kept.
  EXPECT_EQ(flagged({165.0f, 165.0f, 165.0f, 180.0f, 180.0f, 180.0f}, 30.0f, 0.9), std::vector<bool>(6, false));
  // A wall as bright as the post: amplitude cannot tell post, wall and mixture apart.
  EXPECT_EQ(flagged(mixed_amp, 170.0f, 0.9), std::vector<bool>(6, false));
  // Dimmer than the wall: not between the two surfaces, so not their mixture.
  EXPECT_EQ(flagged({25.0f, 25.0f, 25.0f, 180.0f, 180.0f, 180.0f}, 30.0f, 0.9), std::vector<bool>(6, false));
  // Clipped: a post at the amplitude ceiling says nothing about the share of its light.
  EXPECT_EQ(flagged({138.5f, 144.0f, 150.0f, 255.0f, 255.0f, 255.0f}, 30.0f, 0.9), std::vector<bool>(6, false));
}

/// Flat ground only, 1 m below a nodding scanner, scanned near the horizon (nod -0.35 to -0.04 rad).
namespace {
/// Flat ground only, 1 m below a nodding scanner, scanned near the horizon (nod -0.35 to -0.04
/// rad), registered: one pass of 120 lines. `position_sigma` and `rpy_sigma`: the noise of the
/// poses it is registered with.
Pass grazing_ground(double nod_rate, double position_sigma = 0.0, double rpy_sigma = 0.0) {
  sim::SimConfig c;
  c.mount_translation = {0, 0, 1.0};
  c.mount_rpy = {0, 0, 0};
  c.scanner.nod_min = -0.35;
  c.scanner.nod_max = -0.04;
  c.scanner.nod_rate = nod_rate;
  c.scanner.range_sigma = 0.0053;
  c.scanner.range_quantum = 0.001;
  c.motion.position_sigma = position_sigma;
  c.motion.rpy_sigma = rpy_sigma;
  c.lines_per_pass = 120;
  const auto r = sim::simulate(c);
  const PoseTrack poses(r.poses);
  Pass p = r.passes[0].pass;
  register_pass(p, RegisterParams{}, coaxial_sensor(), make_transform(c.mount_translation, c.mount_rpy, c.rpy_order),
                &poses);
  return p;
}
}  // namespace

TEST(RejectMixedPixels, GrazingGroundIsKept) {
  // Ranges grow fast but smoothly across lines.
  Pass p = grazing_ground(0.6);
  const SensorParams s = coaxial_sensor();
  const std::size_t kept = p.kept();
  ASSERT_GT(kept, 10000u);
  // The budget for valid returns wrongly rejected is 1 %. Measured 1 of 18,110: each nod
  // sweep is a sequence of its own (where the nod reverses the lines fold back over each other),
  // and a side's 2-D patch predicts the ground where a trend through one beam's returns bends.
  const std::size_t rejected = reject_mixed_pixels(p, MixedPixelParams{}, s);
  std::printf("grazing ground: %zu of %zu returns rejected\n", rejected, kept);
  EXPECT_LT(rejected, kept / 1000);
}

TEST(RejectMixedPixels, BesideAVoidAcrossLinesPoseNoiseIsNoEvidenceUnlessTheReturnIsDimmer) {
  // Grazing ground registered with noisy poses (1 cm, 0.5 mrad per pose): across lines a return
  // lies off its neighbours' plane by the poses' noise, which at grazing incidence is decimetres
  // in range. Bands of 9 lines are voids (dropped returns, wider than the stage's window), so the
  // line after each has one side across lines only: the one-sided test.
  Pass p = grazing_ground(0.15, 0.01, 0.0005);  // lines close together: the ground's trend across lines is fine
  const SensorParams s;  // non-coaxial: a mixture may be dimmer than the mixing model says
  std::vector<std::size_t> beside_void;  // kept returns whose neighbour on the line before is a void
  for (std::size_t k = 0; k < p.line_count(); ++k)
    for (std::size_t i = p.line_begin[k]; i < p.line_begin[k + 1]; ++i) {
      if (k % 20 >= 3 && k % 20 <= 11 && p.is_kept(i)) p.label[i] = Label::kLowAmplitude;
      if (k % 20 == 12 && p.is_kept(i)) beside_void.push_back(i);
    }
  ASSERT_GT(beside_void.size(), 500u);
  const auto flagged_beside_void = [&](const Pass& in, const PoseSigma& ps, const MixedPixelParams& mp = {}) {
    Pass q = in;
    reject_mixed_pixels(q, mp, s, ps);
    return static_cast<std::size_t>(std::count_if(beside_void.begin(), beside_void.end(),
                                                  [&](std::size_t i) { return q.label[i] == Label::kMixedPixel; }));
  };
  const PoseSigma declared{0.01, 0.0005};
  const std::size_t blind = flagged_beside_void(p, PoseSigma{0.0, 0.0}), aware = flagged_beside_void(p, declared);
  std::printf("beside a void: %zu flagged without the pose noise, %zu with it, of %zu\n", blind, aware,
              beside_void.size());
  EXPECT_GT(blind, 5u);  // the pose noise alone breaks the ground's trend across lines
  EXPECT_LT(aware, blind / 2);
  // The same returns far dimmer than their surface (amplitude 1): a mixture with a void loses the
  // void's share of the power, so a dim return off the plane by the poses' noise is not excused.
  // This ground returns about 10 amplitude units, so the amplitude slack must be below that.
  Pass dim = p;
  for (const std::size_t i : beside_void) dim.amplitude[i] = 1.0f;
  MixedPixelParams fine;
  fine.amplitude_slack = 1.0;
  const std::size_t dim_blind = flagged_beside_void(dim, PoseSigma{0.0, 0.0}, fine);
  const std::size_t dim_aware = flagged_beside_void(dim, declared, fine);
  std::printf("dimmed: %zu flagged without the pose noise, %zu with it\n", dim_blind, dim_aware);
  EXPECT_GT(dim_blind, 5u);
  EXPECT_EQ(dim_aware, dim_blind);
}

TEST(RejectMixedPixels, OnSimulatedScenesOfTwoSensorSettings) {
  // The same seeds as bench/pcdp_mixed_bench (which adds the baselines). Measured: A 0.911
  // (637/699; 0.908 before corners beside one neighbour across, 0.901 with spike_width 1),
  // B 0.965 (251/260; 0.958 before the amplitude test for spikes, 0.923 before the spike test),
  // both above the target of 0.90. A is held at 0.905 so that losing the spikes two and three
  // returns wide fails, B at 0.94 so that losing the spike test fails (docs/mixed_pixels.md:
  // more seeds).
  for (char which : {'A', 'B'}) {
    std::uint64_t pos = 0, tp = 0, valid = 0, fp = 0;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      const bench::Setting st = bench::make_setting(which, seed);
      const sim::SimResult r = sim::simulate(st.sim);
      const PoseTrack poses(r.poses);
      const Eigen::Isometry3d T = make_transform(st.sim.mount_translation, st.sim.mount_rpy, st.sim.rpy_order);
      for (const auto& sp : r.passes) {
        Pass p = sp.pass;
        register_pass(p, RegisterParams{}, st.sensor, T, &poses);
        reject_occlusion(p, OcclusionParams{}, st.sensor);
        Pass q = p;
        reject_mixed_pixels(q, MixedPixelParams{}, st.sensor);
        for (std::size_t i = 0; i < p.size(); ++i) {
          if (!p.is_kept(i)) continue;
          const bool flagged = q.label[i] == Label::kMixedPixel;
          if (sp.truth[i] == Label::kMixedPixel) {
            ++pos;
            tp += flagged;
          } else if (sp.truth[i] == Label::kKept) {
            ++valid;
            fp += flagged;
          }
        }
      }
    }
    const double recall = static_cast<double>(tp) / static_cast<double>(pos);
    const double false_rate = static_cast<double>(fp) / static_cast<double>(valid);
    std::cout << which << ": recall " << recall << " (" << tp << "/" << pos << "), valid rejected " << 100 * false_rate << " %\n";
    EXPECT_LE(false_rate, 0.01) << which;
    EXPECT_GE(recall, which == 'B' ? 0.94 : 0.905) << which;
  }
}

TEST(RejectMixedPixels, UnorganizedCloudWithAViewpoint) {
  // A wall at 10 m with a box face at 6 m in front, plus veil points between, shuffled.
  std::vector<Eigen::Vector3d> pts;
  std::vector<char> veil;
  const double step = 0.005;
  for (int row = -20; row <= 20; ++row) {
    for (int col = -60; col <= 60; ++col) {
      const double az = col * step, el = row * step;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const bool on_box = col < 0;
      double range = on_box ? 6.0 / d.x() : 10.0 / d.x();
      const bool is_veil = col == 0;
      if (is_veil) range = 8.0 / d.x();
      pts.push_back(Eigen::Vector3d(1.0, -2.0, 0.5) + range * d);
      veil.push_back(is_veil);
    }
  }
  std::vector<std::size_t> order(pts.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(3));
  std::vector<Eigen::Vector3d> shuffled;
  std::vector<char> truth;
  for (std::size_t i : order) {
    shuffled.push_back(pts[i]);
    truth.push_back(veil[i]);
  }
  const auto mixed = mixed_pixels_in_cloud(shuffled, Eigen::Vector3d(1.0, -2.0, 0.5), {}, step, MixedPixelParams{}, 0.005);
  std::size_t tp = 0, fp = 0, pos = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    pos += truth[i];
    tp += truth[i] && mixed[i];
    fp += !truth[i] && mixed[i];
  }
  EXPECT_EQ(tp, pos);
  EXPECT_EQ(fp, 0u);
}

TEST(RejectMixedPixels, RealKurt3DScanLosesItsVeilPointsAndKeepsItsFloorAndCeiling) {
  // ../shared/datasets/kurt3d_3dtk_nodding/scan000.3d: a real nodding SICK scan, no intensity,
  // through the unorganized-cloud path (as `clean-cloud` runs it) with the viewpoint at the
  // origin, in our frame (z up). The organized path is scored by the end-to-end tests
  // Kurt3D.MixedPixelsThroughThePipeline... and Kurt3D.CleanCloudReadsAnOrganizedPcd....
  const std::string path = std::string(PCDP_SHARED_DIR) + "/datasets/kurt3d_3dtk_nodding/scan000.3d";
  const test::Kurt3DScan scan = test::read_kurt3d_scan(path);
  ASSERT_EQ(scan.points.size(), test::Kurt3DScan::kLines * test::Kurt3DScan::kBeams) << path;
  const auto& all = scan.points;
  const auto& valid = scan.valid;
  std::vector<Eigen::Vector3d> pts;
  std::vector<std::size_t> back;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (valid[i]) {
      pts.push_back(io::uos_to_ours(all[i] * 100.0));  // z up, as the range image's elevation bands need
      back.push_back(i);
    }
  const auto mixed = mixed_pixels_in_cloud(pts, Eigen::Vector3d::Zero(), {}, 0.0087, MixedPixelParams{}, 0.0053);  // as clean-cloud
  std::vector<char> removed(all.size(), 0);
  std::size_t n_removed = 0;
  for (std::size_t k = 0; k < pts.size(); ++k)
    if (mixed[k]) {
      removed[back[k]] = 1;
      ++n_removed;
    }
  // The corridor wall, the returns inside depth jumps and the floor and ceiling's interior
  // (tests/support/kurt3d_reference.hpp).
  const test::Kurt3DScore sc = test::score_kurt3d(scan, removed, valid);
  std::cout << "Kurt3D scan000 (cloud path): " << pts.size() << " valid points, " << n_removed << " removed; returns in depth jumps "
            << sc.jumps_removed() << "/" << sc.jumps() << " removed (on the line through their neighbours " << sc.on_line_removed << "/"
            << sc.on_line << ", off it and far from both lines beside " << sc.veils_removed << "/" << sc.veils << ", the rest "
            << sc.flat_removed << "/" << sc.flat << "); floor and ceiling interior " << sc.planar_removed << "/" << sc.planar
            << " removed; right corridor wall " << sc.wall_removed << "/" << sc.wall << " removed\n";
  test::expect_kurt3d_bars(sc, 0.8, "the cloud path");
}

TEST(RejectMixedPixels, RoundsAcrossLinesFollowTheLocalNodStepAndAWindowDecidesAsTheWholePass) {
  // A near surface (5 m) over a far one (10 m) with ramps of mixtures between them across lines,
  // in columns of different ramp lengths, scanned by a nod whose step changes from line to line
  // (a uniform-distance profile, or one that speeds up). The footprint (8 mrad) is
  // narrower than the bearing step (10 mrad), so only the nod step can call for more rounds.
  // Slow in the first half (1.5-3 mrad a line: up to 5 lines per footprint), fast in the second
  // (10-14 mrad: less than one): the pass's mean step says one round everywhere, the local step
  // two more in the first half and none in the second.
  const std::vector<double> slow = {0.002, 0.0015, 0.003, 0.0025}, fast = {0.012, 0.010, 0.014};
  std::vector<std::vector<float>> rows;
  std::vector<float> nods;
  double nod = 0.0;
  for (int k = 0; k < 80; ++k) {
    std::vector<float> row(21);
    for (int b = 0; b < 21; ++b) {
      const int ramp = 1 + b % 5;            // mixtures in the ramp of this column
      const int at = 10 + (k / 40) * 30 + b % 3;  // where the ramp starts: two edges down the pass
      const int into = (k % 40) - (at % 40);
      row[static_cast<std::size_t>(b)] = into < 0 ? 5.0f : into >= ramp ? 10.0f : 5.0f + 5.0f * static_cast<float>(into + 1) / static_cast<float>(ramp + 1);
    }
    rows.push_back(row);
    nods.push_back(static_cast<float>(nod));
    nod += k < 40 ? slow[static_cast<std::size_t>(k) % slow.size()] : fast[static_cast<std::size_t>(k) % fast.size()];
  }
  const Pass p = grid_pass(rows, nods);
  SensorParams s = coaxial_sensor();
  s.beam_divergence = 0.008;
  Pass batch = p;
  reject_mixed_pixels(batch, MixedPixelParams{}, s);
  // The same without a footprint: no round past the first.
  SensorParams pencil = s;
  pencil.beam_divergence = 1e-9;
  Pass one_round = p;
  reject_mixed_pixels(one_round, MixedPixelParams{}, pencil);
  // Flagged in lines [from, to).
  const auto flagged_in = [](const Pass& q, std::size_t from, std::size_t to) {
    std::size_t c = 0;
    for (std::size_t i = q.line_begin[from]; i < q.line_begin[to]; ++i) c += q.label[i] == Label::kMixedPixel;
    return c;
  };
  const std::size_t slow_rounds = flagged_in(batch, 0, 40), slow_one = flagged_in(one_round, 0, 40);
  const std::size_t fast_rounds = flagged_in(batch, 40, 80), fast_one = flagged_in(one_round, 40, 80);
  std::printf("ramps under a changing nod: slow half %zu flagged with the rounds, %zu in one round; fast half %zu and %zu\n",
              slow_rounds, slow_one, fast_rounds, fast_one);
  EXPECT_GT(slow_rounds, slow_one);   // several lines per footprint: the rounds peel the ramps
  EXPECT_EQ(fast_rounds, fast_one);   // less than one line per footprint: no round past the first
  // Each line as a streamed window labels it: the stage's reach on each side.
  EXPECT_EQ(labels_streamed_otherwise(p, batch, s), 0u);
}

TEST(RejectMixedPixels, RoundsPeelRunsAcrossLinesOnlyWhereTheFootprintsOverlap) {
  // A near surface (5 m) over a far one (10 m), the same on every beam, with a ramp of three
  // returns between them across lines. The footprint (15 mrad) is wider than the bearing step
  // (10 mrad), so the stage runs a later round. Where the lines are 0.5 mrad apart the footprint
  // spans thirty of them and the ramp is a run of mixtures; the surfaces a full divergence away
  // lie farther than the first round's search past a footprint reaches (24 lines), so it cannot
  // judge the inner returns past the footprint and the later rounds peel the run. Where the lines are 20 mrad apart the footprints of two
  // lines do not overlap: no run spans them, and the later round does not test the other line's
  // return again (the first round's verdict stands, as with a pencil beam). Each flagged return
  // says what found it (Pass::flags).
  const auto ramp_pass = [](double line_step) {
    std::vector<std::vector<float>> rows;
    std::vector<float> nods;
    for (int k = 0; k < 80; ++k) {
      // The ramp, lines 40-42: a quarter, a half and three quarters of the footprint on the far
      // surface, which returns a quarter of the near one's power (1 / r^2): the mixing model's
      // ranges r = w 5 + (1 - w) 10 with w = f / (f + (1 - f) / 4). Each surface spans 40 lines
      // on its side, 20 mrad at 0.5 mrad a line: past the footprint, out of the search's reach.
      const int into = k - 40;
      const float ramp[3] = {5.38f, 6.0f, 7.14f};
      const float r = into < 0 ? 5.0f : into >= 3 ? 10.0f : ramp[into];
      rows.emplace_back(21, r);
      nods.push_back(static_cast<float>(line_step * k));
    }
    return grid_pass(rows, nods);
  };
  const auto flagged = [&](double line_step, double divergence, std::uint8_t* evidence) {
    Pass p = ramp_pass(line_step);
    SensorParams s = coaxial_sensor();
    s.beam_divergence = divergence;
    reject_mixed_pixels(p, MixedPixelParams{}, s);
    std::size_t n = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (p.label[i] != Label::kMixedPixel) {
        EXPECT_EQ(p.flags[i], 0u) << "evidence on a return not labelled mixed_pixel";
        continue;
      }
      ++n;
      EXPECT_NE(p.flags[i] & (kFlagMixedAlong | kFlagMixedAcross | kFlagSpike), 0) << "a label without its evidence";
      *evidence |= p.flags[i];
    }
    return n;
  };
  std::uint8_t dense_ev = 0, sparse_ev = 0, ignored = 0;
  const std::size_t dense = flagged(0.0005, 0.015, &dense_ev), dense_pencil = flagged(0.0005, 1e-9, &ignored);
  const std::size_t sparse = flagged(0.020, 0.015, &sparse_ev), sparse_pencil = flagged(0.020, 1e-9, &ignored);
  std::printf("ramp across lines: 0.5 mrad apart %zu flagged (%zu with a pencil beam), 20 mrad apart %zu (%zu)\n", dense,
              dense_pencil, sparse, sparse_pencil);
  EXPECT_GT(dense, dense_pencil);                  // a run of mixtures: the later rounds peel it
  EXPECT_NE(dense_ev & kFlagMixedRun, 0);          // ... and the peeled returns say so
  EXPECT_EQ(sparse, sparse_pencil);                // lines apart: no run across them
  EXPECT_EQ(sparse_ev & kFlagMixedRun, 0);
  EXPECT_EQ(dense_ev & kFlagMixedAlong, 0);        // every line is flat along: found across lines
  EXPECT_NE(dense_ev & kFlagMixedAcross, 0);
}

TEST(RejectMixedPixels, TwoMixturesThatShareAFootprintDoNotVouchForEachOther) {
  // A near surface (5 m) and a far one (10 m) with two returns at 7 m between them: two mixtures
  // of one edge that keep each other's range, where the beams are closer than half the
  // divergence (each lies inside the other's footprint), so neither is a surface's witness; or a
  // strip of surface two returns wide, where the beams are farther apart than the divergence (no
  // footprints overlap). Across lines (the same on every beam) and along the line (the same on
  // every line), each with the beams inside and outside each other's footprint. (Between the two,
  // footprints that overlap without holding each other's beam, the pair is judged against the
  // surfaces past the footprint: ARampOfMixturesIsJudgedAgainstTheSurfacesPastItsFootprint.)
  const auto across_pass = [](double line_step) {
    std::vector<std::vector<float>> rows;
    std::vector<float> nods;
    for (int k = 0; k < 30; ++k) {
      rows.emplace_back(21, k < 12 ? 5.0f : k < 14 ? 7.0f : 10.0f);
      nods.push_back(static_cast<float>(line_step * k));
    }
    return grid_pass(rows, nods);
  };
  const auto along_pass = [] {  // bearings 10 mrad apart (grid_pass)
    std::vector<float> row(21, 10.0f);
    for (int b = 0; b < 9; ++b) row[static_cast<std::size_t>(b)] = 5.0f;
    row[9] = row[10] = 7.0f;
    return grid_pass(std::vector<std::vector<float>>(30, row));
  };
  // How many of the returns at 7 m (2 lines x 21 beams across, 30 lines x 2 beams along) are
  // flagged; the two surfaces' returns, read past their own neighbours too, stay kept.
  const auto flagged_at_7m = [](Pass p, double divergence, unsigned* evidence) {
    SensorParams s = coaxial_sensor();
    s.beam_divergence = divergence;
    reject_mixed_pixels(p, MixedPixelParams{}, s);
    std::size_t n = 0, at7 = 0, surfaces_flagged = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (std::fabs(p.range[i] - 7.0f) > 0.01f) {
        surfaces_flagged += p.label[i] != Label::kKept;
        continue;
      }
      ++at7;
      if (p.label[i] == Label::kMixedPixel) {
        ++n;
        *evidence |= p.flags[i];
      }
    }
    EXPECT_TRUE(at7 == 42u || at7 == 60u) << at7;
    EXPECT_EQ(surfaces_flagged, 0u);
    return n;
  };
  unsigned ev_across = 0, ev_along = 0, ignored = 0;
  // Across lines: 3 mrad apart inside a 15 mrad footprint; 10 mrad apart, the footprints
  // overlapping without holding each other's beam (judged past the footprint: the sides 20 mrad
  // away are the two surfaces); 20 mrad apart; a pencil beam.
  const std::size_t across_shared = flagged_at_7m(across_pass(0.003), 0.015, &ev_across);
  const std::size_t across_overlapping = flagged_at_7m(across_pass(0.010), 0.015, &ignored);
  const std::size_t across_apart = flagged_at_7m(across_pass(0.020), 0.015, &ignored);
  const std::size_t across_pencil = flagged_at_7m(across_pass(0.003), 1e-9, &ignored);
  // Equal nod readings (a scanner that does not nod) cannot say the beams are close.
  const std::size_t across_equal = flagged_at_7m(across_pass(0.0), 0.015, &ignored);
  // Along the line: bearings 10 mrad apart inside a 25 mrad footprint; a 9 mrad one.
  const std::size_t along_shared = flagged_at_7m(along_pass(), 0.025, &ev_along);
  const std::size_t along_apart = flagged_at_7m(along_pass(), 0.009, &ignored);
  std::printf("two returns at 7 m between 5 and 10 m: across lines %zu / %zu / %zu / %zu flagged (shared / overlapping / "
              "apart / pencil); along %zu / %zu\n", across_shared, across_overlapping, across_apart, across_pencil,
              along_shared, along_apart);
  EXPECT_EQ(across_shared, 42u);
  EXPECT_EQ(across_overlapping, 42u);
  EXPECT_NE(ev_across & kFlagMixedAcross, 0u);
  EXPECT_EQ(ev_across & kFlagMixedAlong, 0u);  // flat along every line
  EXPECT_EQ(across_apart, 0u);
  EXPECT_EQ(across_pencil, 0u);
  EXPECT_EQ(across_equal, 0u);
  EXPECT_EQ(along_shared, 60u);
  EXPECT_NE(ev_along & kFlagMixedAlong, 0u);
  EXPECT_EQ(ev_along & kFlagMixedAcross, 0u);  // every line alike: flat across lines
  EXPECT_EQ(along_apart, 0u);
}

TEST(RejectMixedPixels, ARampOfMixturesIsJudgedAgainstTheSurfacesPastItsFootprint) {
  // A table's edge over ground, across lines (the same on every beam, so every line is flat
  // along): the table top nears the sensor by 0.12 m a line, the ground beyond recedes by
  // 0.13-0.17 m a line, and between them three mixtures (6.03, 6.82, 7.29 m: the ranges of the
  // sweep's setting 19, a 13 mrad footprint on lines 5.1 mrad apart). The ramp is an S, as a
  // disc-shaped footprint crossing an edge makes it: no return in it shows an edge against its
  // nearest neighbours, each has as steep a step on one side (a weak edge, or a corner, which a
  // line flat along does not confirm). Judged against the surfaces a full divergence away, past
  // the returns whose footprints overlap its own, the two that lie off both surfaces (6.03 and
  // 6.82 m) are mixtures; 7.29 m continues the ground's trend (test 2) and is kept as ground.
  // Lines farther apart than the footprint make no mixtures of one edge together: the same ranges
  // are then a surface, read as with a pencil beam.
  const std::vector<float> across = {4.09f, 4.21f, 4.33f, 4.45f, 4.57f, 4.69f, 4.81f, 4.93f, 5.05f, 5.17f,
                                     5.29f, 5.41f, 6.03f, 6.82f, 7.29f, 7.42f, 7.55f, 7.69f, 7.84f, 8.00f,
                                     8.17f, 8.35f, 8.54f, 8.74f, 8.95f, 9.17f, 9.40f, 9.64f, 9.89f, 10.15f};
  const auto run = [&](double line_step, double divergence, std::size_t* surfaces_flagged) {
    std::vector<std::vector<float>> rows;
    std::vector<float> nods;
    for (std::size_t k = 0; k < across.size(); ++k) {
      rows.emplace_back(21, across[k]);
      nods.push_back(static_cast<float>(line_step * static_cast<double>(k)));
    }
    Pass p = grid_pass(rows, nods);
    SensorParams s = coaxial_sensor();
    s.beam_divergence = divergence;
    reject_mixed_pixels(p, MixedPixelParams{}, s);
    std::size_t ramp = 0;
    *surfaces_flagged = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const std::size_t line = i / 21;
      if (line == 12 || line == 13) {
        ramp += p.label[i] == Label::kMixedPixel;
        // Found across lines by the two-sided tests of the first round, not beside a void nor
        // by a later round.
        if (p.label[i] == Label::kMixedPixel) {
          EXPECT_EQ(p.flags[i] & (kFlagMixedAcross | kFlagBesideVoid | kFlagMixedRun), kFlagMixedAcross) << line;
        }
      }
      else if (line != 14) *surfaces_flagged += p.label[i] != Label::kKept;
    }
    return ramp;
  };
  std::size_t surf_wide = 0, surf_apart = 0, surf_pencil = 0;
  const std::size_t wide = run(0.0051, 0.013, &surf_wide);      // footprint 2.5 lines wide
  const std::size_t apart = run(0.020, 0.013, &surf_apart);     // lines farther apart than the footprint
  const std::size_t pencil = run(0.0051, 1e-9, &surf_pencil);   // no footprint to read past
  std::printf("ramp of mixtures across 21 beams: %zu of 42 off both surfaces flagged (lines apart %zu, pencil beam %zu); "
              "surface returns flagged %zu / %zu / %zu\n", wide, apart, pencil, surf_wide, surf_apart, surf_pencil);
  EXPECT_EQ(wide, 42u);
  EXPECT_EQ(apart, 0u);
  EXPECT_EQ(pencil, 0u);
  EXPECT_EQ(surf_wide, 0u);
  EXPECT_EQ(surf_apart, 0u);
}

TEST(RejectMixedPixels, ARampIntoAVoidIsJudgedBesideTheVoidPastItsFootprint) {
  // A wall's top at 8 m against a far ground (28 m) too dark to return on its own (the sweep's
  // setting 8012), across lines (the same on every beam): 30 lines on the wall, then 15 lines
  // whose 15 mrad footprint leaves the wall, a disc's share f on it, at the mixing model's range
  // and amplitude (the ground returns 2.5 % of the wall's power), then no return once the
  // mixture is too weak. The lines are 1 mrad apart (a nod near its turn), so the ramp is as
  // deep as the footprint: the return next to the void is judged beside it, the later rounds peel
  // two more, and the ones deeper in have mixtures on both sides. Read past the footprint, one
  // side is the wall and the other the void, and the one-sided test decides.
  const double kPi = 3.14159265358979323846;
  std::vector<float> ramp, amp;
  for (int k = 0; k < 15; ++k) {
    const double x = -1.0 + (k + 0.5) * 2.0 / 15.0;  // the beam's distance past the edge, in footprint radii
    const double f = (std::acos(x) - x * std::sqrt(1 - x * x)) / kPi;
    const double r = mixture_range(f, 8.0, 100.0, 28.0, 2.5);
    ramp.push_back(static_cast<float>(r));
    amp.push_back(static_cast<float>(mixture_amplitude_at(r, 8.0, 100.0, 28.0, 2.5)));
  }
  const auto make = [&](double line_step) {
    std::vector<std::vector<float>> rows;
    std::vector<float> nods;
    for (std::size_t k = 0; k < 60; ++k) {
      const float r = k < 30 ? 8.0f : k < 30 + ramp.size() ? ramp[k - 30] : 0.0f;  // 0: no return
      rows.emplace_back(21, r);
      nods.push_back(static_cast<float>(line_step * static_cast<double>(k)));
    }
    Pass p = grid_pass(rows, nods);
    for (std::size_t i = 0; i < p.size(); ++i)
      if (i / 21 >= 30 && i / 21 < 30 + ramp.size()) p.amplitude[i] = amp[i / 21 - 30];
    return p;
  };
  SensorParams s = coaxial_sensor();
  s.beam_divergence = 0.015;
  // The deep mixtures (lines 38-40, 8.68-9.38 m, which the return next to the void and the two
  // later rounds do not reach) flagged, with their evidence, and the wall's returns flagged. The
  // returns before them (8.25-8.49 m) continue the ramp's own smooth trend and are settled as a
  // surface (docs/mixed_pixels.md).
  const auto count = [&](const Pass& p, std::size_t* wall_flagged, std::uint8_t* evidence) {
    std::size_t deep = 0;
    *wall_flagged = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      const std::size_t line = i / 21;
      if (line < 30) *wall_flagged += p.label[i] != Label::kKept;
      if (line >= 38 && line <= 40 && p.label[i] == Label::kMixedPixel) {
        ++deep;
        *evidence |= p.flags[i];
      }
    }
    return deep;
  };
  Pass batch = make(0.001), pencil = make(0.001), apart = make(0.020);
  reject_mixed_pixels(batch, MixedPixelParams{}, s);
  SensorParams pencil_sensor = s;
  pencil_sensor.beam_divergence = 1e-9;
  reject_mixed_pixels(pencil, MixedPixelParams{}, pencil_sensor);
  reject_mixed_pixels(apart, MixedPixelParams{}, s);
  std::size_t wall = 0, wall_pencil = 0, wall_apart = 0;
  std::uint8_t ev = 0, ignored = 0;
  const std::size_t deep = count(batch, &wall, &ev), deep_pencil = count(pencil, &wall_pencil, &ignored),
                    deep_apart = count(apart, &wall_apart, &ignored);
  std::printf("ramp into a void, 15 mrad footprint on lines 1 mrad apart: %zu of 63 deep mixtures flagged (pencil beam %zu, "
              "lines 20 mrad apart %zu); wall returns flagged %zu / %zu / %zu\n", deep, deep_pencil, deep_apart, wall,
              wall_pencil, wall_apart);
  EXPECT_EQ(deep, 63u);
  EXPECT_EQ(ev & (kFlagMixedAcross | kFlagBesideVoid | kFlagMixedRun | kFlagMixedAlong), kFlagMixedAcross | kFlagBesideVoid);
  EXPECT_EQ(wall, 0u);
  EXPECT_EQ(deep_pencil, 0u);  // no footprint: a surface receding into a void, judged at its end only
  EXPECT_EQ(deep_apart, 0u);   // lines apart: no footprint spans the ramp
  EXPECT_EQ(wall_pencil + wall_apart, 0u);
  // The end of the sweep is not a void: the same pass cut after the ramp's last line.
  Pass cut = lines_of(make(0.001), 0, 45);
  reject_mixed_pixels(cut, MixedPixelParams{}, s);
  std::size_t wall_cut = 0, wall_deep = 0;
  EXPECT_EQ(count(cut, &wall_cut, &ignored), 0u);
  // A footprint deeper than the search reaches (0.5 mrad a line: the wall 30 lines past the
  // deep mixtures' beams): only the rounds judge the ramp.
  Pass deep_footprint = make(0.0005);
  reject_mixed_pixels(deep_footprint, MixedPixelParams{}, s);
  EXPECT_EQ(count(deep_footprint, &wall_deep, &ignored), 0u);
  EXPECT_EQ(wall_cut + wall_deep, 0u);
  // A streamed window of the stage's reach on each side labels each line as the whole pass does.
  EXPECT_EQ(labels_streamed_otherwise(make(0.001), batch, s), 0u);
}
