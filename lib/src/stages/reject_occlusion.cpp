#include "pcdp/stages/reject_occlusion.hpp"

#include <algorithm>
#include <cmath>

#include "pcdp/core/errors.hpp"
#include "pcdp/models/occlusion_model.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp {

const Options<OcclusionParams>& reject_occlusion_options() {
  using P = OcclusionParams;
  static const auto o = Options<P>()
      .add("window", &P::window, bounds(1, 100), "returns", "how far to search on each side for stable neighbours")
      .add("stable", &P::stable, bounds(1, 10), "returns", "stable neighbours used on each side")
      .add("amplitude_margin", &P::amplitude_margin, at_least(0), "", "suspect below min_amplitude + this; surely weak below min_amplitude - this (sensor amplitude units)")
      .add("jump_min", &P::jump_min, bounds(0, 100), "m", "smallest range step between the sides that makes an edge")
      .add("jump_ratio", &P::jump_ratio, bounds(0, 10), "", "... or this fraction of the near range, if larger")
      .add("range_tolerance", &P::range_tolerance, bounds(0, 100), "m", "a range within this of a side's extrapolation fits it")
      .add("range_tolerance_ratio", &P::range_tolerance_ratio, bounds(0, 1), "", "plus this fraction of the range")
      .add("across_lines", &P::across_lines, "also look across scan lines (same beam), where the nod crosses the edge")
      .add("repair", &P::repair, "replace a false range by the nearer stable neighbour's instead of rejecting it")
      .add("low_amplitude", &P::low_amplitude, "label low_amplitude the weak returns away from dipping edges")
      .rule("stable <= window", [](const P& p) { return p.stable <= p.window; },
            "the stable neighbours are found within the window",
            "option 'stable' = {stable} must not exceed 'window' = {window}");
  return o;
}

const OptionSchema& reject_occlusion_schema() { return reject_occlusion_options().schema(); }

namespace {

struct Side {
  int count = 0;
  double range = 0, amplitude = 0;
  double second = 0;     ///< the second-nearest neighbour's range (count >= 2)
  double r[2] = {0, 0};  ///< the two nearest ranges
  double at[2] = {0, 0}; ///< their distances (in positions) from the suspect
  double predicted = 0;  ///< linear extrapolation to the suspect
  std::size_t nearest = 0;
};

struct Judgement {
  /// Sides (along: left, right; across: before, after) whose neighbours (kept returns not surely
  /// weak) the range fits; a smooth fit through both sides of a sequence counts twice.
  int support = 0;
  int sides = 0;  ///< sides with such a neighbour within the window
  bool dipping = false;
  double repair_range = 0;
};

class Sequencer {
 public:
  Sequencer(Pass& p, const OcclusionParams& prm, const SensorParams& s, const std::vector<char>& evidence,
            const std::vector<char>& stable)
      : p_(p), prm_(prm), s_(s), evidence_(evidence), stable_(stable) {}

  /// Judges position `pos` of the sequence `seq` (indices into the pass).
  void judge(const std::vector<std::size_t>& seq, std::size_t pos, bool along, Judgement& j) const {
    const std::size_t i = seq[pos];
    const double rng = p_.range_cal[i];
    const auto fits = [&](const Side& sd) {
      if (sd.count == 0) return false;
      const auto ok = [&](double pred) {
        return std::fabs(rng - pred) <= prm_.range_tolerance + prm_.range_tolerance_ratio * pred;
      };
      // Either neighbour alone, or their extrapolation: one false neighbour does not spoil a side.
      return ok(sd.predicted) || ok(sd.range) || (sd.count >= 2 && ok(sd.second));
    };
    // Consistency: against kept neighbours not surely below the threshold (weak but valid surfaces
    // have weak neighbours);
    // the edge model: against stable neighbours only (their amplitudes are P1 and P2).
    const Side kl = side(seq, pos, -1, evidence_), kr = side(seq, pos, +1, evidence_);
    const double tol = prm_.range_tolerance + prm_.range_tolerance_ratio * rng;
    j.sides += static_cast<int>(kl.count > 0) + static_cast<int>(kr.count > 0);
    if (kl.count > 0 && kr.count > 0 && smooth_fit(kl, kr, tol, rng)) {
      j.support += 2;
    } else {
      // At a discontinuity a valid return lies on one of the two surfaces; a false range is
      // arbitrary and agrees with one side by chance only (a few per cent).
      j.support += static_cast<int>(fits(kl)) + static_cast<int>(fits(kr));
    }
    const Side l = side(seq, pos, -1, stable_), r = side(seq, pos, +1, stable_);
    if (l.count == 0 || r.count == 0) return;
    const bool left_near = l.range < r.range;
    const Side& nr = left_near ? l : r;
    const Side& fr = left_near ? r : l;
    if (fr.range - nr.range <= std::max(prm_.jump_min, prm_.jump_ratio * nr.range)) return;
    // Direction from the suspect towards the near side, in the beam's transverse plane.
    const double theta = s_.transceiver_angle == TransceiverAngle::kMirror
                             ? static_cast<double>(p_.bearing[i]) + s_.transceiver_angle_offset
                             : s_.transceiver_angle_offset;
    double towards_near;
    if (along)
      towards_near = p_.bearing[nr.nearest] > p_.bearing[i] ? 1.0 : -1.0;
    else
      towards_near = p_.nod_at_return[nr.nearest] > p_.nod_at_return[i] ? 1.0 : -1.0;
    const double projected = (along ? std::cos(theta) : std::sin(theta)) * towards_near;
    EdgeParams e;
    e.d1 = nr.range;
    e.d2 = fr.range;
    e.p1 = nr.amplitude;
    e.p2 = fr.amplitude;
    e.alpha = s_.beam_divergence;
    e.separation = std::max(0.0, s_.transceiver_separation * projected);
    e.theta = 0.0;
    if (profile_dips_below(e, s_.min_amplitude)) {
      if (!j.dipping) {
        const std::size_t dl = pos - position_of(seq, pos, l.nearest, -1), dr = position_of(seq, pos, r.nearest, +1) - pos;
        j.repair_range = dl < dr ? l.range : dr < dl ? r.range : nr.range;
      }
      j.dipping = true;
    }
  }

 private:
  /// The kept neighbours on both sides lie on one line (range against position): a smooth surface.
  /// Then the suspect fits if it lies on that line too.
  bool smooth_fit(const Side& l, const Side& r, double tol, double rng) const {
    double xs[4], ys[4];
    int n = 0;
    for (int k = 0; k < l.count && k < 2; ++k) {
      xs[n] = -l.at[k];
      ys[n++] = l.r[k];
    }
    for (int k = 0; k < r.count && k < 2; ++k) {
      xs[n] = r.at[k];
      ys[n++] = r.r[k];
    }
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int k = 0; k < n; ++k) {
      sx += xs[k];
      sy += ys[k];
      sxx += xs[k] * xs[k];
      sxy += xs[k] * ys[k];
    }
    const double det = n * sxx - sx * sx;
    if (det <= 0) return false;
    const double slope = (n * sxy - sx * sy) / det, icept = (sy - slope * sx) / n;
    if (n == 2) {  // two points always lie on a line: accept only a small step
      if (std::fabs(r.r[0] - l.r[0]) > std::max(prm_.jump_min, prm_.jump_ratio * std::min(r.r[0], l.r[0]))) return false;
    } else {
      double ss = 0;
      for (int k = 0; k < n; ++k) ss += (ys[k] - icept - slope * xs[k]) * (ys[k] - icept - slope * xs[k]);
      if (std::sqrt(ss / (n - 2)) > tol) return false;  // not one smooth surface
    }
    return std::fabs(rng - icept) <= tol;
  }

  Side side(const std::vector<std::size_t>& seq, std::size_t pos, int dir, const std::vector<char>& usable) const {
    Side sd;
    double r[16], a[16], at[16];
    const int want = std::min(prm_.stable, 16);
    for (int step = 1; step <= prm_.window && sd.count < want; ++step) {
      const long q = static_cast<long>(pos) + dir * step;
      if (q < 0 || q >= static_cast<long>(seq.size())) break;
      const std::size_t k = seq[static_cast<std::size_t>(q)];
      if (!usable[k]) continue;
      if (sd.count == 0) sd.nearest = k;
      r[sd.count] = p_.range_cal[k];
      a[sd.count] = p_.amplitude[k];
      at[sd.count] = step;
      ++sd.count;
    }
    if (sd.count == 0) return sd;
    for (int k = 0; k < std::min(sd.count, 2); ++k) {
      sd.r[k] = r[k];
      sd.at[k] = at[k];
    }
    // NaN amplitudes ("not measured") sort last so the comparison stays a strict weak ordering.
    std::sort(a, a + sd.count, [](double x, double y) { return x < y || (std::isnan(y) && !std::isnan(x)); });
    sd.amplitude = a[sd.count / 2];
    sd.range = r[0];
    sd.predicted = r[0];
    if (sd.count >= 2) {
      sd.second = r[1];
      // Extrapolate the two nearest linearly to the suspect's position. Across lines on grazing
      // ground the step between lines reaches metres, so no step limit applies: from two false
      // ranges, or across an edge, the prediction is one arbitrary value more, which a false range
      // fits by chance as rarely as a neighbour's own range.
      const double slope = (r[1] - r[0]) / (at[1] - at[0]);
      sd.predicted = r[0] - slope * at[0];
    }
    return sd;
  }

  static std::size_t position_of(const std::vector<std::size_t>& seq, std::size_t pos, std::size_t index, int dir) {
    for (long q = static_cast<long>(pos); q >= 0 && q < static_cast<long>(seq.size()); q += dir)
      if (seq[static_cast<std::size_t>(q)] == index) return static_cast<std::size_t>(q);
    return pos;
  }

  Pass& p_;
  const OcclusionParams& prm_;
  const SensorParams& s_;
  const std::vector<char>& evidence_;  ///< kept and not surely below the threshold
  const std::vector<char>& stable_;
};

}  // namespace

OcclusionCounts reject_occlusion(Pass& p, const OcclusionParams& prm, const SensorParams& s) {
  OcclusionCounts counts;
  const std::size_t n = p.size();
  if (p.range_cal.size() != n) throw std::logic_error("reject_occlusion needs a registered pass");
  if (p.flags.size() != n) p.flags.assign(n, 0);
  const double a0 = s.min_amplitude;
  // Surely below the threshold, noise included (false for an unmeasured, NaN, amplitude).
  const auto surely_weak = [&](double a) { return a < a0 - prm.amplitude_margin; };
  std::vector<char> suspect(n, 0), stable(n, 0), evidence(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!p.is_kept(i)) continue;
    // A neighbour surely below the threshold is itself a false range or no evidence of a surface.
    evidence[i] = !surely_weak(p.amplitude[i]);
    suspect[i] = p.amplitude[i] < a0 + prm.amplitude_margin;
    stable[i] = !suspect[i];
    counts.suspects += suspect[i];
  }
  if (counts.suspects == 0) return counts;

  std::vector<Judgement> judge(n);
  const Sequencer seqr(p, prm, s, evidence, stable);
  std::vector<std::size_t> seq;
  // Along each scan line.
  for (std::size_t k = 0; k < p.line_count(); ++k) {
    seq.clear();
    for (std::size_t i = p.line_begin[k]; i < p.line_begin[k + 1]; ++i) seq.push_back(i);
    for (std::size_t pos = 0; pos < seq.size(); ++pos)
      if (suspect[seq[pos]]) seqr.judge(seq, pos, true, judge[seq[pos]]);
  }
  // Across lines: the same beam in consecutive lines (organized passes: equal line lengths).
  bool organized = p.line_count() > 1;
  for (std::size_t k = 1; organized && k < p.line_count(); ++k)
    organized = p.line_begin[k + 1] - p.line_begin[k] == p.line_begin[1] - p.line_begin[0];
  if (prm.across_lines && organized) {
    const std::size_t width = p.line_begin[1] - p.line_begin[0];
    for (std::size_t b = 0; b < width; ++b) {
      seq.clear();
      for (std::size_t k = 0; k < p.line_count(); ++k) seq.push_back(p.line_begin[k] + b);
      for (std::size_t pos = 0; pos < seq.size(); ++pos)
        if (suspect[seq[pos]]) seqr.judge(seq, pos, false, judge[seq[pos]]);
    }
  }

  for (std::size_t i = 0; i < n; ++i) {
    if (!suspect[i]) continue;
    const Judgement& j = judge[i];
    const double a = p.amplitude[i];
    // At an edge a valid return lies on one of the two surfaces: one side that fits is enough.
    // Away from a dipping edge, a return reported below the threshold is more likely a false range
    // than not: one side fitting by chance (a few per cent) is not enough, two independent sides
    // must fit (the chance squared).
    const int needed = !j.dipping && a < a0 && j.sides >= 2 ? 2 : 1;
    const bool rejected = surely_weak(a) || j.support < needed;
    if (j.dipping && rejected) {
      counts.dipping_edges += 1;
      if (prm.repair) {
        const double old = p.range_cal[i];
        p.range_cal[i] = static_cast<float>(j.repair_range);
        if (std::isfinite(p.x[i]) && old > 0) {
          const double f = j.repair_range / old;  // the point moves along its beam
          p.x[i] = p.ox[i] + f * (p.x[i] - p.ox[i]);
          p.y[i] = p.oy[i] + f * (p.y[i] - p.oy[i]);
          p.z[i] = p.oz[i] + f * (p.z[i] - p.oz[i]);
        }
        p.flags[i] |= kFlagRepaired;
        ++counts.repaired;
      } else {
        p.label[i] = Label::kOcclusion;
        ++counts.occlusion;
      }
    } else if (prm.low_amplitude && rejected) {
      p.label[i] = Label::kLowAmplitude;
      ++counts.low_amplitude;
    }
  }
  return counts;
}

namespace {
class RejectOcclusionStage final : public Stage {
 public:
  RejectOcclusionStage(OcclusionParams p, const RunContext& ctx) : params_(p), sensor_(ctx.config->sensor) {}
  StageKind kind() const override { return StageKind::kLabeller; }
  int reach() const override { return params_.across_lines ? params_.window + 1 : 0; }
  void label(Pass& pass, StageReport& report) const override {
    const OcclusionCounts c = reject_occlusion(pass, params_, sensor_);
    report.metrics["suspects"] += static_cast<double>(c.suspects);
    report.metrics["repaired"] += static_cast<double>(c.repaired);
  }

 private:
  OcclusionParams params_;
  SensorParams sensor_;
};
}  // namespace

StageInfo reject_occlusion_stage_info() {
  return {"reject_occlusion",
          "false ranges at range edges of non-coaxial scanners (Liu et al. 2005 amplitude model), and weak returns",
          reject_occlusion_schema(),
          [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            const OcclusionParams p = reject_occlusion_options().bind(sc.options);
            return std::make_unique<RejectOcclusionStage>(p, ctx);
          }};
}

}  // namespace pcdp
