// Small ROS 2 bags written by the tests with the sqlite3 C API (the schema rosbag2's sqlite3
// storage writes) and a little-endian CDR writer; tf_bag() is a nodding scanner with poses on /tf.
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "test_support.hpp"

namespace pcdp::test::rosbag2 {

/// A CDR writer: little (the default) or big endian, primitives aligned to their size from after
/// the 4-byte encapsulation header, padding bytes `pad` (a reader must not check them).
struct W {
  bool le = true;
  std::uint8_t pad = 0;
  std::vector<std::uint8_t> b{0, 1, 0, 0};
  W() = default;
  explicit W(bool little, std::uint8_t padding = 0)
      : le(little), pad(padding), b{0x00, static_cast<std::uint8_t>(little ? 1 : 0), 0, 0} {}
  void align(std::size_t n) {
    while ((b.size() - 4) % n) b.push_back(pad);
  }
  void put(std::uint64_t v, std::size_t n) {
    align(n);
    for (std::size_t k = 0; k < n; ++k) b.push_back(static_cast<std::uint8_t>(v >> (8 * (le ? k : n - 1 - k))));
  }
  void f32(float f) {
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    put(u, 4);
  }
  void f64(double f) {
    std::uint64_t u;
    std::memcpy(&u, &f, 8);
    put(u, 8);
  }
  void str(const std::string& s) {
    put(s.size() + 1, 4);
    b.insert(b.end(), s.begin(), s.end());
    b.push_back(0);
  }
  /// std_msgs/Header: stamp (sec, nanosec) and frame_id.
  void header(const std::string& frame = "f", std::uint32_t sec = 1, std::uint32_t nanosec = 0) {
    put(sec, 4);
    put(nanosec, 4);
    str(frame);
  }
};

struct Msg {
  int topic;  ///< 1-based index into the topics
  long long t;
  std::vector<std::uint8_t> data;
};

inline void write_db3(const std::string& path, const std::vector<std::pair<std::string, std::string>>& topics,
                      const std::vector<Msg>& msgs) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  const char* schema =
      "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, serialization_format "
      "TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, data "
      "BLOB NOT NULL);";
  ASSERT_EQ(sqlite3_exec(db, schema, nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')", -1, &st, nullptr);
  for (std::size_t k = 0; k < topics.size(); ++k) {
    sqlite3_bind_int64(st, 1, static_cast<long long>(k + 1));
    sqlite3_bind_text(st, 2, topics[k].first.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(st, 3, topics[k].second.c_str(), -1, SQLITE_TRANSIENT);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_reset(st);
  }
  sqlite3_finalize(st);
  sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr);
  sqlite3_prepare_v2(db, "INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", -1, &st, nullptr);
  for (const Msg& m : msgs) {
    sqlite3_bind_int64(st, 1, m.topic);
    sqlite3_bind_int64(st, 2, m.t);
    sqlite3_bind_blob(st, 3, m.data.data(), static_cast<int>(m.data.size()), SQLITE_TRANSIENT);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_reset(st);
  }
  sqlite3_finalize(st);
  sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr);
  sqlite3_close(db);
}

constexpr long long kT0 = 1'700'000'000'000'000'000LL;
constexpr long long kMs = 1'000'000;

/// One LaserScan of 100 beams (-1.5 .. 1.47 rad, 2 m + 1 cm per beam), scan_time 0.1 s.
inline std::vector<std::uint8_t> laser_scan() {
  W w;
  w.header("laser");
  for (float f : {-1.5f, 1.5f, 0.03f, 0.001f, 0.1f, 0.1f, 20.0f}) w.f32(f);
  w.put(100, 4);
  for (int k = 0; k < 100; ++k) w.f32(2.0f + 0.01f * static_cast<float>(k));
  w.put(0, 4);
  return w.b;
}

/// A rotation from roll, pitch, yaw in the project's pose-file order xyz: Rx(roll) Ry(pitch) Rz(yaw)
/// (built here with Eigen's angle-axis, independently of pcdp/core/transforms.hpp).
inline Eigen::Quaterniond xyz_quaternion(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
}

/// odom -> base_link at s seconds into the bag: position (s, 0.5 s, 0.1) m, roll -0.03, pitch 0.05,
/// yaw 0.2 s rad (order xyz).
inline Eigen::Isometry3d odom_base(double s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = xyz_quaternion(-0.03, 0.05, 0.2 * s).toRotationMatrix();
  T.translation() = Eigen::Vector3d(s, 0.5 * s, 0.1);
  return T;
}
/// map -> odom: (10 + 0.1 s, -2, 0) m, yaw 0.5 rad.
inline Eigen::Isometry3d map_odom(double s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(10.0 + 0.1 * s, -2.0, 0.0);
  return T;
}
/// base_link -> laser (on /tf_static): (0.2, 0, 0.3) m, pitch 0.1 rad.
inline Eigen::Isometry3d base_laser() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.2, 0.0, 0.3);
  return T;
}

inline void put_transform(W& w, const std::string& parent, const std::string& child, const Eigen::Isometry3d& T) {
  w.header(parent);
  w.str(child);
  const Eigen::Quaterniond q(T.rotation());
  for (double x : {T.translation().x(), T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w()}) w.f64(x);
}

struct TfBagOptions {
  bool map_odom = true;     ///< /tf also carries map -> odom (in the same messages)
  bool odometry = false;    ///< a nav_msgs/msg/Odometry topic /odom too
  bool truncate = false;    ///< the 11th /tf message loses its last 5 bytes
};

/// A bag of 4 s, one .db3: /scan (10 Hz from 0.2 s), /tilt (std_msgs/msg/Float64, 25 Hz, degrees:
/// 90 + a triangle of +-17 degrees, period 2 s, for the default tilt geometry), /tf (20 Hz:
/// odom -> base_link and map -> odom), /tf_static (base_link -> laser, once), optionally /odom.
inline std::string tf_bag(const std::string& dir, const TfBagOptions& o = {}) {
  std::vector<std::pair<std::string, std::string>> topics = {{"/scan", "sensor_msgs/msg/LaserScan"},
                                                             {"/tilt", "std_msgs/msg/Float64"},
                                                             {"/tf", "tf2_msgs/msg/TFMessage"},
                                                             {"/tf_static", "tf2_msgs/msg/TFMessage"}};
  if (o.odometry) topics.push_back({"/odom", "nav_msgs/msg/Odometry"});
  std::vector<Msg> m;
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 40 * kMs) {
    const double s = std::fmod(static_cast<double>(t - kT0) * 1e-9, 2.0);
    W w;
    w.f64(90.0 + (s < 1.0 ? -17.0 + 34.0 * s : 17.0 - 34.0 * (s - 1.0)));
    m.push_back({2, t, w.b});
  }
  int k = 0;
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 50 * kMs, ++k) {
    const double s = static_cast<double>(t - kT0) * 1e-9;
    W w;
    w.put(o.map_odom ? 2 : 1, 4);
    put_transform(w, "odom", "base_link", odom_base(s));
    if (o.map_odom) put_transform(w, "map", "odom", map_odom(s));
    if (o.truncate && k == 10) w.b.resize(w.b.size() - 5);
    m.push_back({3, t, w.b});
    if (o.odometry) {
      W v;
      v.header("odom");
      v.str("base_link");
      for (double x : {s, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}) v.f64(x);
      for (int c = 0; c < 78; ++c) v.f64(0);
      m.push_back({5, t, v.b});
    }
  }
  {
    W w;
    w.put(1, 4);
    put_transform(w, "base_link", "laser", base_laser());
    m.push_back({4, kT0, w.b});
  }
  for (long long t = kT0 + 200 * kMs; t < kT0 + 3900 * kMs; t += 100 * kMs) m.push_back({1, t, laser_scan()});
  const std::string bag = dir + "/tfbag";
  std::filesystem::create_directories(bag);
  write_db3(bag + "/tfbag_0.db3", topics, m);
  return bag;
}

}  // namespace pcdp::test::rosbag2
