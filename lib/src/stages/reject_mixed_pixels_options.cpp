// The options of stage `reject_mixed_pixels`, declared once (name, member, bounds, unit, doc):
// the schema behind validation, `describe` and docs/stages.md. The algorithm is in
// reject_mixed_pixels.cpp.
#include "pcdp/stages/reject_mixed_pixels.hpp"

namespace pcdp {

const Options<MixedPixelParams>& reject_mixed_pixels_options() {
  using P = MixedPixelParams;
  static const auto o = Options<P>()
      .add("window", &P::window, bounds(1, 100), "returns", "how far to search on each side for neighbours")
      .add("jump_min", &P::jump_min, bounds(0, 100), "m", "smallest range step between the two sides that makes an edge")
      .add("jump_ratio", &P::jump_ratio, bounds(0, 10), "", "... or this fraction of the near range, if larger")
      .add("range_tolerance", &P::range_tolerance, bounds(0, 10), "m", "a return within this (+ ratio * r + 3 range_sigma) of a surface is on it")
      .add("range_tolerance_ratio", &P::range_tolerance_ratio, bounds(0, 1), "", "relative part of the tolerance")
      .add("edge_factor", &P::edge_factor, bounds(0.1, 100), "", "a strong edge: the range changes this many times faster across the return than within each side")
      .add("weak_edge_factor", &P::weak_edge_factor, bounds(0.1, 100), "", "a weak edge (flagged only where the return is not smooth in the other direction)")
      .add("max_angle", &P::max_angle, bounds(0, 1.5708), "rad", "largest angle between the beam and the segment to a neighbour")
      .add("amplitude_ratio", &P::amplitude_ratio, bounds(0, 10), "", "a mixture may be this much brighter than predicted (relative)")
      .add("amplitude_slack", &P::amplitude_slack, bounds(0, 255), "", "... plus this (amplitude units)")
      .add("across_lines", &P::across_lines, "also look across scan lines (same beam)")
      .add("max_span", &P::max_span, bounds(2, 100), "returns", "the two sides' nearest neighbours may be at most this many steps apart")
      .add("amplitude_saturation", &P::amplitude_saturation, bounds(0, 1e9), "", "amplitudes at or above this are clipped: the mixing test is skipped")
      .add("one_sided", &P::one_sided, "beside a void, flag returns that break from the trend of their one visible surface by more than the tolerance")
      .add("spikes", &P::spikes, "flag a run of returns a few beams wide in front of the surface on both sides along its line whose range changes across lines (a mixture with a thin object)")
      .add("spike_width", &P::spike_width, bounds(1, 16), "returns", "widest run along a line the spike test takes for a thin object (or a mixture with one)")
      .add("spike_dim_ratio", &P::spike_dim_ratio, bounds(0, 1), "", "a spike that keeps its range across lines is still a mixture if dimmer than this times its object's brightest return there, and brighter than the surface behind (0: off)")
      .rule("weak_edge_factor <= edge_factor", [](const P& p) { return p.weak_edge_factor <= p.edge_factor; },
            "a weak edge is a lower bar than a strong one",
            "option 'weak_edge_factor' = {weak_edge_factor} must not exceed 'edge_factor' = {edge_factor}");
  return o;
}

const OptionSchema& reject_mixed_pixels_schema() { return reject_mixed_pixels_options().schema(); }

}  // namespace pcdp
