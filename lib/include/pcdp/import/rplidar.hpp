// Importer of servo-nodded 2-D LaserScan records exported to CSV (e.g.
// ../shared/datasets/rplidar_tilt_turboslam/csv/<bag>/: an RPLIDAR C1 tilted by a servo) to the
// raw-pass contract.
//
// What it assumes (the data set's SOURCE.md, from the node that recorded it):
//  - scans.csv has one row per LaserScan (scan_idx, bag_t_ns, angle_min, angle_increment,
//    scan_time, n_ranges, ...), beams.csv one row per beam (scan_idx, beam_idx, angle_rad, range_m,
//    intensity) in scan order, servo.csv the servo angle stream (bag_t_ns, servo_deg);
//  - time: bag receive time. A scan arrives at its bag time after sweeping for scan_time, so beam b
//    of n was measured at t_arrival - scan_time + (b + 0.5) / n * scan_time; the servo angle is
//    interpolated linearly at that time (the recording node used the last angle for the whole scan,
//    a skew of up to one servo period that we do not reproduce). Scans with beams outside the servo
//    stream are dropped and counted;
//  - geometry (TiltGeometry's defaults, all options): laser_frame = servo_frame + (0, 0, 0.04 m),
//    servo_frame = base_link rotated about y by pitch = -(servo_deg - 90) deg, so the nod angle
//    (positive up) is servo_deg - 90 deg. Our
//    contract reads the encoder once per line, at its end: every return of a scan gets the servo
//    angle interpolated at the scan's last beam, and `register` with skew_correction interpolates
//    between line ends (the servo turns about 1.5 deg during one 0.1 s scan). The laser sits 4 cm
//    above the axis and turns with it, which the nod model (laser on the axis) cannot hold; the
//    pipeline puts the 4 cm into the mount (exact at nod 0, off by 4 cm x (sin nod, 0, 1 - cos nod),
//    2.0 cm / 0.5 cm at the 30 deg extremes, under the sensor's own 3 cm);
//  - range 0 is no return; intensity is the RPLIDAR quality (0-63) and becomes the amplitude;
//  - no platform pose is recorded: the vehicle frame is base_link and no pose file is written
//    (pipelines leave input.poses empty: T_M_V = identity);
//  - passes: a new pass starts where the servo reverses (one pass per half nod, at least
//    `min_pass_lines` scans).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"

namespace pcdp::io {

/// How a tilt reading (servo angle, joint position, ...) becomes the nod angle, shared by
/// `import rplidar` and `import rosbag2`. The defaults are TurboSLAM's rig (SOURCE.md): a servo
/// reading in degrees, 90 = level, ROS pitch about y = -(servo - 90) deg.
struct TiltGeometry {
  double zero = 90.0;         ///< the reading at which the scan plane is level
  double sign = -1.0;         ///< +1 or -1: ROS pitch about y (REP 103: positive tips the laser's x axis down)
                              ///< = sign * scale * (reading - zero)
  double scale = 1.0;         ///< degrees per unit of the reading
  double axis_offset = 0.04;  ///< m, the laser above the tilt axis (goes into the pipeline's mount z)

  /// The nod angle of the data contract (rad, positive above the horizon) = -pitch.
  double nod_rad(double reading) const;
  /// Throws ConfigError naming `what` (e.g. "import rplidar") unless sign is +-1, scale is finite
  /// and non-zero, zero finite and axis_offset within +-10 m.
  void check(const std::string& what) const;
};

/// One LaserScan for the pass builder: its bag (arrival) time, its sweep duration and its beams in
/// scan order (beam k has index k).
struct TiltScan {
  long long t_ns = 0;             ///< arrival time (bag receive time), ns
  double scan_time = 0;           ///< s, duration of the sweep (> 0)
  std::uint32_t line = 0;         ///< the scan's number (becomes the `line` field)
  std::vector<double> angle;      ///< rad, any range (wrapped to (-pi, pi])
  std::vector<float> range;       ///< m, 0 = no return
  std::vector<float> intensity;   ///< one per beam
};

/// Bag times beyond this (year 2096) are refused: the time arithmetic stays far from overflow.
inline constexpr long long kMaxBagTimeNs = 4'000'000'000'000'000'000LL;

/// One tilt reading at its bag time (time order, non-decreasing).
struct TiltSample {
  long long t_ns = 0;
  double reading = 0;
};

struct RplidarImportParams {
  std::size_t min_pass_lines = 5;
  TiltGeometry geometry;
};

struct ImportedRplidar {
  std::vector<Pass> passes;
  std::size_t scans = 0;           ///< scans read
  std::size_t dropped_scans = 0;   ///< empty, or outside the servo stream
  std::size_t beams = 0;           ///< beams written
  long long t0_ns = 0;             ///< bag time of stamp 0 (10 s before the first scan)
};

/// The pass building both importers share: beam times (the sweep ends at the arrival time and
/// starts no earlier than the previous sweep's end), the tilt reading interpolated linearly at each
/// beam's time (scans with a beam outside the tilt stream are dropped), one nod per line (the
/// reading at the line's last beam, through `p.geometry`), a new pass where the tilt reverses (at
/// least p.min_pass_lines lines). `scans` in arrival order; `tilt` has at least two samples; all
/// times within 0 .. kMaxBagTimeNs.
/// `source` names the input in the error thrown when no scan lies within the tilt stream.
ImportedRplidar build_tilt_passes(const std::vector<TiltScan>& scans, const std::vector<TiltSample>& tilt,
                                  const RplidarImportParams& p, const std::string& source);

/// `dir` holds scans.csv, beams.csv and servo.csv. Throws InputError naming the file, line and rule.
ImportedRplidar import_rplidar(const std::string& dir, const RplidarImportParams& p = {});

}  // namespace pcdp::io
