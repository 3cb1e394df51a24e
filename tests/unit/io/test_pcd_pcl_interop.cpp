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

#include "pcdp/import/scans.hpp"

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

#include <map>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/pipeline.hpp"

TEST(PclInterop, CloudPcdLoadsIntoPointXYZIWithTheAmplitudeAsIntensity) {
  // A pipeline run's cloud.pcd (and returns.pcd) into pcl::PointXYZI: PCL fills a field by its
  // name, so the amplitude reaches `intensity` only if the file has a field of that name (beside
  // `amplitude`, the data contract's name).
  const std::string dir = test::fresh_dir();
  const sim::SimConfig cfg = test::small_sim_config();
  sim::write_run(sim::simulate(cfg), cfg, dir);
  test::write_text(dir + "/p.yaml", test::pipeline_yaml(cfg, dir, dir + "/out"));
  (void)Pipeline::prepare(load_pipeline(dir + "/p.yaml")).run();

  // The amplitude of every input return, by (line, beam).
  std::map<std::pair<double, double>, double> amp;
  for (int k = 0; k < static_cast<int>(cfg.passes); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "/pass_%03d.pcd", k);
    const io::PcdTable in = io::read_pcd(dir + name);
    const auto line = test::column(in, "line"), beam = test::column(in, "beam"), a = test::column(in, "amplitude");
    for (std::size_t i = 0; i < line.size(); ++i) amp[{line[i], beam[i]}] = a[i];
  }
  ASSERT_GT(amp.size(), 1000u);

  for (const char* product : {"cloud.pcd", "returns.pcd"}) {
    const std::string path = dir + "/out/" + product;
    pcl::PointCloud<pcl::PointXYZI> cloud;
    ASSERT_EQ(pcl::io::loadPCDFile<pcl::PointXYZI>(path, cloud), 0) << product;
    const io::PcdTable t = io::read_pcd(path);
    ASSERT_EQ(cloud.size(), t.header.points) << product;
    EXPECT_GE(t.header.field_index("amplitude"), 0) << product << ": the data contract's name";
    ASSERT_GT(cloud.size(), 1000u) << product;
    const auto line = test::column(t, "line"), beam = test::column(t, "beam"), x = test::column(t, "x");
    std::size_t nonzero = 0, compared = 0, mismatched = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const auto it = amp.find({line[i], beam[i]});
      ASSERT_NE(it, amp.end()) << product << " row " << i;
      const float want = static_cast<float>(it->second);
      if (std::isnan(want)) continue;
      ++compared;
      nonzero += want != 0.0f;  // PCL leaves a field it does not find at 0
      mismatched += cloud[i].intensity != want;
      if (std::isfinite(x[i])) {
        EXPECT_FLOAT_EQ(cloud[i].x, static_cast<float>(x[i])) << product << " row " << i;
      }
    }
    EXPECT_GT(compared, cloud.size() / 2) << product;
    EXPECT_EQ(mismatched, 0u) << product << ": PCL's intensity is not the return's amplitude";
    EXPECT_GT(nonzero, compared / 2) << product << ": too few non-zero amplitudes for the comparison to mean anything";
  }
}
