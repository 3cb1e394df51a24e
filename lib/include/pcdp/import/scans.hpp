// Importers of Cartesian scans to the raw-pass contract: OctoMap's scan.dat (plain ASCII, with
// optional NODE lines) and .graph (binary ScanGraph), and plain Cartesian PCD / PLY / LAS clouds
// with a viewpoint. All of them end in sensor_lines_to_pass (pcdp/models/line_recovery.hpp), which
// recovers the nodding scanner's lines; what it assumes is said there and in docs/real_data.md.
//
// What the importers add:
//  - the points of a scan are in acquisition order, in the sensor (nod) frame (x forward, y left,
//    z up); an organized cloud gives its rows as lines;
//  - no intensity unless the cloud has a field `intensity` (or `amplitude`, cloud.pcd's only name
//    for it up to 0.1.0);
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
#include "pcdp/models/line_recovery.hpp"

namespace pcdp::io {

struct ImportedScans {
  std::vector<Pass> passes;
  std::vector<PoseSample> poses;
  std::vector<LineRecovery> recovery;  ///< one per pass
  std::vector<std::string> notes;      ///< what the import assumed (units, viewpoints), one line each, for the user
};

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

ImportedScans import_octomap(const std::vector<std::string>& files, const ImportOptions& opt = {});

/// Cartesian PCD (any encoding), PLY (ascii, binary_little_endian) or LAS 1.2-1.4 (pcdp/io/las.hpp;
/// chosen by the "LASF" signature; .laz refused) clouds, one scan each. The sensor pose is the PCD
/// VIEWPOINT (a rotation of all zeros is an InputError), or `viewpoint` (x, y, z; identity rotation)
/// when given; PLY and LAS have none (0,0,0).
/// LAS coordinates are scaled to metres (opt.unit_scale), intensity becomes the amplitude.
/// Throws ConfigError when the viewpoint is implausible (see ImportOptions::max_range).
ImportedScans import_cloud(const std::vector<std::string>& files, const Eigen::Vector3d* viewpoint,
                           const ImportOptions& opt = {});

/// A PLY file's vertices: x y z and, if present, intensity (NaN otherwise). Throws InputError.
void read_ply(const std::string& path, std::vector<Eigen::Vector3d>& xyz, std::vector<float>& intensity);

}  // namespace pcdp::io
