// Importers of Cartesian scans to the raw-pass contract: OctoMap's scan.dat (plain ASCII, with
// optional NODE lines) and .graph (binary ScanGraph), and plain Cartesian PCD / PLY clouds with a
// viewpoint. All of them end in sensor_lines_to_pass, which recovers the nodding scanner's lines.
//
// What they assume (documented in docs/real_data.md):
//  - the points of a scan are in acquisition order, in the sensor (nod) frame: x forward, y left,
//    z up, the scan plane the x-y plane at nod 0 and tilted about y (a nodding 2-D scanner);
//  - a scan line runs from one side to the other, so its in-plane bearing atan2(y, hypot(x, z))
//    increases along it; a drop of more than 0.5 rad starts a new line (an organized cloud gives
//    its rows as lines instead);
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
//  - no times are recorded: stamps are synthetic (13.3 ms lines), pipelines use
//    skew_correction: false; no intensity unless the cloud has a field `intensity` (or
//    `amplitude`, cloud.pcd's only name for it up to 0.1.0);
//  - the nod axis passes through `nod_origin` (in the scan's frame; 0 by default): a scan whose
//    origin is not on the nod axis (octomap's scan.dat: its points fit a laser 0.5 m above the
//    origin) rebuilds badly until it is set; estimate_nod_origin finds it from the data;
//  - poses: the scan's pose (NODE line, graph node, PCD VIEWPOINT or --viewpoint) times the
//    nod-origin offset is T_M_V, written constant over the scan's span; the pipeline's mount is
//    the identity.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp::io {

struct LineRecovery {
  Eigen::Vector3d nod_origin = Eigen::Vector3d::Zero();  ///< used, in the scan's frame
  double median_residual = 0.0;   ///< m, median rebuild error over the fitted lines' points
  std::size_t lines = 0;          ///< scan lines found
  std::size_t split_lines = 0;    ///< lines some of whose points did not fit
  std::size_t loose_points = 0;   ///< points that did not fit their line: imported as lines of their own
  double max_residual = 0.0;      ///< m, largest rebuild error over the fitted lines
  bool organized = false;         ///< beams on one grid: missing beams filled with no-returns
};

struct ImportedScans {
  std::vector<Pass> passes;
  std::vector<PoseSample> poses;
  std::vector<LineRecovery> recovery;  ///< one per pass
  std::vector<std::string> notes;      ///< what the import assumed (units, viewpoints), one line each, for the user
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

/// scan.dat (x y z per line; `NODE x y z roll pitch yaw` lines start a new scan with that pose,
/// R = Rz(yaw) Ry(pitch) Rx(roll)) or .graph (binary ScanGraph). Throws InputError naming the
/// file and the line or byte offset.
struct ImportOptions {
  double max_residual = 0.02;     ///< m: a point that rebuilds worse leaves its line
  bool auto_nod_origin = false;   ///< estimate the nod origin of each scan (estimate_nod_origin)
  Eigen::Vector3d nod_origin = Eigen::Vector3d::Zero();
  /// import_cloud: the sensor's maximum range, m. A viewpoint farther than this from more than half
  /// of a cloud's points is refused (ConfigError): a sensor there could not have measured them.
  double max_range = 1000.0;
  /// import_cloud: metres per file unit applied to LAS coordinates; 0: the unit the LAS file declares
  /// (GeoKeys or WKT VLR), or 1 when it declares none (said in the notes).
  double unit_scale = 0.0;
};

/// The point on the nod axis (y = 0; x and z searched) that makes the scan's lines rebuild best
/// (least mean error of every 5th line), by a shrinking pattern search from 0 over +-1 m.
Eigen::Vector3d estimate_nod_origin(const std::vector<Eigen::Vector3d>& pts);

ImportedScans import_octomap(const std::vector<std::string>& files, const ImportOptions& opt = {});

/// Cartesian PCD (any encoding), PLY (ascii, binary_little_endian) or LAS 1.2-1.4 (pcdp/io/las.hpp;
/// chosen by the "LASF" signature; .laz refused) clouds, one scan each. The sensor pose is the PCD
/// VIEWPOINT, or `viewpoint` (x, y, z; identity rotation) when given; PLY and LAS have none (0,0,0).
/// LAS coordinates are scaled to metres (opt.unit_scale), intensity becomes the amplitude.
/// Throws ConfigError when the viewpoint is implausible (see ImportOptions::max_range).
ImportedScans import_cloud(const std::vector<std::string>& files, const Eigen::Vector3d* viewpoint,
                           const ImportOptions& opt = {});

/// A PLY file's vertices: x y z and, if present, intensity (NaN otherwise). Throws InputError.
void read_ply(const std::string& path, std::vector<Eigen::Vector3d>& xyz, std::vector<float>& intensity);

}  // namespace pcdp::io
