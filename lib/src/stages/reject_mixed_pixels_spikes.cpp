// Stage `reject_mixed_pixels`: the spike tests (a thin object, or a mixture of one with the
// surface behind, a few returns wide along a line) and the amplitude test that follows a spike's
// object across lines. Internal; declared in reject_mixed_pixels_detail.hpp.
#include <algorithm>
#include <cmath>

#include "pcdp/models/mixing_model.hpp"
#include "reject_mixed_pixels_detail.hpp"

namespace pcdp::mixed_detail {

namespace {
/// Whether a spike return whose neighbours across lines keep its range is nevertheless a mixture
/// by its amplitude (the mixing model of test 4 used the other way round, as evidence for a
/// mixture rather than against one). At the top of a post seen as the nod turns, or beside a post
/// as the line slides along it, the footprint keeps a similar share of post and wall from line to
/// line, so the mixtures there are as flat across lines as the post. Their amplitude is not: with
/// a bright post (P1 at d1) in front of a dim wall (P2 at d2), a mixture a few centimetres behind
/// the post has lost a large share of the post's light, because the wall's contribution is weighted
/// by its distance from the post (r - d1 = (1 - f) P2 (d2 - d1) / A). The object's pure return is
/// taken as the brightest return of the chain that continues the spike across lines (each within
/// an edge jump of the last, in front of the wall), up to kObjectReach lines each way. The return
/// is a mixture if
///  - its range is behind that return and in front of the wall, each by more than the tolerance;
///  - the object is clearly brighter than the wall (by amplitude_ratio and amplitude_slack), so
///    that amplitude can tell them apart;
///  - its amplitude lies between them: above the wall's by amplitude_slack and below spike_dim_ratio
///    times the object's (a pure return of the same object at the same range would match it; the
///    range term changes it by 2 % per 1 % of range);
///  - it is no brighter than the mixture with the share of post its range gives (as test 4).
/// Clipped or unknown amplitudes say nothing. On benchmark seeds 1-30 of setting B this found 15
/// more mixed pixels for 11 more valid returns rejected; on seeds 46-90, not looked at while it was
/// written, 34 more for 24 (see docs/mixed_pixels.md).
bool dimmer_than_its_object(const ReturnsView& v, const std::vector<std::size_t>& seq, std::size_t pos,
                            const MixedPixelParams& p, double tol, double d2, double p2) {
  const std::size_t i = seq[pos];
  if (!v.amplitude || p.spike_dim_ratio <= 0) return false;
  const double ri = v.range[i], ai = v.amplitude[i];
  if (!std::isfinite(ai) || !std::isfinite(p2) || ai >= p.amplitude_saturation || p2 >= p.amplitude_saturation)
    return false;
  double p1 = -1, d1 = 0;
  for (const long dir : {-1L, 1L}) {
    double last = ri;
    for (long step = 1; step <= kObjectReach; ++step) {
      const long q = static_cast<long>(pos) + dir * step;
      if (q < 0 || q >= static_cast<long>(seq.size()) || !v.usable[seq[static_cast<std::size_t>(q)]]) break;
      const std::size_t j = seq[static_cast<std::size_t>(q)];
      const double rq = v.range[j];
      if (std::fabs(rq - last) > jump_at(p, last) || rq > d2 - jump_at(p, rq)) break;
      last = rq;
      if (std::isfinite(v.amplitude[j]) && v.amplitude[j] > p1) {
        p1 = v.amplitude[j];
        d1 = rq;
      }
    }
  }
  if (p1 < 0 || p1 >= p.amplitude_saturation) return false;
  if (!(ri > d1 + tol && ri < d2 - tol)) return false;
  if (!(p1 > p2 * (1 + p.amplitude_ratio) + p.amplitude_slack)) return false;
  if (!(ai > p2 + p.amplitude_slack && ai < p.spike_dim_ratio * p1)) return false;
  return ai <= mixture_amplitude_at(ri, d1, p1, d2, p2) * (1 + p.amplitude_ratio) + p.amplitude_slack;  // d1 < ri < d2
}
}  // namespace

/// Spikes along a sequence: a run of 1 to spike_width returns, each nearer than both returns
/// flanking the run by more than an edge jump, and the two flanks agree with each other (one
/// surface behind it). Something a few returns wide stands in front: a thin object, or a mixture
/// of one with the surface behind. A post spans width / (range x beam spacing) returns: a 15 cm
/// post at 10 m is about one return of a 1 deg scan (one or two, as it falls against the beams),
/// and with the mixtures on its sides (a footprint of 5-8 mrad on 10-17 mrad spacing) up to three.
///
/// For each return of a spike it records the surface behind: the mean range and amplitude of the
/// two flanks (`behind_r`, `behind_a`), for the amplitude test across lines.
void mark_spikes(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                 std::vector<char>& spike, std::vector<float>& behind_r, std::vector<float>& behind_a) {
  for (std::size_t pos = 1; pos + 1 < seq.size(); ++pos) {
    const std::size_t a = seq[pos - 1];
    if (!v.usable[a]) continue;
    const double ra = v.range[a];
    double farthest = 0;  // of the run seq[pos .. pos + w - 1]
    for (std::size_t w = 1; w <= static_cast<std::size_t>(p.spike_width) && pos + w < seq.size(); ++w) {
      const std::size_t last = seq[pos + w - 1], b = seq[pos + w];
      if (!v.usable[last]) break;
      farthest = std::max(farthest, static_cast<double>(v.range[last]));
      const double jump = jump_at(p, farthest);
      if (ra <= farthest + jump) break;  // the run no longer stands in front of the left flank
      if (!v.usable[b]) break;  // it can neither flank the run nor extend it
      const double rb = v.range[b];
      if (rb > farthest + jump && std::fabs(ra - rb) <= jump_at(p, std::min(ra, rb)))
        for (std::size_t q = 0; q < w; ++q) {
          const std::size_t i = seq[pos + q];
          spike[i] = 1;
          behind_r[i] = static_cast<float>(0.5 * (ra + rb));
          behind_a[i] = v.amplitude ? 0.5f * (v.amplitude[a] + v.amplitude[b]) : NAN;
        }
    }
  }
}

/// Spikes off every surface in a sequence (the other direction): the spike has at least one
/// usable immediate neighbour, and differs from each one it has by more than the tolerance; or,
/// where it keeps their range, its amplitude says it is a mixture (dimmer_than_its_object).
void mark_spikes_off_surface(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                             double range_sigma, const std::vector<char>& spike, const std::vector<float>& behind_r,
                             const std::vector<float>& behind_a, std::vector<char>& off) {
  for (std::size_t pos = 0; pos < seq.size(); ++pos) {
    const std::size_t i = seq[pos];
    if (!spike[i]) continue;
    const double tol = tolerance_at(p, v.range[i], range_sigma);
    int seen = 0, off_it = 0;
    for (const std::size_t q : {pos - 1, pos + 1}) {  // pos - 1 wraps past the end at pos 0
      if (q >= seq.size() || !v.usable[seq[q]]) continue;
      ++seen;
      off_it += std::fabs(v.range[seq[q]] - v.range[i]) > tol;
    }
    off[i] = (seen > 0 && off_it == seen) || dimmer_than_its_object(v, seq, pos, p, tol, behind_r[i], behind_a[i]);
  }
}

}  // namespace pcdp::mixed_detail
