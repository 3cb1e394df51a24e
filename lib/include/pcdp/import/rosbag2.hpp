// Importer of ROS 2 bags (storage sqlite3: `*.db3` + metadata.yaml, serialization CDR) of a 2-D
// scanner on a tilt axis, to the raw-pass contract: sensor_msgs/msg/LaserScan plus a tilt topic
// (a std_msgs number, or one joint of a sensor_msgs/msg/JointState), optionally poses from
// nav_msgs/msg/Odometry or tf (tf2_msgs/msg/TFMessage) as the pose file.
//
// What it assumes:
//  - the bag: a folder with metadata.yaml (storage_identifier sqlite3, no compression; its
//    relative_file_paths name the .db3 files) or, without metadata.yaml, every *.db3 in the folder;
//    a single .db3 file may be given instead. Topics and types come from each file's `topics`
//    table, messages from `messages` (timestamp = bag receive time, ns), in time order;
//  - time: the bag receive time, as for `import rplidar` (header stamps may be on another clock);
//    the tilt stream is associated with the scans by build_tilt_passes (import_rplidar.hpp):
//    linear interpolation at each beam's time, one nod per line, passes split where the tilt
//    reverses;
//  - geometry: TiltGeometry (zero, sign, scale, axis offset; the defaults are the RPLIDAR rig's).
//    A JointState position is in radians (REP 103) and is converted to degrees before the
//    geometry, so a joint that is level at 0 needs zero = 0;
//  - beams: angle = angle_min + k * angle_increment (computed in double from the float32 fields);
//    range 0 or a non-finite range is no return (written as 0); a scan without intensities gets
//    amplitude 0 on every beam;
//  - poses (poses.csv, T_M_V on the passes' time axis, at bag times) from nav_msgs/msg/Odometry
//    (the message's pose) or from tf (tf2_msgs/msg/TFMessage on /tf and /tf_static): the transform
//    PARENT:CHILD, directly or composed along the tf tree from PARENT down to CHILD (each /tf link
//    interpolated at the times of the others, /tf_static links constant). Frame names lose a
//    leading '/'. The choice: --odom-topic or --tf-frames when given (not both); else the only
//    Odometry topic, or the only PARENT:CHILD pair on /tf; a bag with both (or several pairs)
//    needs the option; with neither, no poses.
#pragma once

#include <string>
#include <vector>

#include "pcdp/import/rplidar.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp::io {

struct Rosbag2ImportParams {
  std::string scan_topic;   ///< empty: the bag's only sensor_msgs/msg/LaserScan topic
  /// empty: the bag's only std_msgs number or JointState topic. A JointState topic may name its
  /// joint as TOPIC:JOINT (needed when the messages carry more than one joint).
  std::string tilt_topic;
  std::string odom_topic;   ///< empty: the only nav_msgs/msg/Odometry topic if there is one, else none
  /// PARENT:CHILD, the tf transform that becomes T_M_V (e.g. odom:base_link, map:base_link);
  /// empty: the only pair on /tf when the bag has no Odometry topic.
  std::string tf_frames;
  RplidarImportParams passes;  ///< tilt geometry and pass splitting, shared with import rplidar
};

struct ImportedRosbag2 {
  ImportedRplidar passes;   ///< passes and counts
  std::string scan_topic, tilt_topic, odom_topic;  ///< the topics used (odom_topic empty: none)
  std::string tf_frames;    ///< PARENT:CHILD of the poses from tf (empty: not from tf)
  std::string tf_chain;     ///< its links, e.g. "map:odom (/tf), odom:base_link (/tf)"
  std::string tilt_type;    ///< the tilt topic's message type
  std::size_t tilt_messages = 0;
  std::vector<PoseSample> poses;  ///< from odometry or tf; empty when there is none
};

/// Reads the bag at `path` (folder or .db3). Throws InputError naming the bag file, the topic,
/// the message (index on its topic and bag time) and the rule; ConfigError for a topic option
/// that names nothing usable.
ImportedRosbag2 import_rosbag2(const std::string& path, const Rosbag2ImportParams& p = {});

}  // namespace pcdp::io
