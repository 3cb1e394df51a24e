// Importer of 3DTK `uos` scans (e.g. ../shared/datasets/kurt3d_3dtk_nodding: a nodding SICK on
// Kurt3D) to the raw-pass contract.
//
// What it assumes (from the data set's SOURCE.md and 3DTK's documentation):
//  - a .3d file is x y z in centimetres, one point per line, optionally after a "W x H" line, in
//    acquisition order, line after line; the frame is left-handed with y up and z forward
//    (x right);
//  - the beams per scan line are read from the geometry (beams_per_line_from_geometry): along a
//    line the in-plane bearing moves by one beam step, and a new line starts where it jumps back
//    by more than half the bearing span the scan covers. Every line must have the same count, the
//    point count must be a whole number of lines, and a "W x H" header, when present, must agree
//    on W; otherwise the import fails and asks for an explicit count (--beams-per-line). Ours is right-handed, x forward, y left, z up: p = C p_uos / 100 with
//    C = [[0,0,1],[-1,0,0],[0,1,0]] (a reflection, det -1), and rotations R = C R_uos C^T;
//  - the sentinel range 3276.7 cm means no return (range 0 here); near-field returns are kept
//    (the pipeline's range_min decides);
//  - the points are already projected with one tilt per line: the nod of a line is the median
//    elevation of its returns, bearings come from each point; no stamps are recorded, so the
//    importer writes synthetic ones (13.3 ms lines) and pipelines use `skew_correction: false`;
//  - no intensity: amplitude is NaN (not measured);
//  - poses: `odometry` reads scanNNN.pose (x y z cm, then theta x y z in degrees;
//    R = Rx Ry Rz, p_world = R p + t), `frames` the last 4x4 matrix (column-major) of
//    scanNNN.frames (slam6D's registered pose). Scan k starts at stamp 100 k s; its pose is
//    written, constant, every 0.25 s over its span.
#pragma once

#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp::io {

struct Imported3dtk {
  std::vector<Pass> passes;
  std::vector<PoseSample> poses;
};

/// Throws InputError naming the file and line. `beams_per_line`: 0 reads it from each scan's
/// geometry; otherwise every scan must be a whole number of lines of that many beams.
Imported3dtk import_3dtk(const std::vector<std::string>& scans, bool use_frames, std::size_t beams_per_line = 0);

/// The beams per scan line of points in acquisition order (uos frame, cm), from the geometry: the
/// in-plane bearing of consecutive points (points at the origin have none and are skipped) jumps
/// by more than half the scan's bearing span exactly where a new line starts, and every line has
/// the same count. Returns the point count for a single line. Throws InputError naming `file`
/// when the jumps do not fall on one line length.
std::size_t beams_per_line_from_geometry(const std::vector<Eigen::Vector3d>& pts_cm, const std::string& file);

/// The uos pose of a scan (odometry or frames) as T in our frame.
Eigen::Isometry3d read_3dtk_pose(const std::string& scan, bool use_frames);

/// Converts a point in the uos frame (cm) to ours (m).
Eigen::Vector3d uos_to_ours(const Eigen::Vector3d& p_cm);

}  // namespace pcdp::io
