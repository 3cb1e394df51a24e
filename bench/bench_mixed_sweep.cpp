// Randomized sweep of the main chain (register -> reject_occlusion -> reject_mixed_pixels, default
// options as in pipelines/nodding_terrain.yaml) over sensors and scenes drawn from wide ranges, so
// that the numbers describe scanners in general rather than one benchmark setting.
//
// A setting is (sensor, scene, seed), all drawn from the setting index alone (make_sweep_setting):
//  - sensor: 180-1141 beams over 180-270 deg, full divergence 2-15 mrad, transceiver separation
//    2-10 cm, fixed or mirror transceiver geometry, 25-75 lines/s, range noise 3-15 mm, encoder
//    0.03-0.11 deg; nodding (Broten & Collier 4.1, 4.2) at a constant 0.5-1.5 rad/s between
//    -0.6..-0.3 and 0..0.15 rad, or at a uniform ground sample distance of 0.1-0.3 m (90 deg/s
//    limit); mount 1-2 m high, pitched 0.1-0.3 rad; vehicle 0-2 m/s, following flat or undulating
//    terrain;
//  - scene: boxes of every size (0.2-2 m, 0.15-1.5 m tall) and reflectivity (3-95 %, log-uniform),
//    axis-aligned or turned (edges parallel, perpendicular and oblique to the scan lines), posts
//    (5-20 cm cylinders), a wall, a step, a kerb, a table (a top raised off the ground on four
//    legs: an overhang), and a bright box in front of a dark one or the reverse.
// The pipeline is told the simulated scanner's true values (sensor block = the simulator's).
//
// Two disjoint sets of settings: the tuning set (indices 0-23) and the held-out set (1000-1015).
// The held-out set is never used while tuning a detector: run it only to report.
//
// Truth (the simulator's): a mixed pixel is a return whose footprint lit two or more objects and
// whose range lies more than 4 cm (mixed_pixel_tolerance) from the depth interval each lit
// object's part spans; an occlusion false range is a false range read when the receiver's view of
// the footprint was hidden.
//
// Per setting: mixed-pixel recall (truth mixed pixels not kept by the chain, any label), valid
// rejected (truth-valid returns with a pose and in range that a filter labelled), F1 of the chain
// against the mixed truth (true positives: mixed pixels rejected; false positives: valid returns
// rejected), occlusion recall, and the elevation error: every pass's kept points fused with
// fuse_elevation's defaults (fuse_pass, 0.1 m cells), each cell's surface compared with the true
// top surface over the cell grown by 5 cm on each side (Scene::top_height sampled on 7 x 7 points;
// the margin takes in a vertical face's points registered into the cell in front of it): above =
// surface minus the highest true top there, a phantom obstacle when > 0.3 m; below = lowest true
// top minus surface (a top not seen, e.g. only the ground under a table). The same grid is also
// made after check_consistency over the setting's passes (the main pipeline's next stage, as in
// pipelines/nodding_terrain.yaml): column "+cc", its phantom cells; below the pooled row, the
// mixed pixels, valid returns and false ranges check_consistency removes after the filters (the
// column's price). The map's other side: cells whose surface lies more than 0.3 m below the lowest
// true top, and those of them where a perfect filter's map (every truth-valid return kept, nothing
// else) lies that low too (the valid returns did not reach the top); and what the false
// rejections alone cost: the map of the truth-valid returns the filters kept against the perfect
// one, its cells lowered by more than 0.3 m and those left without a surface.
//
// Usage: pcdp_mixed_sweep [--set tuning|heldout] [--index N]... [--json FILE] [--misses K] [--rank recall|f1|valid]
//                         [--require-recall R] [--require-valid-rejected PCT] [--require-occlusion-recall R]
//                         [--require-phantom-cells N] [--dump-misses K] [--dump-phantoms] [--param NAME=VALUE]...
// --param NAME=VALUE (repeatable) runs the stage with one MixedPixelParams member changed from its
// default, for the trades in docs/mixed_pixels.md: jump_min (metres, or "derived": 2 x
// (range_tolerance + 3 sensor.range_sigma)), jump_ratio, range_tolerance, amplitude_ratio,
// amplitude_slack, window, spike_width.
// --dump-misses K prints every K-th miss and every K-th valid return rejected as a mixed pixel
// ("false <object>"): its range, the lit depths, its near share and amplitude, then range, truth
// (V valid, M mixed, O occlusion, L low amplitude, N none), label initial and amplitude of its
// in-line neighbours (4 each side) and across lines (2 each side, with their nod angles).
// Below the pooled row, how many settings meet each per-setting bar (recall >= 0.90, valid
// rejected <= 1 %, no phantom cell) and all three, and the kept points standing more than 0.3 m
// above their cell's true top: by truth label, the mixed pixels among them by what surrounds
// them (phantom_kind()), and how many of those lie on a line next to a nod turn against the share
// of all mixed pixels on such lines (next_to_nod_turn()).
// The --require options check the pooled numbers (exit 1 naming each one missed): CI runs both sets
// with a margin below today's numbers (bench/CMakeLists.txt), so a regression fails the build.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/transforms.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "sim/bench_scenes.hpp"
#include "stages/reject_mixed_pixels_detail.hpp"  // sweep_starts: the stage's split at the nod's turns
#include "pcdp/fusion/consistency.hpp"
#include "pcdp/stages/fuse_elevation.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/stages/reject_occlusion.hpp"

using namespace pcdp;

namespace {
int g_dump_every = 0;  ///< --dump-misses K: print every K-th miss with its neighbours
bool g_dump_phantoms = false;  ///< --dump-phantoms: print every kept return > 0.3 m above its cell's true top
/// The MixedPixelParams members --param NAME=VALUE may set, each with its setter: the one list
/// that checks the name, applies the value and names them in the messages.
using ParamSetter = void (*)(MixedPixelParams&, double);
const std::map<std::string, ParamSetter> kSweepParams = {
    {"jump_min", [](MixedPixelParams& p, double v) { p.jump_min = v; }},
    {"jump_ratio", [](MixedPixelParams& p, double v) { p.jump_ratio = v; }},
    {"range_tolerance", [](MixedPixelParams& p, double v) { p.range_tolerance = v; }},
    {"amplitude_ratio", [](MixedPixelParams& p, double v) { p.amplitude_ratio = v; }},
    {"amplitude_slack", [](MixedPixelParams& p, double v) { p.amplitude_slack = v; }},
    {"window", [](MixedPixelParams& p, double v) { p.window = static_cast<int>(v); }},
    {"spike_width", [](MixedPixelParams& p, double v) { p.spike_width = static_cast<int>(v); }},
};
std::string sweep_param_names() {
  std::string names;
  for (const auto& [name, set] : kSweepParams) names += (names.empty() ? "" : ", ") + name;
  return names;
}
/// --param NAME=VALUE, checked when read; NaN for jump_min=derived.
std::vector<std::pair<std::string, double>> g_params;

/// The stage's parameters for a sensor: the defaults, with --param's changes.
MixedPixelParams sweep_params(const SensorParams& sensor) {
  MixedPixelParams p;
  for (const auto& [name, v] : g_params) kSweepParams.at(name)(p, v);
  if (std::isnan(p.jump_min)) p.jump_min = 2 * (p.range_tolerance + 3 * sensor.range_sigma);  // derived
  return p;
}
constexpr double kPi = 3.14159265358979323846;

struct SweepSetting {
  int index = 0;
  sim::SimConfig sim;
  SensorParams sensor;
  std::vector<std::string> kind;  ///< per object id (boxes, then posts): wall, step, kerb, box, ...
  std::string kind_of(int object) const {
    return object < 0 ? "ground" : static_cast<std::size_t>(object) < kind.size() ? kind[static_cast<std::size_t>(object)] : "?";
  }
};

/// Lines of one full nod (down and up) for the scanner's profile.
int nod_cycle_lines(const sim::SimConfig& c) {
  const sim::NodTrajectory t(c, 4000);
  const auto& e = t.line_angles();
  bool went_down = false;
  for (std::size_t k = 1; k < e.size(); ++k) {
    if (e[k] < e[k - 1]) went_down = true;
    if (went_down && k > 2 && e[k] >= e[0] - 1e-12 && e[k - 1] < e[k]) return static_cast<int>(k);
  }
  return 200;
}

SweepSetting make_sweep_setting(int index) {
  SweepSetting st;
  st.index = index;
  std::mt19937_64 rng(0x9E3779B97F4A7C15ULL ^ (static_cast<std::uint64_t>(index) * 1000003ULL + 17));
  const auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  const auto coin = [&](double p) { return U(0, 1) < p; };
  const auto refl = [&](double lo = 0.03, double hi = 0.95) { return std::exp(U(std::log(lo), std::log(hi))); };
  sim::SimConfig& c = st.sim;
  sim::Scanner& s = c.scanner;
  s.beams = static_cast<int>(std::floor(U(180, 1142)));
  const double span = U(kPi, 1.5 * kPi);
  s.bearing_min = -0.5 * span;
  s.bearing_max = 0.5 * span;
  s.line_period = 1.0 / U(25, 75);
  s.beam_divergence = U(0.002, 0.015);
  s.transceiver_separation = U(0.02, 0.10);
  s.mirror = coin(0.5);
  s.transceiver_angle_offset = 0.0;
  s.subrays = 19;
  s.encoder_resolution = U(0.0005, 0.002);
  s.range_n = U(0.999, 1.001);
  s.range_c = U(-0.01, 0.01);
  s.range_sigma = U(0.003, 0.015);
  s.range_quantum = 0.001;
  s.range_max = 30.0;
  s.amplitude_scale = 5000;
  s.amplitude_sigma = 2.0;
  s.min_amplitude = 18;
  s.false_range_probability = U(0.3, 0.7);
  s.mixed_pixel_tolerance = 0.04;  // issue 32's truth rule
  s.nod_max = U(0.0, 0.15);
  s.nod_min = U(-0.6, -0.3);
  if (coin(0.7)) {
    s.profile = sim::NodProfile::kConstantRate;
    s.nod_rate = U(0.5, 1.5);
  } else {
    s.profile = sim::NodProfile::kUniformDistance;
    s.sample_distance = U(0.1, 0.3);
    s.max_nod_rate = 1.5708;
  }
  c.mount_translation = {0.5, 0.0, U(1.0, 2.0)};
  c.mount_rpy = {0.0, U(0.1, 0.3), 0.0};
  c.motion.speed = U(0.0, 2.0);
  c.motion.yaw_rate = U(-0.05, 0.05);
  c.motion.follow_terrain = true;
  c.motion.roll_amplitude = 0.01;
  c.motion.pitch_amplitude = 0.01;
  c.motion.sway_frequency = 0.4;
  c.motion.position_sigma = 0.005;  // the pipeline's default pose_sigma
  c.motion.rpy_sigma = 0.00035;
  c.scene.undulation_amplitude = coin(0.5) ? U(0.02, 0.15) : 0.0;
  c.scene.undulation_wavelength = U(8, 16);
  c.scene.ground_reflectivity = U(0.1, 0.6);
  c.t0 = 1000.0;
  c.seed = 7700000 + static_cast<std::uint64_t>(index);

  auto& boxes = c.scene.boxes;
  std::vector<std::string> box_kind, post_kind;
  const double bottom = -0.3;  // below the lowest terrain
  const auto add_box = [&](const char* kind, double cx, double cy, double lx, double ly, double z0, double z1, double r,
                           double yaw) {
    boxes.push_back({{cx - lx / 2, cy - ly / 2, z0}, {cx + lx / 2, cy + ly / 2, z1}, r, yaw});
    box_kind.emplace_back(kind);
  };
  const auto edge_yaw = [&]() {  // axis-aligned (edges along and across the lines) or oblique
    const double u = U(0, 1);
    return u < 0.35 ? 0.0 : u < 0.5 ? kPi / 2 : U(0.15, 1.4) * (coin(0.5) ? 1 : -1);
  };
  const auto side = [&]() { return coin(0.5) ? 1.0 : -1.0; };
  // Free boxes, off the vehicle's corridor (|y| < 1.2 m holds only low things).
  const int nbox = 2 + static_cast<int>(U(0, 3));
  for (int k = 0; k < nbox; ++k) {
    const double lx = U(0.2, 2.0), ly = U(0.2, 2.0), h = U(0.15, 1.5);
    const double half = 0.5 * std::hypot(lx, ly);
    add_box(h < 0.5 ? "low box" : "box", U(3, 14), side() * (1.2 + half + U(0, 4)), lx, ly, bottom, h, refl(), edge_yaw());
  }
  // Bright in front of dark, or dark in front of bright.
  {
    const bool bright_front = coin(0.5);
    const double rf = bright_front ? U(0.8, 0.95) : U(0.03, 0.08), rb = bright_front ? U(0.03, 0.08) : U(0.8, 0.95);
    const double x = U(4, 11), y = side() * U(2.5, 5.5), yaw = edge_yaw();
    const double lf = U(0.3, 0.8);
    add_box(bright_front ? "bright front" : "dark front", x, y, lf, lf, bottom, U(0.4, 1.2), rf, yaw);
    const double gap = U(0.5, 3.0);
    add_box(bright_front ? "dark back" : "bright back", x + gap + 0.5, y, 0.4, U(2, 3.5), bottom, U(1.3, 2.2), rb, yaw * 0.3);
  }
  if (coin(0.6)) {  // wall
    add_box("wall", U(13, 20), U(-3, 3), 0.2, U(4, 16), bottom, U(1, 3), refl(0.1, 0.9), U(-0.4, 0.4));
  }
  if (coin(0.5)) {  // step: a platform up
    const double x0 = U(5, 11), h = U(0.08, 0.3);
    add_box("step", x0 + 4.0, 0.0, 8.0, 20.0, bottom, h, refl(0.1, 0.7), U(-0.6, 0.6));
  }
  if (coin(0.6)) {  // kerb: along x (across the lines), along y (along the lines) or oblique
    const double u = U(0, 1);
    const double yaw = u < 0.33 ? 0.0 : u < 0.66 ? kPi / 2 : U(0.2, 1.3) * side();
    add_box("kerb", U(4, 12), yaw == 0.0 ? side() * U(1.0, 3.5) : U(-2, 2), U(6, 15), U(0.15, 0.3), bottom, U(0.1, 0.2),
            refl(0.1, 0.9), yaw);
  }
  if (coin(0.7)) {  // table: a top raised off the ground on four legs (an overhang)
    const double cx = U(4, 11), cy = side() * U(2.0, 5.0), lx = U(0.6, 1.6), ly = U(0.6, 1.2), top = U(0.6, 1.0);
    const double th = U(0.03, 0.08), yaw = edge_yaw(), r = refl();
    add_box("table top", cx, cy, lx, ly, top - th, top, r, yaw);
    const double cyaw = std::cos(yaw), syaw = std::sin(yaw);
    for (double sx : {-1.0, 1.0})
      for (double sy : {-1.0, 1.0}) {
        const double ax = sx * (lx / 2 - 0.06), ay = sy * (ly / 2 - 0.06);
        c.scene.posts.push_back({cx + cyaw * ax - syaw * ay, cy + syaw * ax + cyaw * ay, 0.025, bottom, top - th, r});
        post_kind.emplace_back("table leg");
      }
  }
  const int nposts = 1 + static_cast<int>(U(0, 3));
  for (int k = 0; k < nposts; ++k) {
    c.scene.posts.push_back({U(3, 14), side() * U(1.4, 6), U(0.025, 0.1), bottom, U(0.8, 2.0), refl()});
    post_kind.emplace_back("post");
  }
  st.kind = box_kind;
  st.kind.insert(st.kind.end(), post_kind.begin(), post_kind.end());

  c.passes = 4;
  c.lines_per_pass = std::min(nod_cycle_lines(c), 250);

  st.sensor = bench::true_sensor(s);  // the simulated scanner's true values
  return st;
}

struct Miss {
  double range, gap, inline_dev, across_dev, near_share, near_refl, far_refl;
  std::string near_kind, far_kind;
  double height;  ///< m, the kept point's height above the true top surface at its position
};

struct Result {
  int index = 0;
  std::string sensor;
  std::uint64_t returns = 0, mixed = 0, mixed_rejected = 0, mixed_reaching = 0, valid = 0, valid_rejected = 0;
  std::uint64_t valid_rejected_mixed = 0, occlusion = 0, occlusion_rejected = 0, low_amplitude = 0, low_rejected = 0;
  std::uint64_t cells = 0, phantom_cells = 0, phantom_cells_cc = 0;  ///< cc: after check_consistency too
  /// The kept returns check_consistency labels inconsistent after the filters, by truth: mixed
  /// pixels, valid returns (the price of the "+cc" column), false ranges (occlusion, low amplitude).
  std::uint64_t cc_mixed = 0, cc_valid = 0, cc_false_ranges = 0;
  /// Cells > 0.3 m below the lowest true top; of them, those where the perfect filter's map is too.
  /// The perfect map's cells with a surface; of them, those the map of the valid returns the
  /// filters kept has > 0.3 m lower, or no surface in.
  std::uint64_t cells_below = 0, cells_below_unseen = 0, perfect_cells = 0, cells_lowered = 0, cells_emptied = 0;
  std::map<std::string, std::uint64_t> phantom_points;  ///< kept points > 0.3 m above their cell's true top, by truth label
  /// The mixed pixels among them, by what surrounds them (phantom_kind()).
  std::map<std::string, std::uint64_t> phantom_mixed;
  std::uint64_t phantom_mixed_turn = 0;  ///< ... of which on a line next to a nod turn (next_to_nod_turn())
  std::uint64_t phantom_mixed_turn_last = 0;  ///< ... on the last line before the nod reverses
  std::uint64_t mixed_turn = 0;          ///< all mixed pixels on a line next to a nod turn, for comparison
  double elev_above = 0, elev_below = 0, seconds = 0;
  std::vector<Miss> misses;
  std::map<std::string, std::uint64_t> false_alarms;  ///< valid returns labelled mixed_pixel, by what the footprint lit
  /// Returns labelled mixed_pixel by the evidence the stage gives (Pass::flags): {truth mixed, truth valid}.
  std::map<std::string, std::array<std::uint64_t, 2>> evidence;
  double recall() const { return mixed ? double(mixed_rejected) / double(mixed) : 1.0; }
  double valid_rate() const { return valid ? double(valid_rejected) / double(valid) : 0.0; }
  double occ_recall() const { return occlusion ? double(occlusion_rejected) / double(occlusion) : 1.0; }
  double f1() const {
    const double tp = double(mixed_rejected), fp = double(valid_rejected), fn = double(mixed - mixed_rejected);
    return tp > 0 ? 2 * tp / (2 * tp + fp + fn) : 0.0;
  }
};

/// Whether the nod moved return i's beam by more than the divergence to both neighbouring lines
/// (nb returns a line; one neighbour on the first and last line): their footprints then leave
/// unsampled ground between them and this one's; otherwise they touch or overlap it.
bool lines_apart(const Pass& p, std::size_t i, std::size_t nb, double divergence) {
  double step = INFINITY;
  if (i >= nb) step = std::min(step, std::fabs(static_cast<double>(p.nod[i]) - p.nod[i - nb]));
  if (i + nb < p.size()) step = std::min(step, std::fabs(static_cast<double>(p.nod[i + nb]) - p.nod[i]));
  return step > divergence;
}

/// The evidence behind return i's mixed_pixel label, from its flags (Pass::flags): the direction
/// (along its line, across lines, both, or a spike alone), whether beside a void or in a later
/// round; for evidence across lines alone, whether the neighbouring lines' footprints touch this
/// one's (the nod moved the beam by at most the divergence to the nearer of the two) or leave
/// unsampled ground between them.
std::string evidence_of(const Pass& p, std::size_t i, std::size_t nb, double divergence) {
  const unsigned f = p.flags[i];
  const bool al = f & kFlagMixedAlong, ac = f & kFlagMixedAcross;
  std::string k = al && ac ? "along and across" : al ? "along" : ac ? "across" : "spike";
  if (ac && !al) k += lines_apart(p, i, nb, divergence) ? ", lines apart" : ", footprints touch";
  if (f & kFlagBesideVoid) k += ", beside a void";
  if ((f & kFlagSpike) && (al || ac)) k += ", spike";
  if (f & kFlagMixedRun) k += ", later round";
  return k;
}

/// The lowest and highest true top surface over cell (ix, iy) grown by kCellMargin on each side
/// (a point on a vertical face lands in the cell in front of it by its registration error):
/// Scene::top_height on 7 x 7 points (spacing 5 cm at 0.1 m cells: a 5 cm post is always sampled).
constexpr double kCellMargin = 0.05;
std::pair<double, double> cell_top(const sim::Scene& sc, double rs, std::int64_t ix, std::int64_t iy) {
  double tmin = 1e9, tmax = -1e9;
  const double step = (rs + 2 * kCellMargin) / 6.0;
  for (int a = 0; a < 7; ++a)
    for (int b = 0; b < 7; ++b) {
      const double h = sc.top_height(static_cast<double>(ix) * rs - kCellMargin + a * step,
                                     static_cast<double>(iy) * rs - kCellMargin + b * step);
      tmin = std::min(tmin, h);
      tmax = std::max(tmax, h);
    }
  return {tmin, tmax};
}

/// What surrounds a kept mixed pixel that stands more than 0.3 m above its cell's true top: along
/// its line, whether the neighbouring beams hold no kept return (a void, as the stage reads it:
/// no return, or one a filter rejected; a line's end is not a void); across lines, whether the
/// neighbouring lines' footprints touch or overlap its own (lines_apart()); and whether the near
/// surface holds 90 % or more of the power (a mixture dominated by it, behind it only by the far
/// surface's small share of the power, which a far gap makes large in range).
std::string phantom_kind(const Pass& p, const sim::SimPass& sp, std::size_t i, std::size_t nb, double divergence) {
  const std::size_t b = i % nb;
  const bool void_l = b > 0 && !p.is_kept(i - 1), void_r = b + 1 < nb && i + 1 < p.size() && !p.is_kept(i + 1);
  std::string k = void_l && void_r ? "between voids along its line" : void_l || void_r ? "beside a void along its line" : "no void beside it along its line";
  k += lines_apart(p, i, nb, divergence) ? ", lines apart" : ", footprints touch across lines";
  if (sp.footprint[i].near_power_share >= 0.9) k += ", near share >= 0.9";
  return k;
}

/// Whether line k of an organized pass is the last line of a sweep before the nod reverses or the
/// first after it, by the stage's own split (mixed_detail::sweep_starts): there the sequence of
/// lines across which the stage compares a beam ends, so the line has neighbours across lines on
/// one side only. (The pass's first and last lines have too, but are not turns.) `starts`: the
/// pass's sweep_starts(); `last`: k is the last line before a reversal, the sweep's extreme,
/// beyond which no line looked.
bool next_to_nod_turn(const std::vector<std::size_t>& starts, std::size_t k, bool* last = nullptr) {
  // The inner starts (not 0, not line_count()) are the first lines after a reversal.
  const auto turn_starts_at = [&](std::size_t q) { return std::binary_search(starts.begin() + 1, starts.end() - 1, q); };
  if (last) *last = turn_starts_at(k + 1);
  return turn_starts_at(k) || turn_starts_at(k + 1);
}

bool is_filter_label(Label l) { return l == Label::kOcclusion || l == Label::kMixedPixel || l == Label::kOutlier || l == Label::kLowAmplitude || l == Label::kInconsistent; }

Result run_setting(const SweepSetting& st) {
  const auto t_start = std::chrono::steady_clock::now();
  const sim::SimConfig& c = st.sim;
  Result res;
  res.index = st.index;
  char buf[160];
  std::snprintf(buf, sizeof buf, "%4d b/%3.0f deg %4.1f mrad %3.0f mm %s %2.0f l/s %s %.1f m/s", c.scanner.beams,
                (c.scanner.bearing_max - c.scanner.bearing_min) * 180 / kPi, c.scanner.beam_divergence * 1000,
                c.scanner.transceiver_separation * 1000, c.scanner.mirror ? "mir" : "fix", 1.0 / c.scanner.line_period,
                c.scanner.profile == sim::NodProfile::kConstantRate ? "cr" : "ud", c.motion.speed);
  res.sensor = buf;
  const sim::SimResult r = sim::simulate(c);
  const PoseTrack poses(r.poses);
  const Eigen::Isometry3d T_V_N = make_transform(c.mount_translation, c.mount_rpy, c.rpy_order);
  RegisterParams rp;
  rp.max_pose_gap = 0.5;  // as pipelines/nodding_terrain.yaml
  const FuseElevationParams fep;
  ElevationGrid grid = make_elevation_grid(fep);
  // The map a perfect filter gives (every truth-valid return kept, nothing else), and the map of
  // the truth-valid returns the filters kept (the cost of their false rejections alone).
  ElevationGrid perfect = make_elevation_grid(fep), kept_valid = make_elevation_grid(fep);
  const auto fuse_valid = [&](ElevationGrid& g, Pass q, const sim::SimPass& sp) {
    for (std::size_t i = 0; i < q.size(); ++i)
      if (sp.truth[i] != Label::kKept) q.label[i] = Label::kMixedPixel;  // any label but kKept
    fuse_pass(g, q, fep, st.sensor.range_sigma * st.sensor.range_sigma);
  };
  std::vector<Pass> filtered;  // after reject_mixed_pixels, for check_consistency
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, rp, st.sensor, T_V_N, &poses, PoseSigma{}, c.rpy_order);
    fuse_valid(perfect, p, sp);
    reject_occlusion(p, OcclusionParams{}, st.sensor);
    std::vector<char> reaching(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) reaching[i] = p.is_kept(i);
    reject_mixed_pixels(p, sweep_params(st.sensor), st.sensor, PoseSigma{});
    fuse_pass(grid, p, fep, st.sensor.range_sigma * st.sensor.range_sigma);
    fuse_valid(kept_valid, p, sp);
    filtered.push_back(p);
    const std::size_t nb = static_cast<std::size_t>(c.scanner.beams);
    const std::vector<std::size_t> starts = mixed_detail::sweep_starts(p);
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (!p.is_kept(i) || !(p.z[i] > c.scene.top_height(p.x[i], p.y[i]) + 0.3)) continue;
      if (p.z[i] > cell_top(c.scene, grid.resolution(), grid.cell_index(p.x[i]), grid.cell_index(p.y[i])).second + 0.3) {
        ++res.phantom_points[label_name(sp.truth[i])];
        if (sp.truth[i] == Label::kMixedPixel) {
          ++res.phantom_mixed[phantom_kind(p, sp, i, nb, st.sensor.beam_divergence)];
          bool last = false;
          res.phantom_mixed_turn += next_to_nod_turn(starts, i / nb, &last);
          res.phantom_mixed_turn_last += last;
        }
      }
    }
    // One return with its neighbours along its line and across lines: range, truth, label, amplitude.
    const auto dump = [&](const char* what, std::size_t i) {
      const sim::BeamFootprint& f = sp.footprint[i];
      const std::size_t b = i % nb;
      std::printf("%s r=%.3f near %.3f far %.3f share %.2f amp %.0f |", what, p.range[i], f.near, f.far,
                  f.near_power_share, p.amplitude[i]);
      for (long d = -4; d <= 4; ++d) {
        const long j = static_cast<long>(i) + d;
        if (static_cast<long>(b) + d < 0 || static_cast<long>(b) + d >= static_cast<long>(nb)) continue;
        const std::size_t u = static_cast<std::size_t>(j);
        std::printf(" %.3f%c%c%.0f", p.range_cal[u], "VNOMRXLPI"[static_cast<int>(sp.truth[u])], label_name(p.label[u])[0],
                    p.amplitude[u]);
      }
      std::printf(" | across:");
      for (long d = -2; d <= 2; ++d) {
        const long j = static_cast<long>(i) + d * static_cast<long>(nb);
        if (j < 0 || j >= static_cast<long>(p.size())) continue;
        const std::size_t u = static_cast<std::size_t>(j);
        std::printf(" %.3f%c%c%.0f@%.4f", p.range_cal[u], "VNOMRXLPI"[static_cast<int>(sp.truth[u])],
                    label_name(p.label[u])[0], p.amplitude[u], p.nod[u]);
      }
      std::printf("\n");
    };
    if (g_dump_phantoms)  // every kept return > 0.3 m above its cell's true top
      for (std::size_t i = 0; i < p.size(); ++i)
        if (p.is_kept(i) && p.z[i] > cell_top(c.scene, grid.resolution(), grid.cell_index(p.x[i]), grid.cell_index(p.y[i])).second + 0.3) {
          std::printf("setting %d pass %zu line %zu beam %zu z %.2f, its cell's true top %.2f: ", st.index,
                      filtered.size() - 1, i / nb, i % nb, p.z[i],
                      cell_top(c.scene, grid.resolution(), grid.cell_index(p.x[i]), grid.cell_index(p.y[i])).second);
          dump("kept", i);
        }
    for (std::size_t i = 0; i < p.size(); ++i) {
      const bool truth_mixed = sp.truth[i] == Label::kMixedPixel, truth_valid = sp.truth[i] == Label::kKept;
      if (p.label[i] == Label::kMixedPixel && (truth_mixed || truth_valid))
        ++res.evidence[evidence_of(p, i, nb, st.sensor.beam_divergence)][truth_mixed ? 0 : 1];
      ++res.returns;
      const Label t = sp.truth[i], l = p.label[i];
      if (t == Label::kMixedPixel) {
        ++res.mixed;
        res.mixed_turn += next_to_nod_turn(starts, i / nb);
        res.mixed_reaching += reaching[i];
        if (l != Label::kKept) {
          ++res.mixed_rejected;
          continue;
        }
        // A miss: what geometry?
        const sim::BeamFootprint& f = sp.footprint[i];
        const double ri = p.range[i];
        const auto dev = [&](std::size_t j) { return p.range[j] > 0 ? std::fabs(p.range[j] - ri) : -1.0; };
        const std::size_t b = i % nb;
        double din = -1, dac = -1;
        if (b > 0) din = std::max(din, dev(i - 1));
        if (b + 1 < nb) din = std::max(din, dev(i + 1));
        if (i >= nb) dac = std::max(dac, dev(i - nb));
        if (i + nb < p.size()) dac = std::max(dac, dev(i + nb));
        if (g_dump_every > 0 && (res.misses.size() % static_cast<std::size_t>(g_dump_every)) == 0) dump("miss", i);
        res.misses.push_back({ri, f.far - f.near, din, dac, f.near_power_share, f.near_reflectivity, f.far_reflectivity,
                              st.kind_of(f.near_object), st.kind_of(f.far_object), p.z[i] - c.scene.top_height(p.x[i], p.y[i])});
      } else if (t == Label::kKept && l != Label::kNoReturn && l != Label::kOutOfRange && l != Label::kNoPose) {
        ++res.valid;
        if (is_filter_label(l)) {
          ++res.valid_rejected;
          if (l == Label::kMixedPixel) {
            ++res.valid_rejected_mixed;
            const sim::BeamFootprint& f = sp.footprint[i];
            const std::string near = st.kind_of(f.near_object), far = st.kind_of(f.far_object);
            ++res.false_alarms[f.near_object == f.far_object ? near + " only" : near + " > " + far + " (within 4 cm)"];
            if (g_dump_every > 0 && (res.valid_rejected_mixed % static_cast<std::size_t>(g_dump_every)) == 0)
              dump(("false " + near).c_str(), i);
          }
        }
      } else if (t == Label::kOcclusion) {
        ++res.occlusion;
        res.occlusion_rejected += l != Label::kKept;
      } else if (t == Label::kLowAmplitude) {
        ++res.low_amplitude;
        res.low_rejected += l != Label::kKept;
      }
    }
  }
  // The main pipeline (pipelines/nodding_terrain.yaml) also runs check_consistency: other passes'
  // rays through a return's voxel, and no other pass's return near it, contradict it.
  {
    ConsistencyEvidence ev{ConsistencyParams{}};
    for (const Pass& p : filtered) ev.add_pass(p);
    ev.finalize();
    ElevationGrid grid_cc = make_elevation_grid(fep);
    for (std::size_t k = 0; k < filtered.size(); ++k) {
      Pass& p = filtered[k];
      ev.label(p);
      for (std::size_t i = 0; i < p.size(); ++i) {
        if (p.label[i] != Label::kInconsistent) continue;
        const Label t = r.passes[k].truth[i];
        res.cc_mixed += t == Label::kMixedPixel;
        res.cc_valid += t == Label::kKept;
        res.cc_false_ranges += t == Label::kOcclusion || t == Label::kLowAmplitude;
      }
      fuse_pass(grid_cc, p, fep, st.sensor.range_sigma * st.sensor.range_sigma);
    }
    grid_cc.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& cell) {
      double e = 0, var = 0;
      if (!grid_cc.surface(cell, e, var)) return;
      res.phantom_cells_cc += e - cell_top(c.scene, grid_cc.resolution(), ix, iy).second > 0.3;
    });
  }
  // Elevation against the true top surface.
  const double rs = grid.resolution();
  grid.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& cell) {
    double e = 0, var = 0;
    if (!grid.surface(cell, e, var)) return;
    ++res.cells;
    const auto [tmin, tmax] = cell_top(c.scene, rs, ix, iy);
    res.elev_above = std::max(res.elev_above, e - tmax);
    res.elev_below = std::max(res.elev_below, tmin - e);
    res.phantom_cells += e - tmax > 0.3;
    if (tmin - e > 0.3) {
      ++res.cells_below;
      const ElevationCell* pc = perfect.find(ix, iy);
      double ep = 0, vp = 0;
      res.cells_below_unseen += pc && perfect.surface(*pc, ep, vp) && tmin - ep > 0.3;
    }
  });
  perfect.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& pc) {
    double ep = 0, vp = 0;
    if (!perfect.surface(pc, ep, vp)) return;
    ++res.perfect_cells;
    const ElevationCell* kc = kept_valid.find(ix, iy);
    double ek = 0, vk = 0;
    if (!kc || !kept_valid.surface(*kc, ek, vk))
      ++res.cells_emptied;
    else
      res.cells_lowered += ep - ek > 0.3;
  });
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return res;
}

Result pool(const std::vector<Result>& rs) {
  Result p;
  p.index = -1;
  p.sensor = "pooled";
  for (const auto& r : rs) {
    p.returns += r.returns;
    p.mixed += r.mixed;
    p.mixed_rejected += r.mixed_rejected;
    p.mixed_reaching += r.mixed_reaching;
    p.valid += r.valid;
    p.valid_rejected += r.valid_rejected;
    p.valid_rejected_mixed += r.valid_rejected_mixed;
    p.occlusion += r.occlusion;
    p.occlusion_rejected += r.occlusion_rejected;
    p.low_amplitude += r.low_amplitude;
    p.low_rejected += r.low_rejected;
    p.cells += r.cells;
    p.phantom_cells += r.phantom_cells;
    p.phantom_cells_cc += r.phantom_cells_cc;
    p.cc_mixed += r.cc_mixed;
    p.cc_valid += r.cc_valid;
    p.cc_false_ranges += r.cc_false_ranges;
    p.cells_below += r.cells_below;
    p.cells_below_unseen += r.cells_below_unseen;
    p.perfect_cells += r.perfect_cells;
    p.cells_lowered += r.cells_lowered;
    p.cells_emptied += r.cells_emptied;
    p.elev_above = std::max(p.elev_above, r.elev_above);
    p.elev_below = std::max(p.elev_below, r.elev_below);
    p.seconds += r.seconds;
    p.misses.insert(p.misses.end(), r.misses.begin(), r.misses.end());
    for (const auto& [k, n] : r.phantom_points) p.phantom_points[k] += n;
    for (const auto& [k, n] : r.phantom_mixed) p.phantom_mixed[k] += n;
    p.phantom_mixed_turn += r.phantom_mixed_turn;
    p.phantom_mixed_turn_last += r.phantom_mixed_turn_last;
    p.mixed_turn += r.mixed_turn;
    for (const auto& [k, n] : r.false_alarms) p.false_alarms[k] += n;
    for (const auto& [k, n] : r.evidence) {
      p.evidence[k][0] += n[0];
      p.evidence[k][1] += n[1];
    }
  }
  return p;
}

/// The per-setting acceptance bars the summary counts (docs/mixed_pixels.md, "Randomized sensors
/// and scenes"): mixed-pixel recall at least this, valid returns rejected at most this per cent, and
/// no elevation cell more than 0.3 m above the true top.
constexpr double kBarRecall = 0.90, kBarValidPct = 1.0;

void print_row(const Result& r) {
  std::printf("%5s %-44s %7llu %6.3f %6.2f %% %6.3f %6llu %6.3f %6.2f %6.2f %5llu %5llu %6.1f\n",
              r.index < 0 ? "all" : std::to_string(r.index).c_str(), r.sensor.c_str(),
              static_cast<unsigned long long>(r.mixed), r.recall(), 100 * r.valid_rate(), r.f1(),
              static_cast<unsigned long long>(r.occlusion), r.occ_recall(), r.elev_above, r.elev_below,
              static_cast<unsigned long long>(r.phantom_cells), static_cast<unsigned long long>(r.phantom_cells_cc), r.seconds);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Where the misses are: the edge's direction from the neighbours (in-line: beams +-1; across:
/// the same beam on lines +-1), the range gap between the nearest and farthest lit surfaces, the
/// near surface's share of the power and the objects.
void print_misses(const Result& r) {
  const auto& m = r.misses;
  std::printf("  setting %s: %zu misses of %llu mixed pixels (%llu reached the mixed-pixel filter)\n",
              r.index < 0 ? "all" : std::to_string(r.index).c_str(), m.size(), static_cast<unsigned long long>(r.mixed),
              static_cast<unsigned long long>(r.mixed_reaching));
  if (!r.phantom_points.empty()) {
    std::printf("    kept points > 0.3 m above the true top:");
    for (const auto& [k, n] : r.phantom_points) std::printf(" %s %llu;", k.c_str(), static_cast<unsigned long long>(n));
    std::printf("\n");
  }
  if (!r.false_alarms.empty()) {
    std::vector<std::pair<std::uint64_t, std::string>> fa;
    for (const auto& [k, n] : r.false_alarms) fa.emplace_back(n, k);
    std::sort(fa.rbegin(), fa.rend());
    std::printf("    valid returns rejected as mixed pixels (%llu), what the footprint lit:",
                static_cast<unsigned long long>(r.valid_rejected_mixed));
    for (std::size_t k = 0; k < std::min<std::size_t>(5, fa.size()); ++k)
      std::printf(" %s %llu;", fa[k].second.c_str(), static_cast<unsigned long long>(fa[k].first));
    std::printf("\n");
  }
  if (m.empty()) return;
  std::map<std::string, int> cls, objs;
  std::vector<double> gap, range, share, ratio, din, dac;
  for (const auto& x : m) {
    const double t = std::max(0.15, 0.25 * x.gap);  // a neighbour this far off is on the other surface
    const bool in = x.inline_dev > t, ac = x.across_dev > t;
    cls[in && ac ? "both differ (oblique/corner)" : in ? "in-line differs only (edge across the lines)"
        : ac ? "across-line differs only (edge along the lines)" : "neither differs (isolated)"]++;
    objs[x.near_kind + " > " + x.far_kind]++;
    gap.push_back(x.gap);
    range.push_back(x.range);
    share.push_back(x.near_share);
    ratio.push_back(x.far_refl > 0 ? x.near_refl / x.far_refl : 0);
    din.push_back(x.inline_dev);
    dac.push_back(x.across_dev);
  }
  for (const auto& [k, n] : cls) std::printf("    %-48s %5d (%4.1f %%)\n", k.c_str(), n, 100.0 * n / double(m.size()));
  std::vector<std::pair<int, std::string>> o;
  for (const auto& [k, n] : objs) o.emplace_back(n, k);
  std::sort(o.rbegin(), o.rend());
  std::printf("    near > far objects:");
  for (std::size_t k = 0; k < std::min<std::size_t>(4, o.size()); ++k) std::printf(" %s %d;", o[k].second.c_str(), o[k].first);
  std::printf("\n    median: range %.2f m, gap %.2f m, near power share %.2f, near/far reflectivity %.2f, in-line dev %.3f m, across dev %.3f m\n",
              median(range), median(gap), median(share), median(ratio), median(din), median(dac));
  int gap_small = 0, gap_big = 0;
  for (double g : gap) {
    gap_small += g < 0.3;
    gap_big += g > 1.0;
  }
  std::printf("    gap < 0.3 m: %d, gap > 1 m: %d\n", gap_small, gap_big);
  // What a kept miss does to a terrain map: its height above the true top where it lies (below
  // it: on a vertical face or under an overhang, which a 2.5-D map's top surface does not show).
  int h[5] = {};
  for (const auto& x : m) h[x.height < -0.05 ? 0 : x.height <= 0.05 ? 1 : x.height <= 0.1 ? 2 : x.height <= 0.3 ? 3 : 4]++;
  std::printf("    height above the true top where the point lies: below -0.05 m %d, within 0.05 m %d, 0.05-0.1 m %d, 0.1-0.3 m %d, above 0.3 m %d\n",
              h[0], h[1], h[2], h[3], h[4]);
}

/// The kept mixed pixels standing more than 0.3 m above their cell's true top.
std::uint64_t phantom_mixed_pixels(const Result& r) {
  const auto it = r.phantom_points.find(label_name(Label::kMixedPixel));
  return it == r.phantom_points.end() ? 0 : it->second;
}

void json_row(FILE* f, const Result& r, const char* name) {
  std::fprintf(f,
               "{\"setting\": %s, \"sensor\": \"%s\", \"returns\": %llu, \"mixed\": %llu, \"mixed_rejected\": %llu, "
               "\"mixed_recall\": %.4f, "
               "\"mixed_reaching_filter\": %llu, \"valid\": %llu, \"valid_rejected\": %llu, \"valid_rejected_pct\": %.4f, "
               "\"valid_rejected_as_mixed\": %llu, \"f1\": %.4f, \"occlusion\": %llu, \"occlusion_recall\": %.4f, "
               "\"low_amplitude\": %llu, \"low_amplitude_rejected\": %llu, \"elevation_cells\": %llu, "
               "\"elevation_max_above_m\": %.3f, \"elevation_max_below_m\": %.3f, \"phantom_cells\": %llu, "
               "\"phantom_cells_with_check_consistency\": %llu, \"check_consistency_mixed\": %llu, "
               "\"check_consistency_valid\": %llu, \"check_consistency_false_ranges\": %llu, "
               "\"phantom_mixed_pixels\": %llu, \"phantom_mixed_pixels_next_to_nod_turn\": %llu, "
               "\"phantom_mixed_pixels_on_last_line_before_nod_turn\": %llu, \"mixed_next_to_nod_turn\": %llu, "
               "\"cells_below_true_top\": %llu, \"cells_below_true_top_unseen\": %llu, "
               "\"perfect_filter_cells\": %llu, \"cells_lowered_by_false_rejections\": %llu, "
               "\"cells_emptied_by_false_rejections\": %llu, \"seconds\": %.2f}",
               name, r.sensor.c_str(), static_cast<unsigned long long>(r.returns), static_cast<unsigned long long>(r.mixed),
               static_cast<unsigned long long>(r.mixed_rejected), r.recall(), static_cast<unsigned long long>(r.mixed_reaching), static_cast<unsigned long long>(r.valid),
               static_cast<unsigned long long>(r.valid_rejected), 100 * r.valid_rate(),
               static_cast<unsigned long long>(r.valid_rejected_mixed), r.f1(), static_cast<unsigned long long>(r.occlusion),
               r.occ_recall(), static_cast<unsigned long long>(r.low_amplitude), static_cast<unsigned long long>(r.low_rejected),
               static_cast<unsigned long long>(r.cells), r.elev_above, r.elev_below,
               static_cast<unsigned long long>(r.phantom_cells), static_cast<unsigned long long>(r.phantom_cells_cc),
               static_cast<unsigned long long>(r.cc_mixed), static_cast<unsigned long long>(r.cc_valid),
               static_cast<unsigned long long>(r.cc_false_ranges), static_cast<unsigned long long>(phantom_mixed_pixels(r)),
               static_cast<unsigned long long>(r.phantom_mixed_turn), static_cast<unsigned long long>(r.phantom_mixed_turn_last),
               static_cast<unsigned long long>(r.mixed_turn), static_cast<unsigned long long>(r.cells_below),
               static_cast<unsigned long long>(r.cells_below_unseen), static_cast<unsigned long long>(r.perfect_cells),
               static_cast<unsigned long long>(r.cells_lowered), static_cast<unsigned long long>(r.cells_emptied), r.seconds);
}
}  // namespace

/// A --require value: a non-negative number, or exit 2 naming it (a typo must not disable a check).
static double number(const char* text) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(v >= 0)) {
    std::fprintf(stderr, "pcdp_mixed_sweep: '%s' is not a non-negative number\n", text);
    std::exit(2);
  }
  return v;
}

int main(int argc, char** argv) {
  std::string set = "tuning", json;
  std::vector<int> indices;
  int worst = 3;
  std::string rank = "recall";
  double need_recall = -1, need_valid = -1, need_occlusion = -1;
  long need_phantom = -1;
  for (int a = 1; a < argc; ++a) {
    const std::string k = argv[a];
    const bool has = a + 1 < argc;
    if (k == "--set" && has) set = argv[++a];
    else if (k == "--index" && has) indices.push_back(std::atoi(argv[++a]));
    else if (k == "--json" && has) json = argv[++a];
    else if (k == "--misses" && has) worst = std::atoi(argv[++a]);
    else if (k == "--rank" && has) rank = argv[++a];
    else if (k == "--dump-misses" && has) g_dump_every = std::atoi(argv[++a]);
    else if (k == "--dump-phantoms") g_dump_phantoms = true;
    else if (k == "--require-recall" && has) need_recall = number(argv[++a]);
    else if (k == "--require-valid-rejected" && has) need_valid = number(argv[++a]);
    else if (k == "--require-occlusion-recall" && has) need_occlusion = number(argv[++a]);
    else if (k == "--require-phantom-cells" && has) need_phantom = static_cast<long>(number(argv[++a]));
    else if (k == "--param" && has && std::strchr(argv[a + 1], '=')) {
      const std::string nv = argv[++a], name = nv.substr(0, nv.find('=')), value = nv.substr(nv.find('=') + 1);
      if (!kSweepParams.count(name)) {
        std::fprintf(stderr, "--param %s: unknown parameter (one of %s)\n", name.c_str(), sweep_param_names().c_str());
        return 2;
      }
      g_params.emplace_back(name, name == "jump_min" && value == "derived" ? NAN : number(value.c_str()));
    } else {
      std::fprintf(stderr,
                   "usage: %s [--set tuning|heldout] [--index N]... [--json FILE] [--misses K] [--rank recall|f1|valid]\n"
                   "          [--require-recall R] [--require-valid-rejected PCT] [--require-occlusion-recall R] [--require-phantom-cells N]\n"
                   "          [--dump-misses K] [--dump-phantoms] [--param NAME=VALUE]...\n"
                   "  --param NAME=VALUE: one MixedPixelParams member changed (%s; jump_min=derived:\n"
                   "                      2 x (range_tolerance + 3 sensor.range_sigma))\n"
                   "  --dump-misses K: print every K-th miss and every K-th valid return rejected, with neighbours\n"
                   "  --dump-phantoms: print every kept return more than 0.3 m above its cell's true top, with neighbours\n"
                   "  --misses K: analyse the misses of the K worst settings by --rank (default 3, recall)\n"
                   "  tuning: settings 0-23; heldout: 1000-1015 (never used for tuning)\n",
                   argv[0], sweep_param_names().c_str());
      return 2;
    }
  }
  if (indices.empty()) {
    if (set == "tuning") for (int i = 0; i < 24; ++i) indices.push_back(i);
    else if (set == "heldout") for (int i = 1000; i < 1016; ++i) indices.push_back(i);
    else {
      std::fprintf(stderr, "--set must be tuning or heldout\n");
      return 2;
    }
  } else {
    set = "chosen";
  }
  std::printf("%5s %-44s %7s %6s %8s %6s %6s %6s %6s %6s %5s %5s %6s\n", "set", "sensor (beams/span, div, s-q, geom, lines/s, nod, v)",
              "mixed", "recall", "valid rj", "F1", "occl", "recall", "el+ m", "el- m", "phant", "+cc", "s");
  std::vector<Result> results;
  for (int i : indices) {
    results.push_back(run_setting(make_sweep_setting(i)));
    print_row(results.back());
    std::fflush(stdout);
  }
  const Result all = pool(results);
  print_row(all);
  // The acceptance bars hold per setting, not pooled (a good pool can hide a bad sensor).
  std::size_t met_recall = 0, met_valid = 0, met_phantom = 0, met_all = 0;
  for (const auto& r : results) {
    const bool rec = r.recall() >= kBarRecall, val = 100 * r.valid_rate() <= kBarValidPct, ph = r.phantom_cells == 0;
    met_recall += rec;
    met_valid += val;
    met_phantom += ph;
    met_all += rec && val && ph;
  }
  std::printf("settings meeting each bar: recall >= %.2f %zu / %zu; valid rejected <= %.0f %% %zu / %zu; no phantom cell %zu / %zu; all "
              "three %zu / %zu\n",
              kBarRecall, met_recall, results.size(), kBarValidPct, met_valid, results.size(), met_phantom, results.size(), met_all,
              results.size());
  std::printf("valid returns rejected as mixed pixels: %llu of %llu rejected; low-amplitude false ranges rejected: %llu of %llu\n",
              static_cast<unsigned long long>(all.valid_rejected_mixed), static_cast<unsigned long long>(all.valid_rejected),
              static_cast<unsigned long long>(all.low_rejected), static_cast<unsigned long long>(all.low_amplitude));
  std::printf("check_consistency after the filters (column +cc): %llu more mixed pixels, %llu more valid returns (%.3f %% of "
              "the valid) and %llu more false ranges removed\n",
              static_cast<unsigned long long>(all.cc_mixed), static_cast<unsigned long long>(all.cc_valid),
              all.valid ? 100.0 * static_cast<double>(all.cc_valid) / static_cast<double>(all.valid) : 0.0,
              static_cast<unsigned long long>(all.cc_false_ranges));
  std::printf("cells more than 0.3 m below the lowest true top: %llu, %llu of them also with a perfect filter; the false "
              "rejections alone (the valid returns kept against all of them, %llu cells): %llu cells lowered by more than "
              "0.3 m, %llu left without a surface\n",
              static_cast<unsigned long long>(all.cells_below), static_cast<unsigned long long>(all.cells_below_unseen),
              static_cast<unsigned long long>(all.perfect_cells), static_cast<unsigned long long>(all.cells_lowered),
              static_cast<unsigned long long>(all.cells_emptied));
  std::printf("kept points more than 0.3 m above their cell's true top, by truth label:");
  for (const auto& [k, n] : all.phantom_points) std::printf(" %s %llu;", k.c_str(), static_cast<unsigned long long>(n));
  std::printf("\n");
  if (!all.phantom_mixed.empty()) {
    std::vector<std::pair<std::uint64_t, std::string>> pm;
    for (const auto& [k, n] : all.phantom_mixed) pm.emplace_back(n, k);
    std::sort(pm.rbegin(), pm.rend());
    std::printf("  the mixed pixels among them, by what surrounds them:\n");
    for (const auto& [n, k] : pm) std::printf("    %-90s %6llu\n", k.c_str(), static_cast<unsigned long long>(n));
    std::printf("  of them on a line next to a nod turn (the last before the nod reverses or the first after): %llu "
                "(%.1f %%, %llu on the last line before; of all mixed pixels %.1f %% lie on such lines)\n",
                static_cast<unsigned long long>(all.phantom_mixed_turn),
                100.0 * static_cast<double>(all.phantom_mixed_turn) / static_cast<double>(phantom_mixed_pixels(all)),
                static_cast<unsigned long long>(all.phantom_mixed_turn_last),
                all.mixed ? 100.0 * static_cast<double>(all.mixed_turn) / static_cast<double>(all.mixed) : 0.0);
  }
  std::vector<const Result*> order;
  for (const auto& r : results) order.push_back(&r);
  std::sort(order.begin(), order.end(), [&](const Result* a, const Result* b) {
    return rank == "f1" ? a->f1() < b->f1() : rank == "valid" ? a->valid_rate() > b->valid_rate() : a->recall() < b->recall();
  });
  std::printf("\nmisses (truth mixed pixels kept), pooled and for the %d worst settings by %s:\n", worst, rank.c_str());
  print_misses(all);
  {
    // Which evidence labels the returns, against the truth: where the false alarms come from.
    std::vector<std::pair<std::array<std::uint64_t, 2>, std::string>> ev;
    for (const auto& [k, n] : all.evidence) ev.push_back({n, k});
    std::sort(ev.begin(), ev.end(), [](const auto& a, const auto& b) { return a.first[0] + a.first[1] > b.first[0] + b.first[1]; });
    std::printf("  returns labelled mixed_pixel, by the evidence (flags): mixed pixels found, valid returns rejected\n");
    for (const auto& [n, k] : ev)
      std::printf("    %-52s %7llu %7llu\n", k.c_str(), static_cast<unsigned long long>(n[0]), static_cast<unsigned long long>(n[1]));
  }
  for (int k = 0; k < worst && k < static_cast<int>(order.size()); ++k) print_misses(*order[static_cast<std::size_t>(k)]);
  if (!json.empty()) {
    FILE* f = std::fopen(json.c_str(), "w");
    if (!f) {
      std::fprintf(stderr, "%s: cannot write\n", json.c_str());
      return 4;
    }
    std::fprintf(f, "{\"set\": \"%s\", \"settings\": [\n", set.c_str());
    for (std::size_t k = 0; k < results.size(); ++k) {
      json_row(f, results[k], std::to_string(results[k].index).c_str());
      std::fprintf(f, k + 1 < results.size() ? ",\n" : "\n");
    }
    std::fprintf(f, "], \"pooled\": ");
    json_row(f, all, "\"pooled\"");
    std::fprintf(f,
                 ", \"settings_meeting\": {\"recall_at_least_0_90\": %zu, \"valid_rejected_at_most_1_pct\": %zu, "
                 "\"no_phantom_cell\": %zu, \"all_three\": %zu, \"settings\": %zu}}\n",
                 met_recall, met_valid, met_phantom, met_all, results.size());
    std::fclose(f);
  }
  int failed = 0;
  const auto require = [&](bool ok, const char* what, double got, double need) {
    if (ok) return;
    std::fprintf(stderr, "pooled %s is %.4f, required %.4f\n", what, got, need);
    failed = 1;
  };
  if (need_recall >= 0) require(all.recall() >= need_recall, "mixed-pixel recall (at least)", all.recall(), need_recall);
  if (need_valid >= 0) require(100 * all.valid_rate() <= need_valid, "valid returns rejected, % (at most)", 100 * all.valid_rate(), need_valid);
  if (need_occlusion >= 0) require(all.occ_recall() >= need_occlusion, "occlusion recall (at least)", all.occ_recall(), need_occlusion);
  if (need_phantom >= 0) require(static_cast<long>(all.phantom_cells) <= need_phantom, "phantom cells (at most)", double(all.phantom_cells), double(need_phantom));
  return failed;
}
