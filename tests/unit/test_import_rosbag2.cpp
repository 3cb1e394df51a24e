// import_rosbag2 on small bags written here with the sqlite3 C API (the schema rosbag2's sqlite3
// storage writes): a JointState tilt (one joint of two, radians), Odometry poses, several .db3 files
// named by metadata.yaml, topic choice and its errors.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "pcdp/errors.hpp"
#include "pcdp/io/import_rosbag2.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using namespace pcdp::io;

namespace {
struct W {  // little-endian CDR
  std::vector<std::uint8_t> b{0, 1, 0, 0};
  void put(std::uint64_t v, std::size_t n) {
    while ((b.size() - 4) % n) b.push_back(0);
    for (std::size_t k = 0; k < n; ++k) b.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
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
  void header() {
    put(1, 4);
    put(0, 4);
    str("f");
  }
};

constexpr long long kT0 = 1'700'000'000'000'000'000LL;
constexpr long long kMs = 1'000'000;
constexpr double kPi = 3.14159265358979323846;

/// The tilt joint's position (rad) at bag time t: a triangle wave +-0.3 rad, period 2 s.
double tilt_at(long long t) {
  const double s = std::fmod(static_cast<double>(t - kT0) * 1e-9, 2.0);
  return s < 1.0 ? -0.3 + 0.6 * s : 0.3 - 0.6 * (s - 1.0);
}

struct Msg {
  int topic;
  long long t;
  std::vector<std::uint8_t> data;
};

void write_db3(const std::string& path, const std::vector<std::pair<std::string, std::string>>& topics,
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

/// A bag of 4 s in two .db3 files: /scan (10 Hz, 100 beams), /joint_states (25 Hz, joints "wheel"
/// and "tilt"), /odom (20 Hz, x = t m, yaw = 0.1 t rad), /battery (Float32, a second number topic).
std::string make_bag(const std::string& dir) {
  const std::vector<std::pair<std::string, std::string>> topics = {{"/scan", "sensor_msgs/msg/LaserScan"},
                                                                   {"/joint_states", "sensor_msgs/msg/JointState"},
                                                                   {"/odom", "nav_msgs/msg/Odometry"},
                                                                   {"/battery", "std_msgs/msg/Float32"}};
  std::vector<Msg> a, b;
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 40 * kMs) {
    W w;
    w.header();
    w.put(2, 4);
    w.str("wheel");
    w.str("tilt");
    w.put(2, 4);
    w.f64(7.0);
    w.f64(tilt_at(t));
    w.put(0, 4);
    w.put(0, 4);
    (t < kT0 + 2000 * kMs ? a : b).push_back({2, t, w.b});
    W v;
    v.f32(12.5f);
    (t < kT0 + 2000 * kMs ? a : b).push_back({4, t, v.b});
  }
  for (long long t = kT0; t <= kT0 + 4000 * kMs; t += 50 * kMs) {
    const double s = static_cast<double>(t - kT0) * 1e-9;
    W w;
    w.header();
    w.str("base_link");
    for (double x : {s, 0.0, 0.0, 0.0, 0.0, std::sin(0.05 * s), std::cos(0.05 * s)}) w.f64(x);
    for (int k = 0; k < 78; ++k) w.f64(0);
    (t < kT0 + 2000 * kMs ? a : b).push_back({3, t, w.b});
  }
  for (long long t = kT0 + 200 * kMs; t < kT0 + 3900 * kMs; t += 100 * kMs) {
    W w;
    w.header();
    for (float f : {-1.5f, 1.5f, 0.03f, 0.001f, 0.1f, 0.1f, 20.0f}) w.f32(f);
    w.put(100, 4);
    for (int k = 0; k < 100; ++k) w.f32(k == 5 ? INFINITY : 2.0f + 0.01f * static_cast<float>(k));
    w.put(0, 4);  // no intensities
    (t < kT0 + 2000 * kMs ? a : b).push_back({1, t, w.b});
  }
  const std::string bag = dir + "/bag";
  fs::create_directories(bag);
  write_db3(bag + "/bag_0.db3", topics, a);
  write_db3(bag + "/bag_1.db3", topics, b);
  test::write_text(bag + "/metadata.yaml",
                   "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
                   "  compression_format: \"\"\n  relative_file_paths:\n    - bag_0.db3\n    - bag_1.db3\n");
  return bag;
}
}  // namespace

TEST(ImportRosbag2, JointStateTiltOdometryPosesAndSplitFiles) {
  const std::string bag = make_bag(test::fresh_dir());
  Rosbag2ImportParams p;
  p.tilt_topic = "/joint_states:tilt";
  p.passes.geometry.zero = 0;  // the joint is level at 0; radians are converted to degrees
  const ImportedRosbag2 r = import_rosbag2(bag, p);
  EXPECT_EQ(r.scan_topic, "/scan");
  EXPECT_EQ(r.tilt_topic, "/joint_states:tilt");
  EXPECT_EQ(r.odom_topic, "/odom");
  EXPECT_EQ(r.passes.scans, 37u);
  EXPECT_EQ(r.passes.dropped_scans, 0u);
  EXPECT_EQ(r.passes.beams, 3700u);
  // The tilt reverses at 1, 2 and 3 s: four passes.
  ASSERT_EQ(r.passes.passes.size(), 4u);
  std::size_t lines = 0;
  for (const Pass& pass : r.passes.passes) {
    for (std::size_t l = 0; l < pass.line_count(); ++l, ++lines) {
      const std::size_t last = pass.line_begin[l + 1] - 1;
      // nod = -pitch = -(-1) * (deg - 0): the joint position at the line's last beam, in rad.
      const long long t = r.passes.t0_ns + std::llround(pass.stamp[last] * 1e9);
      EXPECT_NEAR(pass.nod[last], tilt_at(t), 1e-6) << "line " << pass.line[last];
      EXPECT_EQ(pass.range[pass.line_begin[l] + 5], 0.0f);  // inf: no return
      EXPECT_FLOAT_EQ(pass.range[pass.line_begin[l] + 6], 2.06f);
      EXPECT_EQ(pass.amplitude[pass.line_begin[l] + 6], 0.0f);  // no intensities
      EXPECT_NEAR(pass.bearing[pass.line_begin[l] + 60], -1.5 + 60 * static_cast<double>(0.03f), 1e-6);
    }
  }
  EXPECT_EQ(lines, 37u);
  // Odometry: 81 poses on the passes' time axis (t0 = 10 s before the first scan).
  ASSERT_EQ(r.poses.size(), 81u);
  EXPECT_NEAR(r.poses.front().stamp, 10.0 - 0.2, 1e-9);
  EXPECT_NEAR(r.poses[40].position.x(), 2.0, 1e-12);
  EXPECT_NEAR(r.poses[40].orientation.z(), std::sin(0.1), 1e-12);
}

TEST(ImportRosbag2, TopicChoiceIsExplicitWhenTheBagIsAmbiguous) {
  const std::string bag = make_bag(test::fresh_dir());
  const auto err = [&](Rosbag2ImportParams p) -> std::string {
    try {
      import_rosbag2(bag, p);
    } catch (const ConfigError& e) {
      return std::string("config: ") + e.what();
    } catch (const InputError& e) {
      return std::string("input: ") + e.what();
    }
    return "(no error)";
  };
  Rosbag2ImportParams p;
  // Two tilt candidates: /battery (Float32) and /joint_states.
  EXPECT_NE(err(p).find("config: import rosbag2: " + bag + " has 2 topics of type a std_msgs number or sensor_msgs/msg/JointState (/battery, /joint_states): choose one with --tilt-topic"),
            std::string::npos)
      << err(p);
  // A JointState of two joints needs the joint.
  p.tilt_topic = "/joint_states";
  EXPECT_NE(err(p).find("carries 2 joints: name the tilt joint with --tilt-topic /joint_states:JOINT"), std::string::npos)
      << err(p);
  p.tilt_topic = "/joint_states:nope";
  EXPECT_NE(err(p).find("input: " + bag + ": topic /joint_states:nope has 0 usable message(s)"), std::string::npos) << err(p);
  // The wheel at 7 rad = 401 deg is no tilt.
  p.tilt_topic = "/joint_states:wheel";
  p.passes.geometry.zero = 0;
  EXPECT_NE(err(p).find("gives a nod of 401.07"), std::string::npos) << err(p);
  p.tilt_topic = "/battery:x";
  EXPECT_NE(err(p).find("config: import rosbag2: --tilt-topic /battery:x: a joint name is for sensor_msgs/msg/JointState"),
            std::string::npos)
      << err(p);
  // A .db3 given directly reads that file alone (the second half of the bag).
  Rosbag2ImportParams q;
  q.tilt_topic = "/joint_states:tilt";
  q.passes.geometry.zero = 0;
  q.odom_topic = "/odom";
  const ImportedRosbag2 r = import_rosbag2(bag + "/bag_1.db3", q);
  EXPECT_EQ(r.passes.scans, 19u);
}
