// Stage `reject_occlusion`: false ranges of non-coaxial scanners at range edges
// (Liu, Adams & Wijesoma 2005), and returns below the detectable amplitude elsewhere.
//
// A return is a *suspect* when its reported amplitude is below min_amplitude + amplitude_margin
// (reported amplitudes are noisy; the margin keeps the decision from hinging on noise). For each
// suspect, along its scan line (by bearing) and across lines (same beam, by nod), the nearest
// stable returns on each side give d1, P1 (near) and d2, P2 (far). Where they form a range edge,
// the amplitude model (occlusion_model.hpp) predicts the dip for the sensor's geometry: the
// receiver offset (s - q) projected on the direction from the edge to the near side, using the
// transceiver angle (fixed: theta = offset; mirror: theta = bearing + offset; cos(theta) along the
// line, sin(theta) across lines). Then:
//  - dip predicted below min_amplitude, and the suspect's amplitude is surely below the
//    threshold (< min - margin) or its range fits no side: `occlusion` (or, with `repair`,
//    its range is replaced by the nearer stable neighbour's and it is flagged repaired);
//  - otherwise, amplitude surely below the threshold, or a suspect whose range fits fewer sides
//    than it needs (below): `low_amplitude`;
//  - otherwise kept (a valid return whose amplitude noise put it near the threshold).
// "Fits" means within range_tolerance + range_tolerance_ratio * range of the nearest or second
// nearest neighbour on a side, or of their linear extrapolation; the sides are left and right along
// the line and before and after across lines. Neighbours are the kept returns not surely below the
// threshold (a weak surface has weak neighbours). A suspect reported at or above min_amplitude, or
// at a predicted dip, needs one side that fits (at an edge a valid return lies on one surface); one
// reported below it, more likely false than not, needs two where two sides have neighbours: a
// false range is arbitrary and fits any one side by chance only (about 2 * tolerance /
// (range_max - range_min) per value, a few per cent), two with about that chance squared. The edge
// model uses only stable neighbours, whose amplitudes stand for P1 and P2.
#pragma once

#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

struct Pass;

struct OcclusionParams {
  int window = 6;                 ///< returns searched on each side for stable neighbours
  int stable = 2;                 ///< stable neighbours used per side
  double amplitude_margin = 6.0;  ///< amplitude units (about 3 sigma of the amplitude noise)
  double jump_min = 0.15;         ///< m, smallest range step that makes an edge
  double jump_ratio = 0.05;       ///< ... or this fraction of the near range, if larger
  double range_tolerance = 0.05;  ///< m
  double range_tolerance_ratio = 0.01;
  bool across_lines = true;
  bool repair = false;
  bool low_amplitude = true;      ///< label low_amplitude away from edges
};

/// The options of `reject_occlusion`, bound to OcclusionParams (its schema drives validation,
/// describe and docs).
const Options<OcclusionParams>& reject_occlusion_options();
const OptionSchema& reject_occlusion_schema();

struct OcclusionCounts {
  std::uint64_t suspects = 0, occlusion = 0, low_amplitude = 0, repaired = 0, dipping_edges = 0;
};

/// Pure function over a registered pass.
OcclusionCounts reject_occlusion(Pass& pass, const OcclusionParams& params, const SensorParams& sensor);

StageInfo reject_occlusion_stage_info();

}  // namespace pcdp
