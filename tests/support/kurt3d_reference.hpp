// References derived from the Kurt3D data itself (../shared/datasets/kurt3d_3dtk_nodding), shared
// by the unit test of the cloud path and the end-to-end test of the pipeline: no truth labels
// exist for real scans, so the tests score what the data shows (docs/mixed_pixels.md, "Real data").
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace pcdp::test {

/// A 3DTK uos scan as its file has it: x right, y up, z ahead, in metres, the scanner at the
/// origin, 226 lines x 360 beams in scan order (line l, beam b is point l * 360 + b).
struct Kurt3DScan {
  static constexpr std::size_t kLines = 226, kBeams = 360;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> range;
  std::vector<char> valid;  ///< within config.ini's limits: nearer is the robot, 32.7 m the no-return sentinel
};
/// Reads `path`; empty points if the file cannot be read.
Kurt3DScan read_kurt3d_scan(const std::string& path);

/// How many of each kind of reference return a filter removed (`removed[i]`, per scan point).
struct Kurt3DScore {
  std::size_t wall = 0, wall_removed = 0;        ///< the right corridor wall (grazing, door recesses)
  std::size_t on_line = 0, on_line_removed = 0;  ///< in a depth jump, on the line through its neighbours
  std::size_t veils = 0, veils_removed = 0;      ///< in a depth jump, off that line, far from both lines beside
  std::size_t flat = 0, flat_removed = 0;        ///< in a depth jump, off that line, the rest (ambiguous)
  std::size_t planar = 0, planar_removed = 0;    ///< the floor's and ceiling's interior
  std::size_t jumps() const { return on_line + veils + flat; }
  std::size_t jumps_removed() const { return on_line_removed + veils_removed + flat_removed; }
};
/// The wall: points right of the robot (x > 0.5 m), 3-12 m ahead, 0-1.2 m above the floor. The
/// returns inside a depth jump along their line (neighbours more than 1 m apart, the return more
/// than 0.2 m from both and between them), in three kinds: on the straight line through the two
/// neighbours within 5 cm along the beam (a plane seen at grazing incidence meets the scan's fan in
/// a straight line: mostly such planes); off it and more than 0.2 m from the
/// returns of the same beam on both neighbouring lines (a veil: its range follows the footprint's
/// share, not a surface); off it and the rest: within 0.2 m of a neighbouring line's return, or
/// beside a line with no return there (either: a veil down a vertical edge, or a wall with
/// recesses). The floor and
/// ceiling: least-squares planes through the points near y = -0.40 m and y = 2.0 m; their interior
/// is the points within 2 cm of the plane together with their four scan neighbours (a point at
/// the foot of the robot or of a wall is not interior: real veils hang there). `scored[i]`
/// false leaves point i out (a return the filter never saw).
Kurt3DScore score_kurt3d(const Kurt3DScan& s, const std::vector<char>& removed, const std::vector<char>& scored);

/// The bars every path that knows the scanner's frame must meet (gtest failures, each class first
/// asserted non-empty): the wall loses at most 10 %, the planes on the line at most 15 %, the
/// floor and ceiling at most 1 % (the false-rejection budget), and at least `min_veils` of the
/// veils go. `what` names the path in the messages.
void expect_kurt3d_bars(const Kurt3DScore& sc, double min_veils, const std::string& what);

}  // namespace pcdp::test
