// `import rosbag2` with poses from tf, through the CLI, on small bags written by the test
// (tests/support/rosbag2_test_bag.hpp): poses.csv holds the /tf transforms (positions, and
// roll/pitch/yaw in rpy_order xyz equal to the angles the quaternions were made of), a chain
// map -> odom -> base_link composed, the frame choice's errors exit 2, a truncated TFMessage exit 3.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "rosbag2_test_bag.hpp"
#include "test_support.hpp"

using namespace pcdp;
using test::run_cli;

namespace {
/// The rows of poses.csv: stamp, x, y, z, roll, pitch, yaw.
std::vector<std::vector<double>> pose_rows(const std::string& path) {
  std::istringstream in(test::read_text(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "stamp,x,y,z,roll,pitch,yaw");
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::istringstream ls(line);
    std::string f;
    while (std::getline(ls, f, ',')) row.push_back(std::stod(f));
    EXPECT_EQ(row.size(), 7u) << line;
    rows.push_back(row);
  }
  return rows;
}
}  // namespace

TEST(Rosbag2Tf, PosesComeFromTheOnlyTfPairWithTheirAngles) {
  test::rosbag2::TfBagOptions o;
  o.map_odom = false;
  const std::string dir = test::fresh_dir();
  const std::string bag = test::rosbag2::tf_bag(dir, o);
  const auto r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/out"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("poses tf odom:base_link (81; odom:base_link (/tf))"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("poses.csv, rpy_order xyz"), std::string::npos) << r.out;
  const auto rows = pose_rows(dir + "/out/poses.csv");
  ASSERT_EQ(rows.size(), 81u);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const double s = 0.05 * static_cast<double>(k);
    EXPECT_NEAR(rows[k][0] - rows[0][0], s, 1e-9);
    EXPECT_NEAR(rows[k][1], s, 1e-12) << k;
    EXPECT_NEAR(rows[k][2], 0.5 * s, 1e-12) << k;
    EXPECT_NEAR(rows[k][3], 0.1, 1e-12) << k;
    EXPECT_NEAR(rows[k][4], -0.03, 1e-12) << k;  // roll
    EXPECT_NEAR(rows[k][5], 0.05, 1e-12) << k;   // pitch
    EXPECT_NEAR(rows[k][6], 0.2 * s, 1e-12) << k;  // yaw
  }
}

TEST(Rosbag2Tf, TheFramesOptionComposesAChainAndItsErrorsExit2) {
  const std::string dir = test::fresh_dir();
  const std::string bag = test::rosbag2::tf_bag(dir);
  // Two pairs on /tf: the choice is the user's.
  auto r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/x"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("has 2 transforms on /tf (map:odom, odom:base_link): choose the one that becomes T_M_V with "
                       "--tf-frames PARENT:CHILD"),
            std::string::npos)
      << r.err;
  r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/x", "--tf-frames", "map:base_lnk"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--tf-frames map:base_lnk: no chain of transforms from map down to base_lnk"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("tf pairs: map:odom (/tf), odom:base_link (/tf), base_link:laser (/tf_static)"), std::string::npos)
      << r.err;
  r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/x", "--tf-frames", "map"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--tf-frames map: expected PARENT:CHILD"), std::string::npos) << r.err;
  r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/x", "--tf-frames", "map:base_link", "--odom-topic", "/odom"});
  EXPECT_EQ(r.exit_code, 2);
  r = run_cli({"import", "rplidar", dir, "--output-dir", dir + "/x", "--tf-frames", "map:base_link"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--tf-frames are for rosbag2"), std::string::npos) << r.err;

  // map -> odom -> base_link, checked against the two transforms composed here.
  r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/out", "--tf-frames", "map:base_link"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("poses tf map:base_link (81; map:odom (/tf), odom:base_link (/tf))"), std::string::npos) << r.out;
  const auto rows = pose_rows(dir + "/out/poses.csv");
  ASSERT_EQ(rows.size(), 81u);
  for (std::size_t k = 0; k < rows.size(); k += 10) {
    const double s = 0.05 * static_cast<double>(k);
    const Eigen::Isometry3d T = test::rosbag2::map_odom(s) * test::rosbag2::odom_base(s);
    EXPECT_NEAR(rows[k][1], T.translation().x(), 1e-9) << k;
    EXPECT_NEAR(rows[k][2], T.translation().y(), 1e-9) << k;
    EXPECT_NEAR(rows[k][3], T.translation().z(), 1e-9) << k;
    // The file's angles, rebuilt in order xyz, give the composed rotation.
    const Eigen::Matrix3d R = test::rosbag2::xyz_quaternion(rows[k][4], rows[k][5], rows[k][6]).toRotationMatrix();
    EXPECT_LT((R - T.rotation()).norm(), 1e-9) << k;
  }
}

TEST(Rosbag2Tf, ATruncatedTfMessageExits3NamingTheTopic) {
  test::rosbag2::TfBagOptions o;
  o.truncate = true;
  const std::string dir = test::fresh_dir();
  const std::string bag = test::rosbag2::tf_bag(dir, o);
  const auto r = run_cli({"import", "rosbag2", bag, "--output-dir", dir + "/out", "--tf-frames", "map:base_link"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("tfbag_0.db3: topic /tf, message 10 (id "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("byte 180: truncated: transforms.transform.rotation.w needs 8 byte(s), 3 left"), std::string::npos)
      << r.err;
}
