// `import rosbag2` through the CLI on TurboSLAM's ROS 2 bags (../shared/datasets/rplidar_tilt_turboslam):
// the same passes as `import rplidar` on the data set's CSV export of the same bags, and damaged
// copies of a bag refused with exit 3 naming the file, the topic, the message and the rule.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <cstdio>
#include <filesystem>
#include <string>

#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {
const std::string kData = std::string(PCDP_SHARED_DIR) + "/datasets/rplidar_tilt_turboslam";

std::string pass_file(const std::string& dir, std::size_t k) {
  char name[32];
  std::snprintf(name, sizeof name, "/pass_%03zu.pcd", k);
  return dir + name;
}

std::vector<Pass> read_passes(const std::string& dir) {
  std::vector<Pass> out;
  for (std::size_t k = 0; fs::exists(pass_file(dir, k)); ++k) out.push_back(read_pass(pass_file(dir, k), k));
  return out;
}

/// A writable copy of bag `name` in `dir`, with `sql` run on its .db3 (empty: none).
std::string corrupted_copy(const std::string& name, const std::string& dir, const std::string& sql) {
  const std::string bag = dir + "/" + name;
  fs::create_directories(bag);
  for (const auto& e : fs::directory_iterator(kData + "/bags/" + name)) {
    const fs::path to = fs::path(bag) / e.path().filename();
    fs::copy_file(e.path(), to, fs::copy_options::overwrite_existing);
    fs::permissions(to, fs::perms::owner_write, fs::perm_options::add);
  }
  if (!sql.empty()) {
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open((bag + "/" + name + "_0.db3").c_str(), &db), SQLITE_OK);
    char* err = nullptr;
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
    sqlite3_free(err);
    sqlite3_close(db);
  }
  return bag;
}
}  // namespace

// The acceptance test of issue 34: the bag and its CSV export give the same passes.
TEST(Rosbag2, TheRplidarBagGivesTheSamePassesAsItsCsvExport) {
  if (!fs::exists(kData + "/bags/lidarServo/metadata.yaml")) GTEST_SKIP() << "no " << kData;
  for (const std::string name : {"lidarServo", "subset"}) {
    SCOPED_TRACE(name);
    const std::string dir = test::fresh_dir(name);
    const auto bag = run_cli({"import", "rosbag2", kData + "/bags/" + name, "--output-dir", dir + "/bag"});
    ASSERT_EQ(bag.exit_code, 0) << bag.err;
    EXPECT_NE(bag.out.find("topics: scans /scan, tilt /lidar_servo_angle (std_msgs/msg/Int32"), std::string::npos) << bag.out;
    const auto csv = run_cli({"import", "rplidar", kData + "/csv/" + name, "--output-dir", dir + "/csv"});
    ASSERT_EQ(csv.exit_code, 0) << csv.err;
    // The same counts line (scans read, dropped, returns, passes).
    const auto counts = [](const std::string& out) { return out.substr(0, out.find(" -> ")); };
    EXPECT_EQ(counts(bag.out.substr(bag.out.find("imported"))), counts(csv.out.substr(csv.out.find("imported"))));
    const std::vector<Pass> a = read_passes(dir + "/bag"), b = read_passes(dir + "/csv");
    ASSERT_EQ(a.size(), b.size());
    ASSERT_GE(a.size(), 10u);  // lidarServo: 13 half nods, subset: 29
    std::size_t returns = 0, bearing_ulps = 0;
    double max_bearing_diff = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
      ASSERT_EQ(a[k].size(), b[k].size()) << "pass " << k;
      returns += a[k].size();
      for (std::size_t i = 0; i < a[k].size(); ++i) {
        // Exact: the same float32 ranges and intensities, the same bag times, the same servo readings.
        ASSERT_EQ(a[k].line[i], b[k].line[i]) << k << " " << i;
        ASSERT_EQ(a[k].beam[i], b[k].beam[i]) << k << " " << i;
        ASSERT_EQ(a[k].range[i], b[k].range[i]) << k << " " << i;
        ASSERT_EQ(a[k].amplitude[i], b[k].amplitude[i]) << k << " " << i;
        ASSERT_EQ(a[k].nod[i], b[k].nod[i]) << k << " " << i;
        ASSERT_EQ(a[k].stamp[i], b[k].stamp[i]) << k << " " << i;
        // The bearing: the bag gives angle_min + k * angle_increment from the float32 fields; the
        // CSV holds that sum printed with 9 significant digits (off by up to 5e-9 rad for angles
        // under 10 rad). After wrapping to (-pi, pi] and rounding to float32 the two agree or
        // differ by that plus one unit in the last place: at most 2.4e-7 rad (an ulp between 2
        // and pi), a few ulps only near 0 where the ulp is smaller than 5e-9.
        const float x = a[k].bearing[i], y = b[k].bearing[i];
        if (x != y) {
          ++bearing_ulps;
          const float m = std::max(std::fabs(x), std::fabs(y));
          const double ulp = static_cast<double>(std::nextafter(m, INFINITY) - m);
          ASSERT_LE(std::fabs(static_cast<double>(x) - y), ulp + 5e-9)
              << "pass " << k << " return " << i << ": " << x << " vs " << y;
          max_bearing_diff = std::max(max_bearing_diff, std::fabs(static_cast<double>(x) - y));
        }
      }
    }
    // SOURCE.md: 150,519 beams in lidarServo; 123,764 in subset, of which the scans outside the
    // servo stream are dropped by both importers.
    EXPECT_EQ(returns, name == "lidarServo" ? 150519u : 123256u);
    EXPECT_LT(bearing_ulps, returns / 20) << "bearings apart: " << bearing_ulps;
    EXPECT_LE(max_bearing_diff, 2.4e-7);
    std::cout << name << ": " << a.size() << " passes, " << returns << " returns; " << bearing_ulps
              << " bearings differ (at most " << max_bearing_diff << " rad), everything else identical\n";
  }
}

TEST(Rosbag2, TheTiltGeometryOptionsApplyToBothImporters) {
  if (!fs::exists(kData + "/bags/lidarServo/metadata.yaml")) GTEST_SKIP() << "no " << kData;
  const std::string dir = test::fresh_dir();
  // Sign +1 mirrors the nod; zero 80 shifts it by 10 degrees; both importers agree.
  for (const char* fmt : {"rosbag2", "rplidar"}) {
    const std::string in = kData + (std::string(fmt) == "rosbag2" ? "/bags/lidarServo" : "/csv/lidarServo");
    const auto def = run_cli({"import", fmt, in, "--output-dir", dir + "/" + fmt + "_def"});
    const auto alt = run_cli({"import", fmt, in, "--output-dir", dir + "/" + fmt + "_alt", "--tilt-sign", "1",
                              "--tilt-zero", "80", "--axis-offset", "0.1"});
    ASSERT_EQ(def.exit_code, 0) << def.err;
    ASSERT_EQ(alt.exit_code, 0) << alt.err;
    EXPECT_NE(alt.out.find("put mount z: 0.1 in the pipeline"), std::string::npos) << alt.out;
    const Pass p = read_pass(pass_file(dir + "/" + fmt + "_def", 3), 3), q = read_pass(pass_file(dir + "/" + fmt + "_alt", 3), 3);
    ASSERT_EQ(p.size(), q.size());
    for (std::size_t i = 0; i < p.size(); i += 97)
      EXPECT_NEAR(q.nod[i], -(p.nod[i] + 10.0 * M_PI / 180.0), 1e-6) << fmt << " " << i;
  }
  const auto bad = run_cli({"import", "rosbag2", kData + "/bags/lidarServo", "--output-dir", dir + "/x", "--tilt-scale", "0"});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("tilt scale"), std::string::npos) << bad.err;
  const auto topic = run_cli({"import", "rosbag2", kData + "/bags/lidarServo", "--output-dir", dir + "/x", "--tilt-topic", "/scan"});
  EXPECT_EQ(topic.exit_code, 2);
  EXPECT_NE(topic.err.find("--tilt-topic /scan has type sensor_msgs/msg/LaserScan"), std::string::npos) << topic.err;
  const auto none = run_cli({"import", "rosbag2", kData + "/bags/lidarServo", "--output-dir", dir + "/x", "--scan-topic", "/lidar"});
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_NE(none.err.find("--scan-topic /lidar: no such topic"), std::string::npos) << none.err;
  EXPECT_NE(none.err.find("/lidar_servo_angle (std_msgs/msg/Int32)"), std::string::npos) << none.err;
  const auto other = run_cli({"import", "cloud", "x.pcd", "--output-dir", dir + "/x", "--tilt-zero", "0"});
  EXPECT_EQ(other.exit_code, 2);
  EXPECT_NE(other.err.find("import cloud: --tilt-zero is for rplidar and rosbag2"), std::string::npos) << other.err;
  EXPECT_FALSE(fs::exists(dir + "/x"));
}

// Damaged bags: exit 3, the message names the .db3, the topic, the message and the rule, and no
// output folder is left.
TEST(Rosbag2, ACorruptedBagFailsNamingTheFileTopicMessageAndRule) {
  if (!fs::exists(kData + "/bags/lidarServo/metadata.yaml")) GTEST_SKIP() << "no " << kData;
  const std::string dir = test::fresh_dir();
  struct Case {
    const char* tag;
    std::string sql;
    std::vector<std::string> expect;
  };
  const Case cases[] = {
      // The first LaserScan (id 2) cut after its header: angle_min is missing.
      {"truncated", "UPDATE messages SET data = substr(data, 1, 30) WHERE id = 2",
       {"lidarServo_0.db3: topic /scan, message 0 (id 2, bag time 1748602825116519468 ns): byte 28: truncated: angle_min"}},
      // Its ranges count (bytes 56-59, after the header, frame_id and 7 floats) set to 2^31 - 1.
      {"sequence", "UPDATE messages SET data = CAST(substr(data, 1, 56) || x'FFFFFF7F' || substr(data, 61) AS BLOB) WHERE id = 8",
       {"topic /scan, message 1 (id 8,", "byte 56: ranges: sequence of 2147483647 element(s) of 4 byte(s) is longer than"}},
      // An encapsulation header that is not plain CDR.
      {"encapsulation", "UPDATE messages SET data = CAST(x'0007' || substr(data, 3) AS BLOB) WHERE id = 13",
       {"topic /scan, message 2 (id 13,", "byte 0: encapsulation header 00 07 is not plain CDR"}},
      // The servo topic claims Float64: its 4-byte Int32 payload is too short.
      {"type", "UPDATE topics SET type = 'std_msgs/msg/Float64' WHERE name = '/lidar_servo_angle'",
       {"topic /lidar_servo_angle, message 0 (id 1,", "truncated: data needs 8 byte(s), 4 left"}},
      // A LaserScan topic whose messages are servo angles.
      {"type2", "UPDATE messages SET data = (SELECT data FROM messages WHERE id = 1) WHERE id = 2",
       {"topic /scan, message 0 (id 2,", "truncated: header.stamp.nanosec"}},
      // The data stored as text: not a blob.
      {"text", "UPDATE messages SET data = 'hello' WHERE id = 2", {"topic /scan, message 0 (id 2,", "the data is not a blob"}},
      {"table", "DROP TABLE messages", {"lidarServo_0.db3: no such table: messages: a ROS 2 sqlite3 bag has the tables"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.tag);
    const std::string bag = corrupted_copy("lidarServo", dir + "/" + c.tag, c.sql);
    const auto r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/" + c.tag + "/out"});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    for (const auto& e : c.expect) EXPECT_NE(r.err.find(e), std::string::npos) << "want: " << e << "\ngot: " << r.err;
    EXPECT_EQ(r.err.find("internal"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/" + c.tag + "/out"));
  }
  // Not an SQLite file at all.
  const std::string bag = corrupted_copy("lidarServo", dir + "/junk", "");
  test::write_text(bag + "/lidarServo_0.db3", "this is not a database, just text\n");
  auto r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/junk/out"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("lidarServo_0.db3: byte 0: not an SQLite database"), std::string::npos) << r.err;
  // MCAP storage is named, not misread.
  std::string meta = test::read_text(bag + "/metadata.yaml");
  meta.replace(meta.find("storage_identifier: sqlite3"), 27, "storage_identifier: mcap");
  test::write_text(bag + "/metadata.yaml", meta);
  r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/junk/out"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("metadata.yaml: storage_identifier 'mcap': only sqlite3 storage"), std::string::npos) << r.err;
}
