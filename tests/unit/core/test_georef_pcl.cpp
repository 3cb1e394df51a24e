// PCL reads the products of a georeferenced run: the "# map_origin" header line is skipped as a
// comment, the points (relative to the origin) and the identity VIEWPOINT come through.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include "pcdp/io/outputs.hpp"
#include "pcdp/core/pass.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(GeorefPcl, PclReadsACloudWithAMapOrigin) {
  const std::string dir = test::fresh_dir();
  Pass p = test::line_pass({5.0f, 6.0f}, {100.0f, 90.0f});
  p.x = {12.345678, -3.25};
  p.y = {-3.5, 7.0};
  p.z = {100.25, 99.0};
  {
    io::CloudWriter c(dir + "/cloud.pcd", Eigen::Vector3d(500000.0, 5300000.0, 0.0));
    c.append(p);
    c.close();
  }
  ASSERT_NE(test::read_text(dir + "/cloud.pcd").find("# map_origin 500000 5300000 0\n"), std::string::npos);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(dir + "/cloud.pcd", cloud), 0);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_FLOAT_EQ(cloud[0].x, 12.345678f);
  EXPECT_FLOAT_EQ(cloud[1].y, 7.0f);
  EXPECT_EQ(cloud.sensor_origin_.head<3>().norm(), 0.0f);  // VIEWPOINT is not the origin
}
