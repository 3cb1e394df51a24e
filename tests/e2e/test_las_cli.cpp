// LAS and Cartesian clouds through the CLI: `import cloud` of the Autzen LAS files (units said,
// implausible viewpoints refused), ISPRS samp11 through pipelines/cartesian_cloud.yaml scored
// against its ground reference, and clean-cloud's output formats and viewpoint check.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "pcdp/fusion/elevation.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/import/scans.hpp"
#include "pcdp/io/las.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {
const std::string kAutzen = std::string(PCDP_SHARED_DIR) + "/datasets/pdal_autzen/";
const std::string kIsprs = std::string(PCDP_SHARED_DIR) + "/datasets/isprs_terrain_pcl/";

}  // namespace

TEST(LasCli, ImportCloudReadsAutzenAndSaysItsUnits) {
  const std::string dir = test::fresh_dir("las_autzen");
  // No viewpoint: LAS carries none, and 0,0,0 is hundreds of km from the points: refused, exit 2,
  // with a viewpoint to try.
  auto r = run_cli({"import", "cloud", kAutzen + "autzen_trim.las", "--output-dir", dir + "/a"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("autzen_trim.las: the viewpoint 0.000,0.000,0.000 (none given: PLY and LAS carry no viewpoint) is farther "
                       "than the maximum range 1000.000 m from 110000 of the 110000 points"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("pass --viewpoint X,Y,Z"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/a"));
  // The suggested viewpoint, 500 m up: imported in metres (the file declares feet).
  r = run_cli({"import", "cloud", kAutzen + "autzen_trim.las", "--viewpoint", "194032.8,258841.2,658.7", "--output-dir", dir + "/a"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("LAS 1.2, point format 3, 110000 points; units: foot (GeoKey ProjLinearUnitsGeoKey = 9002"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("coordinates scaled to metres"), std::string::npos) << r.out;
  EXPECT_EQ(io::read_pcd_header(dir + "/a/pass_000.pcd").points, 110000u);
  // autzen-thin declares no unit: taken as given unless --unit-scale says otherwise.
  r = run_cli({"import", "cloud", kAutzen + "autzen-thin.las", "--viewpoint", "637291.9,851210.9,1094", "--max-range", "4000",
               "--output-dir", dir + "/b"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("units: not declared (no GeoKey or WKT VLR); taken as metres: pass --unit-scale 0.3048 if they are feet"),
            std::string::npos)
      << r.out;
  r = run_cli({"import", "cloud", kAutzen + "autzen-thin.las", "--unit-scale", "0.3048", "--viewpoint", "194246.6,259449.1,681", "--max-range", "2000",
               "--output-dir", dir + "/c"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("coordinates scaled by --unit-scale 0.304800"), std::string::npos) << r.out;
  EXPECT_EQ(io::read_pcd_header(dir + "/c/pass_000.pcd").points, 10653u);
  // A LAS file named otherwise is still read as LAS (by its signature), and LAZ is refused.
  fs::copy_file(kAutzen + "autzen-thin.las", dir + "/thin.dat");
  r = run_cli({"import", "cloud", dir + "/thin.dat", "--output-dir", dir + "/d"});
  EXPECT_EQ(r.exit_code, 2) << r.err;  // read as LAS: the viewpoint check, not a PCD parse error
  EXPECT_NE(r.err.find("PLY and LAS carry no viewpoint"), std::string::npos) << r.err;
  fs::copy_file(kAutzen + "autzen-thin.las", dir + "/thin.laz");
  r = run_cli({"import", "cloud", dir + "/thin.laz", "--output-dir", dir + "/e"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("LAZ (compressed LAS) is not supported"), std::string::npos) << r.err;
}

// ISPRS samp11 through the template pipeline: the imports's viewpoint check, then the grid's
// coverage and its error against the -ground reference. The grid is a DSM (the top surface of all
// returns): over bare ground it should match the reference, over buildings and trees it is above it.
TEST(LasCli, Samp11ThroughTheCartesianTemplateIsADsmOverTheGround) {
  const std::string dir = test::fresh_dir("cartesian_samp11");
  auto r = run_cli({"import", "cloud", kIsprs + "samp11-utm.pcd", "--output-dir", dir + "/bad"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("(the PCD VIEWPOINT) is farther than the maximum range"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("e.g. above the centre, 512767.812,5403698.750,404.080"), std::string::npos) << r.err;

  const std::string yaml = std::string(PCDP_SOURCE_DIR) + "/pipelines/cartesian_cloud.yaml";
  const auto args = test::prepare_args(yaml, dir + "/import");
  ASSERT_FALSE(args.empty());
  r = run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"run", yaml, "--set", "input.scans=" + dir + "/import/pass_*.pcd", "--set", "input.poses=" + dir + "/import/poses.csv",
               "--output-dir", dir + "/run", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(io::read_pcd_header(dir + "/run/cloud.pcd").points, 38010u);  // every point in range and kept

  const ElevationGrid g = io::read_elevation_geotiff(dir + "/run/elevation.tif");
  std::int64_t ix0, iy0, ix1, iy1;
  ASSERT_TRUE(g.bounds(ix0, iy0, ix1, iy1));
  std::size_t cells = 0, filled = 0;
  for (std::int64_t iy = iy0; iy <= iy1; ++iy)
    for (std::int64_t ix = ix0; ix <= ix1; ++ix) {
      ++cells;
      double e, v;
      const ElevationCell* c = g.find(ix, iy);
      if (c && g.surface(*c, e, v)) ++filled;
    }
  const io::PcdTable ground = io::read_pcd(kIsprs + "samp11-utm-ground.pcd");
  const auto gx = test::column(ground, "x"), gy = test::column(ground, "y"), gz = test::column(ground, "z");
  std::vector<double> d;
  for (std::size_t i = 0; i < gx.size(); ++i) {
    double e, v;
    const ElevationCell* c = g.find(g.cell_index(gx[i]), g.cell_index(gy[i]));
    if (c && g.surface(*c, e, v)) d.push_back(e - gz[i]);
  }
  std::sort(d.begin(), d.end());
  const auto pct = [&](double p) { return d[static_cast<std::size_t>(p * static_cast<double>(d.size() - 1))]; };
  double sq = 0;
  std::size_t within = 0;
  for (double x : d) {
    sq += x * x;
    within += std::abs(x) <= 0.5;
  }
  const double coverage = static_cast<double>(filled) / static_cast<double>(cells);
  const double ground_covered = static_cast<double>(d.size()) / static_cast<double>(gx.size());
  std::printf("samp11 DSM: %zu x %zu cells of %.1f m, %.1f %% with a surface; ground reference: %zu points, %.1f %% in a "
              "filled cell; DSM - ground: median %.3f m, 10th pct %.3f m, 90th pct %.3f m, RMS %.3f m, %.1f %% within 0.5 m\n",
              static_cast<std::size_t>(ix1 - ix0 + 1), static_cast<std::size_t>(iy1 - iy0 + 1), g.resolution(), 100 * coverage,
              gx.size(), 100 * ground_covered, pct(0.5), pct(0.1), pct(0.9), std::sqrt(sq / static_cast<double>(d.size())),
              100.0 * static_cast<double>(within) / static_cast<double>(d.size()));
  EXPECT_GT(coverage, 0.9);
  // The ground is part of the cloud, so its points lie in filled cells, but for a few on a cell
  // edge (the float32 northings come in 0.5 m steps, on the 2 m edges too) that fall to the other side.
  EXPECT_GT(ground_covered, 0.995);
  EXPECT_GE(pct(0.1), -0.6);       // a DSM is never far below the ground it contains
  EXPECT_LT(std::abs(pct(0.5)), 0.5);
  EXPECT_GT(pct(0.9), 0.0);        // and is above it where trees and buildings stand
}

TEST(LasCli, CleanCloudWritesTheFormatItsExtensionNames) {
  const std::string in = std::string(PCDP_SHARED_DIR) + "/datasets/pcl_table_scene_lms400/table_scene_lms400_downsampled.pcd";
  const std::string dir = test::fresh_dir("clean_formats");
  auto r = run_cli({"clean-cloud", in, "-o", dir + "/k.pcd", "--resolution", "0.005", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::uint64_t kept = io::read_pcd_header(dir + "/k.pcd").points;
  r = run_cli({"clean-cloud", in, "-o", dir + "/k.ply", "--removed", dir + "/r.las", "--resolution", "0.005", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<Eigen::Vector3d> xyz;
  std::vector<float> amp;
  io::read_ply(dir + "/k.ply", xyz, amp);
  EXPECT_EQ(xyz.size(), kept);
  EXPECT_EQ(amp.size(), kept);  // the table scene has intensity
  EXPECT_EQ(test::read_text(dir + "/k.ply").rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  const io::LasCloud las = io::read_las(dir + "/r.las");
  EXPECT_EQ(las.xyz.size() + kept, io::read_pcd_header(in).points);
  EXPECT_GT(las.xyz.size(), 0u);
  // Any other extension: exit 2 naming it and the supported ones, nothing written.
  r = run_cli({"clean-cloud", in, "-o", dir + "/k.xyz"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("clean-cloud --output '" + dir + "/k.xyz': extension '.xyz' is not a cloud format this writes; use .pcd, .ply"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir + "/k.xyz"));
  r = run_cli({"clean-cloud", in, "-o", dir + "/k2.pcd", "--removed", dir + "/r.laz"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("LAZ, compressed LAS, is not written"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/k2.pcd"));
}

// The README's old example, `clean-cloud cloud.pcd --viewpoint 0,0,0` on the pipeline's own
// cloud, cut a third of it (nearly all valid ground): the cloud was measured from a moving
// scanner, so no single viewpoint fits. Its `range` field says so, and the command refuses.
TEST(LasCli, CleanCloudRefusesAViewpointThePointsRangesContradict) {
  const std::string dir = test::fresh_dir("clean_viewpoint");
  auto r = run_cli({"run", std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml", "--output-dir", dir + "/run", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"clean-cloud", dir + "/run/cloud.pcd", "-o", dir + "/clean.pcd", "--viewpoint", "0,0,0"});
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("cloud.pcd: the points were not measured from the viewpoint 0.000000,0.000000,0.000000 (--viewpoint)"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("stage reject_mixed_pixels"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/clean.pcd"));
  // A single pass seen from a static scanner at the origin (a simulated scan with its VIEWPOINT):
  // the ranges agree and the command runs.
  const std::string one = dir + "/one.pcd";
  {
    io::PcdWriter w(one + ".tmp", {{"x", 'F', 4, 1}, {"y", 'F', 4, 1}, {"z", 'F', 4, 1}, {"range", 'F', 4, 1}});
    for (int i = 0; i < 400; ++i) {
      const double b = -0.8 + 0.004 * i, rr = 5.0 + 0.001 * i;
      const float row[4] = {static_cast<float>(rr * std::cos(b)), static_cast<float>(rr * std::sin(b)), -1.0f,
                            static_cast<float>(std::sqrt(rr * rr + 1.0))};
      w.append(reinterpret_cast<const std::uint8_t*>(row), 1);
    }
    w.close();
  }
  fs::rename(one + ".tmp", one);
  r = run_cli({"clean-cloud", one, "-o", dir + "/one_clean.pcd"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST(LasCli, MergeRefusesAnOutputThatIsNotATiff) {
  const std::string dir = test::fresh_dir("merge_ext");
  const auto r = run_cli({"merge", dir + "/a.tif", dir + "/b.tif", "-o", dir + "/m.ply"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("merge --output '" + dir + "/m.ply': extension '.ply'; merge writes a GeoTIFF: use .tif or .tiff"),
            std::string::npos)
      << r.err;
}

TEST(LasCli, CleanCloudToLasNamesAStrayPointAndCountsTheUnwritable) {
  const std::string dir = test::fresh_dir();
  // 20 points on a line 10 m ahead, then one more: far away (1e38 m) or with an infinite x.
  const auto cloud = [&](const std::string& name, const std::string& last) {
    std::string body;
    for (int i = 0; i < 20; ++i) body += "10 " + std::to_string(0.05 * i) + " 0\n";
    body += last + "\n";
    test::write_text(dir + "/" + name,
                     "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 21\nHEIGHT 1\n"
                     "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 21\nDATA ascii\n" + body);
    return dir + "/" + name;
  };
  auto r = run_cli({"clean-cloud", cloud("far.pcd", "1e38 0 0"), "-o", dir + "/far.las"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("far.pcd: points "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" and 20 lie 9.99999968e+37 m apart along x"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("spans at most 4,294 km"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/far.las"));
  r = run_cli({"clean-cloud", cloud("inf.pcd", "inf 0 0"), "-o", dir + "/inf.las"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("1 point(s) with a non-finite coordinate are not in the LAS output"), std::string::npos) << r.err;
  // The PLY keeps it, so says nothing.
  r = run_cli({"clean-cloud", dir + "/inf.pcd", "-o", dir + "/inf.ply"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("not in the LAS output"), std::string::npos) << r.err;
}
