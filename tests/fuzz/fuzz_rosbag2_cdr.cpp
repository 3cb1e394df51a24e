// The CDR message decoders of `import rosbag2` (lib/src/io/cdr.hpp) on arbitrary bytes: the first
// byte picks the message type, the rest is the serialized message (header included). A bad message
// must end in InputError, never in a crash, a hang or an allocation beyond the input's size.
#include <cstdint>
#include <string>

#include "io/cdr.hpp"
#include "pcdp/core/errors.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kNumbers[] = {"std_msgs/msg/Float32", "std_msgs/msg/Float64", "std_msgs/msg/Int8",
                                         "std_msgs/msg/Int16",   "std_msgs/msg/Int32",   "std_msgs/msg/Int64",
                                         "std_msgs/msg/UInt16",  "std_msgs/msg/UInt64"};
  const std::uint8_t pick = data[0];
  const std::uint8_t* msg = data + 1;
  const std::size_t n = size - 1;
  try {
    switch (pick % 5) {
      case 0: {
        const auto m = pcdp::io::cdr::decode_laser_scan(msg, n);
        if (m.ranges.size() * 4 > n || m.intensities.size() * 4 > n) __builtin_trap();
        break;
      }
      case 1: {
        const auto m = pcdp::io::cdr::decode_joint_state(msg, n);
        if (m.name.size() * 5 > n || m.position.size() * 8 > n) __builtin_trap();
        break;
      }
      case 2:
        pcdp::io::cdr::decode_odometry(msg, n);
        break;
      case 3: {
        const auto m = pcdp::io::cdr::decode_tf_message(msg, n);
        if (m.transforms.size() * 74 > n) __builtin_trap();
        break;
      }
      default:
        pcdp::io::cdr::decode_number(kNumbers[(pick / 5) % 8], msg, n);
        break;
    }
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
