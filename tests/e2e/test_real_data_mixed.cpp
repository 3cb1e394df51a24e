// Mixed pixels on real data through the CLI, as a user runs it: pipelines/kurt3d.yaml (import,
// then run) on the organized Kurt3D scans, scored on scan 0 against references derived from the
// data itself (docs/mixed_pixels.md, "Real data").
#include <gtest/gtest.h>

#include <iostream>
#include <string>
#include <vector>

#include "kurt3d_reference.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;
using test::run_cli;

TEST(Kurt3D, ThePipelineKeepsTheGrazingCorridorWallAndRemovesTheVeils) {
  const std::string k3d = std::string(PCDP_SHARED_DIR) + "/datasets/kurt3d_3dtk_nodding/";
  const std::string yaml = std::string(PCDP_SOURCE_DIR) + "/pipelines/kurt3d.yaml";
  const std::string dir = test::fresh_dir("kurt3d_mixed");
  const auto args = test::prepare_args(yaml, dir + "/import");
  ASSERT_FALSE(args.empty()) << yaml << " has no prepare line";
  auto r = run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_cli({"run", yaml, "--set", "input.scans=" + dir + "/import/pass_*.pcd", "--set", "input.poses=" + dir + "/import/poses.csv",
               "--output-dir", dir + "/run", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;

  // Scan 0 (pass 0, its lines numbered from 0): each return's label from returns.pcd.
  const test::Kurt3DScan scan = test::read_kurt3d_scan(k3d + "scan000.3d");
  ASSERT_EQ(scan.points.size(), test::Kurt3DScan::kLines * test::Kurt3DScan::kBeams) << k3d << "scan000.3d";
  const io::PcdTable t = io::read_pcd(dir + "/run/returns.pcd");
  const auto pass = test::column(t, "pass"), line = test::column(t, "line"), beam = test::column(t, "beam"),
             label = test::column(t, "label");
  std::vector<char> mixed(scan.points.size(), 0), seen(scan.points.size(), 0);
  for (std::size_t k = 0; k < pass.size(); ++k) {
    if (pass[k] != 0) continue;
    const std::size_t i = static_cast<std::size_t>(line[k]) * test::Kurt3DScan::kBeams + static_cast<std::size_t>(beam[k]);
    ASSERT_LT(i, scan.points.size());
    seen[i] = 1;
    mixed[i] = label[k] == static_cast<double>(Label::kMixedPixel);
  }
  const test::Kurt3DScore sc = test::score_kurt3d(scan, mixed, seen);
  std::cout << "Kurt3D scan 0 through pipelines/kurt3d.yaml, labelled mixed_pixel: right corridor wall " << sc.wall_removed << "/"
            << sc.wall << "; returns inside depth jumps " << sc.jumps_removed() << "/" << sc.jumps()
            << ": on the line through their neighbours " << sc.on_line_removed << "/" << sc.on_line
            << ", off it and rough across lines (veils) " << sc.veils_removed << "/" << sc.veils << ", off it and flat across "
            << sc.flat_removed << "/" << sc.flat << "; floor and ceiling interior " << sc.planar_removed << "/" << sc.planar << "\n";
  ASSERT_GT(sc.wall, 500u);
  EXPECT_LE(static_cast<double>(sc.wall_removed), 0.10 * static_cast<double>(sc.wall));  // the wall is not gutted
  ASSERT_GT(sc.on_line, 50u);
  EXPECT_LE(static_cast<double>(sc.on_line_removed), 0.15 * static_cast<double>(sc.on_line));  // planes at grazing incidence stay
  ASSERT_GT(sc.veils, 25u);
  EXPECT_GE(static_cast<double>(sc.veils_removed), 0.85 * static_cast<double>(sc.veils));  // the veils go
  ASSERT_GT(sc.planar, 5000u);
  EXPECT_LE(static_cast<double>(sc.planar_removed), 0.01 * static_cast<double>(sc.planar));  // the 1 % budget
}
