#include <gtest/gtest.h>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/poses.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
std::string error_of(const std::string& text) {
  const std::string path = test::fresh_dir() + "/poses.csv";
  test::write_text(path, text);
  try {
    io::read_pose_csv(path, RpyOrder::kXyz);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(PoseCsv, ReadsRowsInTheGivenRpyOrder) {
  const std::string path = test::fresh_dir() + "/poses.csv";
  test::write_text(path, "stamp,x,y,z,roll,pitch,yaw\n0,1,2,3,0.1,0.2,0.3\n1.5,4,5,6,0,0,0\n");
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    const PoseTrack t = io::read_pose_csv(path, order);
    ASSERT_EQ(t.size(), 2u);
    EXPECT_DOUBLE_EQ(t.end_stamp(), 1.5);
    EXPECT_TRUE(t.samples()[0].position.isApprox(Eigen::Vector3d(1, 2, 3)));
    EXPECT_TRUE(t.samples()[0].orientation.toRotationMatrix().isApprox(rpy_to_matrix({0.1, 0.2, 0.3}, order), 1e-12));
  }
}

TEST(PoseCsv, RejectsBadInputWithFileLineAndColumn) {
  EXPECT_NE(error_of("").find("the pose file is empty"), std::string::npos);
  EXPECT_NE(error_of("t,x,y,z,roll,pitch,yaw\n").find("header column 1 is 't' but must be 'stamp'"), std::string::npos);
  EXPECT_NE(error_of("stamp,x,y,z,roll,pitch,yaw\n").find("no poses"), std::string::npos);
  std::string e = error_of("stamp,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n1,nan,0,0,0,0,0\n");
  EXPECT_NE(e.find("poses.csv:3: column 'x': 'nan' is not finite"), std::string::npos) << e;
  e = error_of("stamp,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n1,0,0,0,inf,0,0\n");
  EXPECT_NE(e.find(":3: column 'roll': 'inf' is not finite"), std::string::npos) << e;
  e = error_of("stamp,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n");
  EXPECT_NE(e.find(":3: stamp 0 is not after the previous stamp"), std::string::npos) << e;
  e = error_of("stamp,x,y,z,roll,pitch,yaw\n2,0,0,0,0,0,0\n1,0,0,0,0,0,0\n");
  EXPECT_NE(e.find("strictly increasing"), std::string::npos) << e;
  e = error_of("stamp,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n");
  EXPECT_NE(e.find(":2: has 6 columns but the header has 7"), std::string::npos) << e;
  e = error_of("stamp,x,y,z,roll,pitch,yaw\n0,0,0,zero,0,0,0\n");
  EXPECT_NE(e.find("column 'z': 'zero' is not a number"), std::string::npos) << e;
}

TEST(PoseCsv, MissingFileAndDirectory) {
  const std::string dir = test::fresh_dir();
  EXPECT_THROW(io::read_pose_csv(dir + "/nope.csv", RpyOrder::kXyz), InputError);
  try {
    io::read_pose_csv(dir, RpyOrder::kXyz);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos);
  }
}
