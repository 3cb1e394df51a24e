// A small, strict decoder of the ROS 2 messages `import rosbag2` reads, serialized as plain CDR
// (OMG CDR / XCDR1, what rmw_fastrtps and rmw_cyclonedds write to a bag):
//  - a 4-byte encapsulation header: 0x00 0x00 (big endian) or 0x00 0x01 (little endian), then two
//    option bytes (ignored);
//  - every primitive aligned to its own size (8 for float64/int64), counted from the first byte
//    after the header; the padding is skipped, not checked;
//  - a string is a uint32 length that counts a terminating NUL, then the bytes (the last one NUL);
//  - a sequence is a uint32 element count, then the elements; the count is checked against the
//    bytes left before anything is allocated;
//  - after the message at most 7 bytes may remain (padding); more means the message is not of the
//    type the topic names.
// Every read is bounds-checked. A violation throws InputError("byte N: <rule>"), N counted from
// the start of the serialized message (header included); the caller adds the bag, topic and message.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace pcdp::io::cdr {

struct Time {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
};

struct Header {
  Time stamp;
  std::string frame_id;
};

/// sensor_msgs/msg/LaserScan.
struct LaserScan {
  Header header;
  float angle_min = 0, angle_max = 0, angle_increment = 0, time_increment = 0, scan_time = 0, range_min = 0,
        range_max = 0;
  std::vector<float> ranges, intensities;
};

/// sensor_msgs/msg/JointState (velocity and effort are checked and skipped).
struct JointState {
  Header header;
  std::vector<std::string> name;
  std::vector<double> position;
};

/// nav_msgs/msg/Odometry: the pose of child_frame_id in header.frame_id (covariances and twist
/// are checked and skipped).
struct Odometry {
  Header header;
  std::string child_frame_id;
  double px = 0, py = 0, pz = 0;          ///< position, m
  double qx = 0, qy = 0, qz = 0, qw = 1;  ///< orientation quaternion
};

/// geometry_msgs/msg/TransformStamped: the pose of child_frame_id in header.frame_id.
struct TransformStamped {
  Header header;
  std::string child_frame_id;
  double tx = 0, ty = 0, tz = 0;          ///< transform.translation, m
  double qx = 0, qy = 0, qz = 0, qw = 1;  ///< transform.rotation quaternion
};

/// tf2_msgs/msg/TFMessage (the type of /tf and /tf_static).
struct TFMessage {
  std::vector<TransformStamped> transforms;
};

LaserScan decode_laser_scan(const std::uint8_t* data, std::size_t size);
JointState decode_joint_state(const std::uint8_t* data, std::size_t size);
Odometry decode_odometry(const std::uint8_t* data, std::size_t size);
TFMessage decode_tf_message(const std::uint8_t* data, std::size_t size);

/// True for the std_msgs/msg number types: Float32, Float64, Int8/16/32/64, UInt8/16/32/64 (and
/// Byte, Char): one field `data`.
bool is_number_type(const std::string& type);
/// The `data` of a std_msgs number message of `type` (is_number_type) as a double.
double decode_number(const std::string& type, const std::uint8_t* data, std::size_t size);

}  // namespace pcdp::io::cdr
