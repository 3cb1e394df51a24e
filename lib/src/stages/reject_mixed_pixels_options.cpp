// The options of stage `reject_mixed_pixels`, declared once (name, member, bounds, unit, doc):
// the schema behind validation, `describe` and docs/stages.md. The algorithm is in
// reject_mixed_pixels.cpp. The search window, the widest spike and the tests' dimensionless thresholds
// (MixedPixelParams: edge factors, relative tolerance, angle, span, spike dimness) are fixed in the
// library, not pipeline options: no sensor property sets them, and retuning them one by one did not
// generalize (docs/mixed_pixels.md, Limits).
#include <string>

#include "pcdp/stages/reject_mixed_pixels.hpp"

namespace pcdp {

const Options<MixedPixelParams>& reject_mixed_pixels_options() {
  using P = MixedPixelParams;
  // Every retired threshold's message ends alike: what to do instead, and where the reason is measured.
  const std::string kTail = "; remove the key, or set MixedPixelParams from the library; docs/mixed_pixels.md)",
                    kFixed = "the threshold is fixed at ", kWhy = " (no sensor property sets it" + kTail;
  static const auto o = Options<P>()
      .add("jump_min", &P::jump_min, bounds(0, 100), "m", "smallest range step between the two sides that makes an edge")
      .add("jump_ratio", &P::jump_ratio, bounds(0, 10), "", "... or this fraction of the near range, if larger")
      .add("range_tolerance", &P::range_tolerance, bounds(0, 10), "m", "a return within this (+ 0.2 % of its range + 3 range_sigma) of a surface is on it")
      .add("amplitude_ratio", &P::amplitude_ratio, bounds(0, 10), "", "a mixture may be this much brighter than predicted (relative)")
      .add("amplitude_slack", &P::amplitude_slack, at_least(0), "", "... plus this (sensor amplitude units, as sensor.min_amplitude)")
      .add("across_lines", &P::across_lines, "also look across scan lines (same beam)")
      .add("one_sided", &P::one_sided, "beside a void, flag returns that break from the trend of their one visible surface by more than the tolerance")
      .add("spikes", &P::spikes, "flag a run of one to three returns in front of the surface on both sides along its line whose range changes across lines (a mixture with a thin object)")
      .retire("window", "the search is fixed at 8 returns on each side (enough to reach a side's three nearest usable "
                        "returns past dropouts; past a footprint, 8 past the returns read past" + kTail)
      .retire("spike_width", "the widest spike is fixed at 3 returns along a line (a thin object one or two returns "
                             "wide and the mixtures on its sides" + kTail)
      .retire("edge_factor", kFixed + "1.5" + kWhy)
      .retire("weak_edge_factor", kFixed + "0.8" + kWhy)
      .retire("range_tolerance_ratio", kFixed + "0.002" + kWhy)
      .retire("max_angle", kFixed + "0.9 rad" + kWhy)
      .retire("max_span", kFixed + "6 returns" + kWhy)
      .retire("spike_dim_ratio", kFixed + "0.9" + kWhy)
      .retire("amplitude_saturation", "the clipping level is a property of the sensor: set sensor.amplitude_saturation");
  return o;
}

const OptionSchema& reject_mixed_pixels_schema() { return reject_mixed_pixels_options().schema(); }

}  // namespace pcdp
