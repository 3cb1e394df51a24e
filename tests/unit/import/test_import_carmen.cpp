// The CARMEN importer on the real logs of ../shared/datasets/carmen_corrected_radish (counts, beam
// angles, poses, the no-return sentinel) and on small hand-written logs (ROBOTLASER1, gzip,
// every malformed field named with its line).
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <string>

#include "pcdp/core/errors.hpp"
#include "pcdp/import/carmen.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
const std::string kCarmen = std::string(PCDP_SHARED_DIR) + "/datasets/carmen_corrected_radish/";

std::string error_of(const std::string& path) {
  try {
    io::import_carmen(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

void write_gz(const std::string& path, const std::string& text) {
  gzFile f = gzopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  ASSERT_EQ(gzwrite(f, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  gzclose(f);
}

/// A FLASER line of the given ranges at (x, y, theta) and time t.
std::string flaser(const std::vector<double>& r, double x, double y, double th, double t) {
  std::string s = "FLASER " + std::to_string(r.size());
  for (double v : r) s += " " + std::to_string(v);
  for (double v : {x, y, th, x, y, th, t}) s += " " + std::to_string(v);
  return s + " host " + std::to_string(t) + "\n";
}
}  // namespace

TEST(ImportCarmen, Fr079GivesOnePlanarPassPerScanWithItsLaserPose) {
  const io::ImportedCarmen r = io::import_carmen(kCarmen + "freiburg-079-corrected.log.gz");
  EXPECT_EQ(r.message, "FLASER");
  ASSERT_EQ(r.passes.size(), 4791u);  // SOURCE.md: 4,791 FLASER scans of 360 beams
  std::size_t returns = 0, zeros = 0;
  for (const Pass& p : r.passes) {
    ASSERT_EQ(p.size(), 360u);
    ASSERT_EQ(p.line_count(), 1u);
    returns += p.size();
    for (float v : p.range) zeros += v == 0.0f ? 1 : 0;
  }
  EXPECT_EQ(returns, 1724760u);
  EXPECT_EQ(r.max_range_readings, 36004u);  // SOURCE.md: the 81.91 m sentinel
  EXPECT_EQ(zeros, 36004u);
  EXPECT_DOUBLE_EQ(r.max_range, 80.99);     // PARAM robot_front_laser_max
  EXPECT_EQ(r.reordered, 0u);
  // The first FLASER (line 192): ranges 1.65 1.66 ..., pose (0.00123601, -0.00106807, 2.85e-05) at 0.227623 s.
  const Pass& p = r.passes[0];
  EXPECT_EQ(p.source, kCarmen + "freiburg-079-corrected.log.gz:192");
  EXPECT_FLOAT_EQ(p.range[0], 1.65f);
  EXPECT_FLOAT_EQ(p.range[1], 1.66f);
  // 360 readings: 0.5 degree steps from -90 degrees (CARMEN's own convention for 360 beams).
  EXPECT_NEAR(p.bearing[0], -M_PI / 2, 1e-6);
  EXPECT_NEAR(p.bearing[359], -M_PI / 2 + 359 * M_PI / 360, 1e-6);
  for (std::size_t i = 0; i < 360; ++i) {
    EXPECT_EQ(p.nod[i], 0.0f);
    EXPECT_EQ(p.stamp[i], 0.227623);
    EXPECT_TRUE(std::isnan(p.amplitude[i]));
  }
  ASSERT_EQ(r.poses.size(), 2 * 4791u);
  EXPECT_LT(r.poses[0].stamp, 0.227623);
  EXPECT_GT(r.poses[1].stamp, 0.227623);
  EXPECT_LE(r.poses[1].stamp - r.poses[0].stamp, 0.002 + 1e-12);
  EXPECT_DOUBLE_EQ(r.poses[0].position.x(), 0.00123601);
  EXPECT_DOUBLE_EQ(r.poses[0].position.y(), -0.00106807);
  EXPECT_NEAR(2 * std::atan2(r.poses[0].orientation.z(), r.poses[0].orientation.w()), 2.85e-05, 1e-12);
  for (std::size_t k = 1; k < r.poses.size(); ++k) ASSERT_GT(r.poses[k].stamp, r.poses[k - 1].stamp) << k;
}

TEST(ImportCarmen, IntelLogIsPutInTimeOrder) {
  const io::ImportedCarmen r = io::import_carmen(kCarmen + "intel-corrected.log.gz");
  ASSERT_EQ(r.passes.size(), 910u);  // SOURCE.md: 910 scans of 180 beams
  EXPECT_EQ(r.passes[0].size(), 180u);
  EXPECT_NEAR(r.passes[0].bearing[179] - r.passes[0].bearing[0], 179 * M_PI / 180, 1e-6);  // 1 degree steps
  EXPECT_EQ(r.reordered, 4u);  // four messages are stamped before the one above them
  EXPECT_DOUBLE_EQ(r.max_range, 80.0);  // no PARAM: CARMEN's FLASER maximum
  EXPECT_EQ(r.max_range_readings, 4172u);  // the 81.83 m readings
  for (std::size_t k = 1; k < r.passes.size(); ++k) {
    ASSERT_GT(r.passes[k].stamp[0], r.passes[k - 1].stamp[0]) << k;
    ASSERT_EQ(r.passes[k].line[0], k);
  }
}

TEST(ImportCarmen, RegisteredBeamsLieOnTheRaysOfTheLaserPose) {
  // Two scans of three beams (odd count: -90, 0, +90 degrees), the robot at (1, 2) facing +y.
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/a.log", "# a comment\nPARAM robot_front_laser_max 10.0 host 0\nODOM 0 0 0 0 0 0 1 host 1\n" +
                                       flaser({1.0, 2.0, 50.0}, 1.0, 2.0, M_PI / 2, 5.0) +
                                       flaser({3.0, 0.0, 4.0}, 1.0, 2.5, M_PI / 2, 5.5));
  io::ImportedCarmen r = io::import_carmen(dir + "/a.log");
  ASSERT_EQ(r.passes.size(), 2u);
  EXPECT_EQ(r.passes[0].range[2], 0.0f);  // 50 m >= 10 m: no return
  EXPECT_EQ(r.passes[1].range[1], 0.0f);  // 0: no return
  const PoseTrack poses(r.poses);
  SensorParams s;
  s.range_min = 0.05;
  s.range_max = 100.0;
  RegisterParams rp;
  rp.skew_correction = false;
  rp.covariance = false;
  register_pass(r.passes[0], rp, s, Eigen::Isometry3d::Identity(), &poses);
  register_pass(r.passes[1], rp, s, Eigen::Isometry3d::Identity(), &poses);
  // Beam 0 looks to the robot's right (-90 degrees from +y: +x), beam 1 ahead (+y).
  EXPECT_NEAR(r.passes[0].x[0], 2.0, 1e-5);  // theta is written with 6 decimals
  EXPECT_NEAR(r.passes[0].y[0], 2.0, 1e-5);
  EXPECT_NEAR(r.passes[0].x[1], 1.0, 1e-5);
  EXPECT_NEAR(r.passes[0].y[1], 4.0, 1e-5);
  EXPECT_NEAR(r.passes[1].x[2], 1.0 - 4.0, 1e-5);  // beam 2: to the left (-x)
  EXPECT_NEAR(r.passes[1].y[2], 2.5, 1e-5);
  EXPECT_NEAR(r.passes[1].z[2], 0.0, 1e-9);
  EXPECT_EQ(r.passes[0].label[0], Label::kKept);
  EXPECT_EQ(r.passes[0].label[2], Label::kNoReturn);
}

TEST(ImportCarmen, Robotlaser1GivesItsAnglesRemissionsAndRangeLimitAndWinsOverFlaser) {
  const std::string dir = test::fresh_dir();
  // type start fov res max acc mode n r.. m e.. laser_x y th robot_x y th tv rv fsd ssd turn ts host lts
  const std::string rl = "ROBOTLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 5 1 2 3 9 4 5 10 20 30 40 50 0.5 0.25 0.1 0 0 0 0 0 0 0 0 7.5 host 7.5\n";
  write_gz(dir + "/b.log.gz", flaser({1, 2, 3, 4}, 0, 0, 0, 7.5) + rl);
  const io::ImportedCarmen r = io::import_carmen(dir + "/b.log.gz");
  EXPECT_EQ(r.message, "ROBOTLASER1");
  EXPECT_EQ(r.skipped_flaser, 1u);
  ASSERT_EQ(r.passes.size(), 1u);
  const Pass& p = r.passes[0];
  ASSERT_EQ(p.size(), 5u);
  EXPECT_FLOAT_EQ(p.bearing[0], -1.0f);
  EXPECT_FLOAT_EQ(p.bearing[4], 1.0f);
  EXPECT_EQ(p.range[3], 0.0f);  // 9 m >= max_range 8 m
  EXPECT_EQ(p.range[4], 4.0f);
  EXPECT_EQ(p.amplitude[0], 10.0f);
  EXPECT_EQ(p.amplitude[4], 50.0f);
  EXPECT_DOUBLE_EQ(r.poses[0].position.x(), 0.5);  // the laser pose, not the robot's
  EXPECT_DOUBLE_EQ(r.poses[0].position.y(), 0.25);
}

TEST(ImportCarmen, MalformedLinesNameTheFileTheLineAndTheField) {
  const std::string dir = test::fresh_dir();
  const std::string good = flaser({1, 2, 3}, 0, 0, 0, 1.0);
  const auto err = [&](const std::string& text) {
    test::write_text(dir + "/bad.log", "PARAM x 1 host 0\n" + text);
    return error_of(dir + "/bad.log");
  };
  const std::string f = dir + "/bad.log:2: ";
  EXPECT_EQ(err("FLASER 3 1.0 abc 2.0 0 0 0 0 0 0 1.0 host 1.0\n"), f + "FLASER field 4 (range 2 of 3) 'abc': not a number");
  EXPECT_EQ(err("FLASER 3 1.0 2.0 0 0 0 0 0 0 1.0 host 1.0\n"),
            f + "FLASER has 13 fields, expected 14 (3 readings, then x y theta odom_x odom_y odom_theta timestamp host logger_timestamp)");
  EXPECT_EQ(err("FLASER x3 1 2 3\n"), f + "FLASER field 2 (num_readings) 'x3': not a whole number from 0 to 1048576");
  EXPECT_EQ(err("FLASER 0 0 0 0 0 0 0 1 host 1\n"), f + "FLASER field 2 (num_readings) '0': a laser message needs at least one reading");
  EXPECT_EQ(err("FLASER 3 1.0 -2.0 3 0 0 0 0 0 0 1.0 host 1.0\n"),
            f + "FLASER field 4 (range 2 of 3) '-2.0': must be at least 0 and fit a float");
  EXPECT_EQ(err("FLASER 3 1.0 0x10 2.0 0 0 0 0 0 0 1.0 host 1.0\n"), f + "FLASER field 4 (range 2 of 3) '0x10': not a number");
  EXPECT_EQ(err("FLASER 3 1 2 3 0 nan 0 0 0 0 1.0 host 1.0\n"), f + "FLASER field 7 (laser y, m) 'nan': not a finite number");
  EXPECT_EQ(err("FLASER 3 1 2 3 0 0 0 0 0 0 1e999 host 1.0\n"), f + "FLASER field 12 (timestamp, s) '1e999': not a finite number");
  EXPECT_EQ(err("ROBOTLASER1 0 -1 2 0.5 8 0.01 0 2 1 2 1 5 0 0 0 0 0 0 0 0 0 0 0 1 host 1\n"),
            f + "ROBOTLASER1 field 12 (num_remissions) '1': must be 0 or num_readings (2)");
  EXPECT_EQ(err("ROBOTLASER1 0 -1 2 0 8 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 1 host 1\n"),
            f + "ROBOTLASER1 field 5 (angular_resolution, rad) '0': must be more than 0 and at most the fov");
  // Two scans at one time; no laser message at all.
  EXPECT_EQ(err(good + good), dir + "/bad.log:3: FLASER timestamp 1.000000 equals that of line 2: two scans at one time cannot both have their pose");
  EXPECT_EQ(err("ODOM 0 0 0 0 0 0 1 host 1\n"), dir + "/bad.log: no FLASER or ROBOTLASER1 message: not a CARMEN laser log");
  // A truncated gzip file.
  std::string big;
  for (int k = 0; k < 2000; ++k) big += flaser({1, 2, 3, static_cast<double>(k)}, k, 0, 0, k + 1.0);
  write_gz(dir + "/t.log.gz", big);
  std::string gz = test::read_text(dir + "/t.log.gz");
  test::write_text(dir + "/t.log.gz", gz.substr(0, gz.size() / 2));
  EXPECT_NE(error_of(dir + "/t.log.gz").find("t.log.gz: after line"), std::string::npos) << error_of(dir + "/t.log.gz");
  EXPECT_NE(error_of(dir + "/t.log.gz").find("truncated"), std::string::npos) << error_of(dir + "/t.log.gz");
  // A directory is not a log.
  EXPECT_NE(error_of(dir).find("is a directory, not a CARMEN log"), std::string::npos);
}
