// The strict CDR decoder of `import rosbag2` (lib/src/io/cdr.hpp): messages written here by a
// small CDR writer in both byte orders, alignment counted from after the encapsulation header,
// every truncation refused, sequence lengths checked before allocating, trailing bytes refused.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/cdr.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/import/rplidar.hpp"
#include "pcdp_test_paths.hpp"
#include "rosbag2_test_bag.hpp"

using namespace pcdp;
using namespace pcdp::io;

namespace {
/// The CDR writer of the tests' bags, with non-zero padding (a reader must not check it) and a
/// header stamp of its own.
struct W : test::rosbag2::W {
  explicit W(bool little) : test::rosbag2::W(little, 0xAA) {}
  void header(const std::string& frame) { test::rosbag2::W::header(frame, 634, 27000000); }
};

std::vector<std::uint8_t> laser_scan(bool le, const std::vector<float>& ranges, const std::vector<float>& intens,
                                     const std::string& frame = "laser_frame") {
  W w(le);
  w.header(frame);
  for (float f : {0.0f, 6.28318548f, 0.0123684751f, 0.0f, 0.1f, 0.05f, 10.0f}) w.f32(f);
  w.put(ranges.size(), 4);
  for (float f : ranges) w.f32(f);
  w.put(intens.size(), 4);
  for (float f : intens) w.f32(f);
  return w.b;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(Cdr, LaserScanInBothByteOrders) {
  for (bool le : {true, false}) {
    const auto msg = laser_scan(le, {1.391f, 0.0f, INFINITY}, {12, 0, 3});
    const cdr::LaserScan m = cdr::decode_laser_scan(msg.data(), msg.size());
    EXPECT_EQ(m.header.stamp.sec, 634);
    EXPECT_EQ(m.header.stamp.nanosec, 27000000u);
    EXPECT_EQ(m.header.frame_id, "laser_frame");
    EXPECT_EQ(m.angle_increment, 0.0123684751f);
    EXPECT_EQ(m.scan_time, 0.1f);
    ASSERT_EQ(m.ranges.size(), 3u);
    EXPECT_EQ(m.ranges[0], 1.391f);
    EXPECT_TRUE(std::isinf(m.ranges[2]));
    EXPECT_EQ(m.intensities, (std::vector<float>{12, 0, 3}));
  }
}

TEST(Cdr, AlignmentIsCountedFromAfterTheEncapsulationHeader) {
  // frame_id "ab": 4 + 4 + 4 + 3 = 15 bytes of payload, so angle_min is padded to payload byte 16
  // (message byte 20); counted from the message start it would be byte 16 instead.
  const auto msg = laser_scan(true, {2.5f}, {});
  const auto odd = laser_scan(true, {2.5f}, {}, "ab");
  EXPECT_EQ(cdr::decode_laser_scan(odd.data(), odd.size()).ranges, std::vector<float>{2.5f});
  EXPECT_EQ(odd[19], 0xAA);  // padding
  // A float64 right after an odd-length string: 8-byte alignment from the payload start.
  W w(true);
  w.header("x");        // payload 4 + 4 + 4 + 2 = 14 bytes
  w.str("base_link");   // child_frame_id: 14 -> 16 + 4 + 10 = 30
  for (int k = 0; k < 7; ++k) w.f64(k == 6 ? 1.0 : 0.5 * k);  // aligned to 32
  for (int k = 0; k < 78; ++k) w.f64(0.0);
  EXPECT_EQ(w.b[4 + 30], 0xAA);
  const cdr::Odometry o = cdr::decode_odometry(w.b.data(), w.b.size());
  EXPECT_EQ(o.child_frame_id, "base_link");
  EXPECT_EQ(o.px, 0.0);
  EXPECT_EQ(o.py, 0.5);
  EXPECT_EQ(o.qz, 2.5);
  EXPECT_EQ(o.qw, 1.0);
  (void)msg;
}

TEST(Cdr, NumbersAndJointState) {
  for (bool le : {true, false}) {
    W i16(le);
    i16.put(static_cast<std::uint16_t>(-30), 2);
    EXPECT_EQ(cdr::decode_number("std_msgs/msg/Int16", i16.b.data(), i16.b.size()), -30.0);
    EXPECT_EQ(cdr::decode_number("std_msgs/msg/UInt16", i16.b.data(), i16.b.size()), 65506.0);
    W i32(le);
    i32.put(89, 4);
    EXPECT_EQ(cdr::decode_number("std_msgs/msg/Int32", i32.b.data(), i32.b.size()), 89.0);
    W f64(le);
    f64.f64(-12.25);
    EXPECT_EQ(cdr::decode_number("std_msgs/msg/Float64", f64.b.data(), f64.b.size()), -12.25);
    W f32(le);
    f32.f32(0.5f);
    EXPECT_EQ(cdr::decode_number("std_msgs/msg/Float32", f32.b.data(), f32.b.size()), 0.5);
    W js(le);
    js.header("");
    js.put(2, 4);
    js.str("wheel");
    js.str("tilt_joint");
    js.put(2, 4);
    js.f64(3.0);
    js.f64(-0.25);
    js.put(0, 4);
    js.put(0, 4);
    const cdr::JointState m = cdr::decode_joint_state(js.b.data(), js.b.size());
    EXPECT_EQ(m.name, (std::vector<std::string>{"wheel", "tilt_joint"}));
    EXPECT_EQ(m.position, (std::vector<double>{3.0, -0.25}));
  }
  EXPECT_TRUE(cdr::is_number_type("std_msgs/msg/Int32"));
  EXPECT_FALSE(cdr::is_number_type("std_msgs/msg/String"));
}

TEST(Cdr, EveryTruncationIsRefusedWithTheByteAndTheRule) {
  const auto msg = laser_scan(true, {1.0f, 2.0f}, {5.0f, 6.0f});
  for (std::size_t n = 0; n < msg.size(); ++n) {
    const std::string e = error_of([&] { cdr::decode_laser_scan(msg.data(), n); });
    ASSERT_EQ(e.rfind("byte ", 0), 0u) << n << ": " << e;
  }
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(msg.data(), 3); }),
            "byte 0: 3 byte(s): too short for the 4-byte CDR encapsulation header");
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(msg.data(), 30); }),
            "byte 28: truncated: angle_min needs 4 byte(s), 2 left");
  // Cut inside the ranges: the count is refused before anything is allocated.
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(msg.data(), 63); }),
            "byte 56: ranges: sequence of 2 element(s) of 4 byte(s) is longer than the 3 byte(s) left");
}

TEST(Cdr, MalformedFieldsAreRefused) {
  auto msg = laser_scan(true, {1.0f}, {});
  // A sequence count of 2^32 - 1.
  auto big = msg;
  std::memset(big.data() + 56, 0xFF, 4);
  EXPECT_NE(error_of([&] { cdr::decode_laser_scan(big.data(), big.size()); })
                .find("byte 56: ranges: sequence of 4294967295 element(s)"),
            std::string::npos);
  // A string without its NUL, a string length beyond the message, length 0.
  auto nul = msg;
  nul[27] = 'x';
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(nul.data(), nul.size()); }),
            "byte 27: header.frame_id: string is not NUL-terminated");
  auto len = msg;
  len[12] = 0xF0;
  EXPECT_NE(error_of([&] { cdr::decode_laser_scan(len.data(), len.size()); }).find("byte 12: header.frame_id: string of 240"),
            std::string::npos);
  auto zero = msg;
  zero[12] = 0;
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(zero.data(), zero.size()); }),
            "byte 12: header.frame_id: string length 0 (CDR counts the terminating NUL)");
  // Not plain CDR (e.g. PL_CDR or XCDR2).
  auto enc = msg;
  enc[1] = 0x03;
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(enc.data(), enc.size()); }),
            "byte 0: encapsulation header 00 03 is not plain CDR (00 00 big endian or 00 01 little endian)");
  // Bytes after the message: not the type the topic names.
  auto tail = msg;
  tail.insert(tail.end(), 8, 0);
  EXPECT_NE(error_of([&] { cdr::decode_laser_scan(tail.data(), tail.size()); }).find("8 byte(s) after the end"),
            std::string::npos);
  tail.resize(tail.size() - 1);  // up to 7 bytes of padding are fine
  EXPECT_EQ(error_of([&] { cdr::decode_laser_scan(tail.data(), tail.size()); }), "(no error)");
  // An Int32 message read as a LaserScan, a LaserScan read as a Float64.
  W i32(true);
  i32.put(89, 4);
  EXPECT_NE(error_of([&] { cdr::decode_laser_scan(i32.b.data(), i32.b.size()); }).find("truncated: header.stamp.nanosec"),
            std::string::npos);
  EXPECT_NE(error_of([&] { cdr::decode_number("std_msgs/msg/Float64", msg.data(), msg.size()); }).find("after the end"),
            std::string::npos);
}

namespace {
/// A TFMessage of two transforms (the second with a frame name of odd length: padding before the float64s).
std::vector<std::uint8_t> tf_message(bool le) {
  W w(le);
  w.put(2, 4);
  w.header("odom");
  w.str("base_link");
  for (double x : {1.5, -2.0, 0.25, 0.0, 0.0, 0.6, 0.8}) w.f64(x);
  w.put(7, 4);
  w.put(999999999, 4);
  w.str("map");
  w.str("odom");
  for (double x : {10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}) w.f64(x);
  return w.b;
}
}  // namespace

TEST(Cdr, TfMessageInBothByteOrders) {
  for (bool le : {true, false}) {
    const auto msg = tf_message(le);
    const cdr::TFMessage m = cdr::decode_tf_message(msg.data(), msg.size());
    ASSERT_EQ(m.transforms.size(), 2u);
    const cdr::TransformStamped& a = m.transforms[0];
    EXPECT_EQ(a.header.stamp.sec, 634);
    EXPECT_EQ(a.header.frame_id, "odom");
    EXPECT_EQ(a.child_frame_id, "base_link");
    EXPECT_EQ(a.tx, 1.5);
    EXPECT_EQ(a.ty, -2.0);
    EXPECT_EQ(a.tz, 0.25);
    EXPECT_EQ(a.qz, 0.6);
    EXPECT_EQ(a.qw, 0.8);
    const cdr::TransformStamped& b = m.transforms[1];
    EXPECT_EQ(b.header.stamp.sec, 7);
    EXPECT_EQ(b.header.stamp.nanosec, 999999999u);
    EXPECT_EQ(b.header.frame_id, "map");
    EXPECT_EQ(b.child_frame_id, "odom");
    EXPECT_EQ(b.tx, 10.0);
    EXPECT_EQ(b.qw, 1.0);
    // An empty TFMessage is valid.
    W e(le);
    e.put(0, 4);
    EXPECT_TRUE(cdr::decode_tf_message(e.b.data(), e.b.size()).transforms.empty());
  }
}

TEST(Cdr, TfMessageTruncationsAndBadCountsAreRefused) {
  for (bool le : {true, false}) {
    const auto msg = tf_message(le);
    for (std::size_t n = 0; n < msg.size(); ++n) {
      const std::string e = error_of([&] { cdr::decode_tf_message(msg.data(), n); });
      ASSERT_EQ(e.rfind("byte ", 0), 0u) << n << ": " << e;
    }
    // Cut in the second transform's rotation.w (payload 176 .. 184).
    EXPECT_EQ(error_of([&] { cdr::decode_tf_message(msg.data(), msg.size() - 5); }),
              "byte 180: truncated: transforms.transform.rotation.w needs 8 byte(s), 3 left");
    // A count of 3 for two transforms: 180 bytes after the count cannot hold three of at least 74.
    auto three = msg;
    three[le ? 4 : 7] = 3;
    EXPECT_EQ(error_of([&] { cdr::decode_tf_message(three.data(), three.size()); }),
              "byte 4: transforms: sequence of 3 element(s) of 74 byte(s) is longer than the 180 byte(s) left");
    // A count of 2^32 - 1: refused before anything is allocated.
    auto big = msg;
    std::memset(big.data() + 4, 0xFF, 4);
    EXPECT_EQ(error_of([&] { cdr::decode_tf_message(big.data(), big.size()); }),
              "byte 4: transforms: sequence of 4294967295 element(s) of 74 byte(s) is longer than the 180 byte(s) left");
    // A nanosec of 1e9, a trailing transform-sized tail (not a TFMessage).
    auto ns = msg;
    const std::uint32_t bad = 1000000000u;
    for (int k = 0; k < 4; ++k) ns[104 + k] = static_cast<std::uint8_t>(bad >> (8 * (le ? k : 3 - k)));
    EXPECT_EQ(error_of([&] { cdr::decode_tf_message(ns.data(), ns.size()); }),
              "byte 104: header.stamp.nanosec 1000000000 is not below 1e9");
    auto tail = msg;
    tail.insert(tail.end(), 8, 0);
    EXPECT_NE(error_of([&] { cdr::decode_tf_message(tail.data(), tail.size()); })
                  .find("byte 188: 8 byte(s) after the end of the tf2_msgs/msg/TFMessage message"),
              std::string::npos);
  }
}

TEST(TiltGeometry, DefaultsAreTheRplidarRigAndTheOptionsCompose) {
  const TiltGeometry g;
  // Bit for bit what import rplidar computed before the geometry became options.
  for (double d : {60.0, 89.0, 90.0, 91.0, 119.0, 104.5})
    EXPECT_EQ(g.nod_rad(d), (d - 90.0) * 3.14159265358979323846 / 180.0) << d;
  TiltGeometry h;
  h.sign = 1;
  h.zero = 0;
  h.scale = 180.0 / M_PI;  // radians
  EXPECT_NEAR(h.nod_rad(0.25), -0.25, 1e-15);
  h.scale = 0;
  EXPECT_THROW(h.check("t"), ConfigError);
  h.scale = 1;
  h.sign = 0.5;
  EXPECT_THROW(h.check("t"), ConfigError);
}

// The fuzz target's seeds (tests/fuzz/corpus/rosbag2_cdr: first byte = message type, as in
// fuzz_rosbag2_cdr.cpp: 0 LaserScan, 1 JointState, 2 Odometry, 3 TFMessage, 4 numbers) are valid
// messages: each decodes, in every ordinary build.
TEST(Cdr, FuzzSeedsDecode) {
  std::size_t n = 0;
  for (const auto& e : std::filesystem::directory_iterator(std::string(PCDP_SOURCE_DIR) + "/tests/fuzz/corpus/rosbag2_cdr")) {
    std::ifstream in(e.path(), std::ios::binary);
    const std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(b.empty());
    const std::uint8_t* m = b.data() + 1;
    const std::size_t size = b.size() - 1;
    static const char* const kNumbers[] = {"std_msgs/msg/Float32", "std_msgs/msg/Float64", "std_msgs/msg/Int8",
                                           "std_msgs/msg/Int16",   "std_msgs/msg/Int32",   "std_msgs/msg/Int64",
                                           "std_msgs/msg/UInt16",  "std_msgs/msg/UInt64"};
    const std::string err = error_of([&] {
      switch (b[0] % 5) {
        case 0: cdr::decode_laser_scan(m, size); break;
        case 1: cdr::decode_joint_state(m, size); break;
        case 2: cdr::decode_odometry(m, size); break;
        case 3: cdr::decode_tf_message(m, size); break;
        default: cdr::decode_number(kNumbers[(b[0] / 5) % 8], m, size); break;
      }
    });
    EXPECT_EQ(err, "(no error)") << e.path();
    ++n;
  }
  EXPECT_GE(n, 10u);
}
