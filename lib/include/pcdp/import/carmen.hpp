// Importer of CARMEN logs (e.g. ../shared/datasets/carmen_corrected_radish: a 2-D SICK on a robot,
// with the poses a SLAM run corrected) to the raw-pass contract.
//
// What it assumes (CARMEN's logger format, as its own readers parse it):
//  - a text log, gzip-compressed or plain (both read through zlib), one message per line, fields
//    separated by spaces; lines whose first word is not FLASER or ROBOTLASER1 (PARAM, ODOM, NEFF,
//    SYNC, RAWLASER..., comments) are skipped;
//  - `FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp`:
//    n readings over 180 degrees starting at -90 degrees (to the right), one step apart:
//    180/n degrees for an even n (the scanner's last beam is not logged: 360 readings are 0.5
//    degree steps), 180/(n - 1) for an odd n (both ends logged); the laser pose is x y theta
//    (map frame, m and rad, theta counter-clockwise from +x); the sensor's maximum range is the
//    log's `PARAM robot_front_laser_max` when present, else 80 m (the SICK LMS maximum that
//    CARMEN's own FLASER reader assumes);
//  - `ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n
//    m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety
//    side_safety turn_axis timestamp host logger_timestamp`: the angles from the message, the
//    remissions (m = 0 or m = n) as amplitude; the laser pose is laser_x laser_y laser_theta;
//  - a log with ROBOTLASER1 messages is read from them alone (CARMEN logs the same scan as both);
//  - a reading at or beyond the maximum range (the SICK's 81.91 m sentinel) or of 0 is no return
//    (range 0 in the pass);
//  - each message is one pass of one scan line (nod 0): a planar scanner has no neighbouring line,
//    so the filters judge along the line only; beam = reading index, line = the message's index
//    in time order, every return stamped with the message's timestamp (one pose per scan);
//  - messages are ordered by timestamp (a SLAM-corrected log can hold a few out of order); two
//    messages with the same timestamp are an error;
//  - poses: the laser pose is T_M_V (z = 0, roll = pitch = 0, yaw = theta), written constant at
//    the message's stamp +- 1 ms (less where two messages are closer), so register's
//    max_pose_gap never falls between a scan and its own pose; the pipeline's mount is the
//    identity and skew correction has nothing to correct (nod 0).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp::io {

struct ImportedCarmen {
  std::vector<Pass> passes;
  std::vector<PoseSample> poses;
  std::string message;               ///< "FLASER" or "ROBOTLASER1": the messages imported
  std::size_t skipped_flaser = 0;    ///< FLASER messages skipped because the log has ROBOTLASER1
  std::size_t reordered = 0;         ///< messages whose timestamp was earlier than the one before
  std::size_t max_range_readings = 0;///< readings at or beyond the maximum range (no return)
  double max_range = 0.0;            ///< m, FLASER's maximum range (PARAM or 80 m)
};

/// Reads a CARMEN log (.log or .log.gz). Throws InputError naming the file, the line number and
/// the field for a malformed FLASER / ROBOTLASER1 line, and when the log holds no laser message.
ImportedCarmen import_carmen(const std::string& path);

}  // namespace pcdp::io
