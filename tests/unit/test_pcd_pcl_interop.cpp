// Our PCD reader against PCL's writer (all three encodings), and PCL's reader against our writer.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cmath>

#include "pcdp/io/pcd.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(PclInterop, OurReaderReadsWhatPclWritesInEveryEncoding) {
  pcl::PointCloud<pcl::PointXYZI> cloud;
  cloud.width = 50;
  cloud.height = 4;
  for (int i = 0; i < 200; ++i) {
    pcl::PointXYZI p;
    p.x = 0.5f * static_cast<float>(i);
    p.y = std::sin(static_cast<float>(i));
    p.z = -static_cast<float>(i) / 7.0f;
    p.intensity = static_cast<float>(i % 17);
    cloud.push_back(p);
  }
  cloud.width = 50;
  cloud.height = 4;
  const std::string dir = test::fresh_dir();
  for (const char* enc : {"ascii", "binary", "binary_compressed"}) {
    const std::string path = dir + "/" + enc + ".pcd";
    const std::string e = enc;
    if (e == "ascii") pcl::io::savePCDFileASCII(path, cloud);
    else if (e == "binary") pcl::io::savePCDFileBinary(path, cloud);
    else pcl::io::savePCDFileBinaryCompressed(path, cloud);
    const io::PcdTable t = io::read_pcd(path);
    EXPECT_EQ(t.header.points, 200u) << enc;
    EXPECT_EQ(t.header.width, 50u) << enc;
    const auto x = test::column(t, "x"), z = test::column(t, "z"), in = test::column(t, "intensity");
    ASSERT_EQ(x.size(), 200u);
    for (int i = 0; i < 200; ++i) {
      EXPECT_NEAR(x[static_cast<std::size_t>(i)], cloud[static_cast<std::size_t>(i)].x, 1e-5) << enc;
      EXPECT_NEAR(z[static_cast<std::size_t>(i)], cloud[static_cast<std::size_t>(i)].z, 1e-5) << enc;
      EXPECT_EQ(in[static_cast<std::size_t>(i)], cloud[static_cast<std::size_t>(i)].intensity) << enc;
    }
  }
}

TEST(PclInterop, PclReadsOurWriterOutput) {
  const std::string dir = test::fresh_dir();
  const std::string path = dir + "/ours.pcd";
  {
    io::PcdWriter w(path, {{"x", 'F', 4, 1}, {"y", 'F', 4, 1}, {"z", 'F', 4, 1}, {"label", 'U', 1, 1}});
    for (int i = 0; i < 10; ++i) {
      std::uint8_t row[13];
      const float v[3] = {static_cast<float>(i), 2.0f * static_cast<float>(i), -1.0f};
      std::memcpy(row, v, 12);
      row[12] = static_cast<std::uint8_t>(i);
      w.append(row, 1);
    }
    w.close();
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path, cloud), 0);
  ASSERT_EQ(cloud.size(), 10u);
  EXPECT_FLOAT_EQ(cloud[7].y, 14.0f);
}

#include <pcl/io/ply_io.h>

#include "pcdp/io/import_scans.hpp"

TEST(PclInterop, OurPlyReaderReadsWhatPclWrites) {
  pcl::PointCloud<pcl::PointXYZI> cloud;
  for (int i = 0; i < 300; ++i) {
    pcl::PointXYZI p;
    p.x = 0.25f * static_cast<float>(i);
    p.y = std::cos(static_cast<float>(i));
    p.z = -static_cast<float>(i) / 3.0f;
    p.intensity = static_cast<float>(i % 23);
    cloud.push_back(p);
  }
  const std::string dir = test::fresh_dir();
  for (const bool binary : {false, true}) {
    const std::string path = dir + (binary ? "/b.ply" : "/a.ply");
    pcl::PLYWriter w;
    ASSERT_EQ(w.write(path, cloud, binary, false), 0);
    std::vector<Eigen::Vector3d> xyz;
    std::vector<float> in;
    io::read_ply(path, xyz, in);
    ASSERT_EQ(xyz.size(), 300u) << binary;
    ASSERT_EQ(in.size(), 300u) << binary;
    for (std::size_t i = 0; i < 300; ++i) {
      EXPECT_NEAR(xyz[i].x(), cloud[i].x, 1e-5 * std::max(1.0f, std::fabs(cloud[i].x))) << binary;  // ASCII: 6 digits
      EXPECT_NEAR(xyz[i].z(), cloud[i].z, 1e-5 * std::max(1.0f, std::fabs(cloud[i].z))) << binary;
      EXPECT_EQ(in[i], cloud[i].intensity) << binary;
    }
  }
}
