// Scan-line recovery: the points of one scan of a nodding 2-D scanner, given in the sensor (nod)
// frame without their line structure, back to the raw-pass contract (docs/data_contract.md): scan
// lines, beams, ranges, bearings and nods. The Cartesian importers (pcdp/import/scans.hpp) use it.
//
// What it assumes (documented in docs/real_data.md):
//  - the points are in the sensor (nod) frame: x forward, y left, z up, the scan plane the x-y
//    plane at nod 0 and tilted about y;
//  - a scan line runs from one side to the other, so its in-plane bearing atan2(y, hypot(x, z))
//    increases along it; a drop of more than 0.5 rad starts a new line (split_lines);
//  - a line's nod is the median of atan2(z, x) over its points more than 17 degrees from the
//    scan's ends (at +-90 degrees the nod is undefined); a point's bearing is its angle within
//    that plane (over the full circle: a SICK sees a little past +-90 degrees). The point is then
//    rebuilt from range, bearing and nod. A point that does not come back within max_residual (the
//    scanner was not a nodding one, its laser sits off the nod axis, the line split wrongly)
//    leaves its line and becomes a line of its own, rebuilt exactly but without scan-line
//    neighbours; the counts are reported, so no point moves by more than max_residual;
//  - beams: when the bearings of all lines fall on one grid (the median step), a point's beam is
//    its grid index and missing beams are no-returns (range 0), so the pass is organized and the
//    filters see neighbours across lines too; otherwise beams count along the line;
//  - no times are recorded: stamps are synthetic (kScanLinePeriod a line), pipelines use
//    skew_correction: false.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"

namespace pcdp {

/// The synthetic time of one scan line, s (13.3 ms) for scans that record no times.
inline constexpr double kScanLinePeriod = 0.0133;

struct LineRecovery {
  Eigen::Vector3d nod_origin = Eigen::Vector3d::Zero();  ///< used, in the scan's frame
  double median_residual = 0.0;   ///< m, median rebuild error over the fitted lines' points
  std::size_t lines = 0;          ///< scan lines found
  std::size_t split_lines = 0;    ///< lines some of whose points did not fit
  std::size_t loose_points = 0;   ///< points that did not fit their line: imported as lines of their own
  double max_residual = 0.0;      ///< m, largest rebuild error over the fitted lines
  bool organized = false;         ///< beams on one grid: missing beams filled with no-returns
};

/// Points of one scan in the sensor frame, split into lines (see above), to a raw pass. Scan k
/// starts at stamp 1e5 k s and its lines are numbered from 1e6 k. `intensity`: empty or one per point, same nesting as `lines`.
/// `rows`: the lines are the rows of an organized cloud (beam = column; non-finite points are
/// no-returns) instead of lines split from acquisition order.
Pass sensor_lines_to_pass(const std::vector<std::vector<Eigen::Vector3d>>& lines,
                          const std::vector<std::vector<float>>& intensity, std::size_t k, const std::string& source,
                          double max_residual, bool rows, LineRecovery& rec);

/// Splits points in acquisition order into scan lines where the bearing drops by more than 0.5 rad.
std::vector<std::vector<Eigen::Vector3d>> split_lines(const std::vector<Eigen::Vector3d>& pts,
                                                      std::vector<std::size_t>* starts = nullptr);

/// The point on the nod axis (y = 0; x and z searched) that makes the scan's lines rebuild best
/// (least mean error of every 5th line), by a shrinking pattern search from 0 over +-1 m.
Eigen::Vector3d estimate_nod_origin(const std::vector<Eigen::Vector3d>& pts);

}  // namespace pcdp
