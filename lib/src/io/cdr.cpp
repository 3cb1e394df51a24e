#include "cdr.hpp"

#include <cstring>

#include "pcdp/core/errors.hpp"

namespace pcdp::io::cdr {

namespace {
constexpr std::size_t kHeader = 4;     ///< encapsulation header
constexpr std::size_t kMaxTrailing = 7;///< padding allowed after the message

class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) : d_(data), n_(size) {
    if (size < kHeader)
      fail(0, std::to_string(size) + " byte(s): too short for the 4-byte CDR encapsulation header");
    if (data[0] != 0x00 || (data[1] != 0x00 && data[1] != 0x01))
      fail(0, "encapsulation header " + hex(data[0]) + " " + hex(data[1]) +
                  " is not plain CDR (00 00 big endian or 00 01 little endian)");
    little_ = data[1] == 0x01;
    pos_ = kHeader;
  }

  [[noreturn]] static void fail(std::size_t at, const std::string& rule) {
    throw InputError("byte " + std::to_string(at) + ": " + rule);
  }

  std::uint64_t raw(std::size_t bytes, const char* field) {
    // Alignment is counted from the first byte after the encapsulation header.
    const std::size_t rel = pos_ - kHeader;
    const std::size_t pad = (bytes - rel % bytes) % bytes;
    if (pad > n_ - pos_ || bytes > n_ - pos_ - pad)
      fail(pos_, std::string("truncated: ") + field + " needs " + std::to_string(pad + bytes) + " byte(s), " +
                     std::to_string(n_ - pos_) + " left");
    pos_ += pad;
    std::uint64_t v = 0;
    for (std::size_t k = 0; k < bytes; ++k) {
      const std::uint64_t b = d_[pos_ + k];
      v |= little_ ? b << (8 * k) : b << (8 * (bytes - 1 - k));
    }
    pos_ += bytes;
    return v;
  }
  std::uint32_t u32(const char* f) { return static_cast<std::uint32_t>(raw(4, f)); }
  std::int32_t i32(const char* f) { return static_cast<std::int32_t>(u32(f)); }
  float f32(const char* f) {
    const std::uint32_t u = u32(f);
    float v;
    std::memcpy(&v, &u, 4);
    return v;
  }
  double f64(const char* f) {
    const std::uint64_t u = raw(8, f);
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }

  /// A sequence count, checked against the bytes left (elements of `elem` bytes each, after
  /// alignment to `elem`).
  std::size_t count(const char* field, std::size_t elem) {
    const std::size_t at = pos_;
    const std::uint32_t c = u32(field);
    const std::size_t left = n_ - pos_;
    // At least the elements themselves (alignment padding comes on top).
    if (c > left / elem)
      fail(at, std::string(field) + ": sequence of " + std::to_string(c) + " element(s) of " + std::to_string(elem) +
                   " byte(s) is longer than the " + std::to_string(left) + " byte(s) left");
    return c;
  }

  std::string str(const char* field) {
    const std::size_t at = pos_;
    const std::uint32_t len = u32(field);
    const std::size_t left = n_ - pos_;
    if (len == 0) fail(at, std::string(field) + ": string length 0 (CDR counts the terminating NUL)");
    if (len > left)
      fail(at, std::string(field) + ": string of " + std::to_string(len) + " byte(s) is longer than the " +
                   std::to_string(left) + " byte(s) left");
    if (d_[pos_ + len - 1] != 0) fail(pos_ + len - 1, std::string(field) + ": string is not NUL-terminated");
    std::string s(reinterpret_cast<const char*>(d_ + pos_), len - 1);
    if (s.find('\0') != std::string::npos) fail(pos_, std::string(field) + ": string holds a NUL byte");
    pos_ += len;
    return s;
  }

  std::vector<float> f32_seq(const char* field) {
    const std::size_t c = count(field, 4);
    std::vector<float> v(c);
    for (auto& x : v) x = f32(field);
    return v;
  }
  std::vector<double> f64_seq(const char* field) {
    const std::size_t c = count(field, 8);
    std::vector<double> v;
    v.reserve(c);
    for (std::size_t k = 0; k < c; ++k) v.push_back(f64(field));  // padding before the first may not fit
    return v;
  }

  Header header() {
    Header h;
    h.stamp.sec = i32("header.stamp.sec");
    h.stamp.nanosec = u32("header.stamp.nanosec");
    if (h.stamp.nanosec >= 1'000'000'000u) fail(pos_ - 4, "header.stamp.nanosec " + std::to_string(h.stamp.nanosec) + " is not below 1e9");
    h.frame_id = str("header.frame_id");
    return h;
  }

  void finish(const char* type) const {
    if (n_ - pos_ > kMaxTrailing)
      fail(pos_, std::to_string(n_ - pos_) + " byte(s) after the end of the " + type +
                     " message (at most 7 of padding): is the topic's type right?");
  }

 private:
  static std::string hex(std::uint8_t b) {
    static const char* digits = "0123456789abcdef";
    return std::string{digits[b >> 4], digits[b & 15]};
  }
  const std::uint8_t* d_;
  std::size_t n_;
  std::size_t pos_ = 0;
  bool little_ = true;
};

struct NumberType {
  const char* name;
  std::size_t bytes;
  bool is_signed, is_float;
};
const NumberType kNumbers[] = {
    {"std_msgs/msg/Float32", 4, true, true}, {"std_msgs/msg/Float64", 8, true, true},
    {"std_msgs/msg/Int8", 1, true, false},   {"std_msgs/msg/Int16", 2, true, false},
    {"std_msgs/msg/Int32", 4, true, false},  {"std_msgs/msg/Int64", 8, true, false},
    {"std_msgs/msg/UInt8", 1, false, false}, {"std_msgs/msg/UInt16", 2, false, false},
    {"std_msgs/msg/UInt32", 4, false, false},{"std_msgs/msg/UInt64", 8, false, false},
    {"std_msgs/msg/Byte", 1, false, false},  {"std_msgs/msg/Char", 1, false, false},
};
const NumberType* number_type(const std::string& type) {
  for (const auto& t : kNumbers)
    if (type == t.name) return &t;
  return nullptr;
}
}  // namespace

LaserScan decode_laser_scan(const std::uint8_t* data, std::size_t size) {
  Reader r(data, size);
  LaserScan m;
  m.header = r.header();
  m.angle_min = r.f32("angle_min");
  m.angle_max = r.f32("angle_max");
  m.angle_increment = r.f32("angle_increment");
  m.time_increment = r.f32("time_increment");
  m.scan_time = r.f32("scan_time");
  m.range_min = r.f32("range_min");
  m.range_max = r.f32("range_max");
  m.ranges = r.f32_seq("ranges");
  m.intensities = r.f32_seq("intensities");
  r.finish("sensor_msgs/msg/LaserScan");
  return m;
}

JointState decode_joint_state(const std::uint8_t* data, std::size_t size) {
  Reader r(data, size);
  JointState m;
  m.header = r.header();
  // Each name takes at least 5 bytes (length and NUL).
  const std::size_t names = r.count("name", 5);
  m.name.reserve(names);
  for (std::size_t k = 0; k < names; ++k) m.name.push_back(r.str("name"));
  m.position = r.f64_seq("position");
  r.f64_seq("velocity");
  r.f64_seq("effort");
  r.finish("sensor_msgs/msg/JointState");
  return m;
}

Odometry decode_odometry(const std::uint8_t* data, std::size_t size) {
  Reader r(data, size);
  Odometry m;
  m.header = r.header();
  m.child_frame_id = r.str("child_frame_id");
  m.px = r.f64("pose.pose.position.x");
  m.py = r.f64("pose.pose.position.y");
  m.pz = r.f64("pose.pose.position.z");
  m.qx = r.f64("pose.pose.orientation.x");
  m.qy = r.f64("pose.pose.orientation.y");
  m.qz = r.f64("pose.pose.orientation.z");
  m.qw = r.f64("pose.pose.orientation.w");
  for (int k = 0; k < 36; ++k) r.f64("pose.covariance");
  for (int k = 0; k < 6; ++k) r.f64("twist.twist");
  for (int k = 0; k < 36; ++k) r.f64("twist.covariance");
  r.finish("nav_msgs/msg/Odometry");
  return m;
}

TFMessage decode_tf_message(const std::uint8_t* data, std::size_t size) {
  Reader r(data, size);
  TFMessage m;
  // Each transform takes at least 74 bytes: stamp 8, two strings of 5 (length and NUL), 7 float64.
  const std::size_t n = r.count("transforms", 74);
  m.transforms.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    TransformStamped t;
    t.header = r.header();
    t.child_frame_id = r.str("transforms.child_frame_id");
    t.tx = r.f64("transforms.transform.translation.x");
    t.ty = r.f64("transforms.transform.translation.y");
    t.tz = r.f64("transforms.transform.translation.z");
    t.qx = r.f64("transforms.transform.rotation.x");
    t.qy = r.f64("transforms.transform.rotation.y");
    t.qz = r.f64("transforms.transform.rotation.z");
    t.qw = r.f64("transforms.transform.rotation.w");
    m.transforms.push_back(std::move(t));
  }
  r.finish("tf2_msgs/msg/TFMessage");
  return m;
}

bool is_number_type(const std::string& type) { return number_type(type) != nullptr; }

double decode_number(const std::string& type, const std::uint8_t* data, std::size_t size) {
  const NumberType* t = number_type(type);
  if (!t) throw InputError("type " + type + " is not a std_msgs number");
  Reader r(data, size);
  double v = 0;
  if (t->is_float) {
    v = t->bytes == 4 ? static_cast<double>(r.f32("data")) : r.f64("data");
  } else {
    const std::uint64_t u = r.raw(t->bytes, "data");
    if (t->is_signed) {
      const unsigned shift = static_cast<unsigned>(64 - 8 * t->bytes);
      v = static_cast<double>(static_cast<std::int64_t>(u << shift) >> shift);  // sign-extend
    } else {
      v = static_cast<double>(u);
    }
  }
  r.finish(t->name);
  return v;
}

}  // namespace pcdp::io::cdr
