// Mixed pixels on real data through the CLI, as a user runs it: pipelines/kurt3d.yaml (import,
// then run) on the organized Kurt3D scans, and `clean-cloud` on scan 0 as an organized and an
// unorganized PCD, scored on scan 0 against references derived from the data itself
// (docs/mixed_pixels.md, "Real data").
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "kurt3d_reference.hpp"
#include <Eigen/Geometry>

#include "pcdp/import/3dtk.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;
using test::run_cli;

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

TEST(Kurt3D, MixedPixelsThroughThePipelineSpareTheGrazingCorridorWallAndTakeTheVeils) {
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
             label = test::column(t, "label"), rng = test::column(t, "range");
  ASSERT_EQ(pass.size(), t.header.points);
  for (const auto* c : {&line, &beam, &label, &rng}) ASSERT_EQ(c->size(), pass.size());
  std::vector<char> mixed(scan.points.size(), 0), seen(scan.points.size(), 0), any(scan.points.size(), 0);
  for (std::size_t k = 0; k < pass.size(); ++k) {
    if (pass[k] != 0) continue;
    const std::size_t i = static_cast<std::size_t>(line[k]) * test::Kurt3DScan::kBeams + static_cast<std::size_t>(beam[k]);
    ASSERT_LT(i, scan.points.size());
    if (scan.valid[i]) {
      ASSERT_NEAR(rng[k], scan.range[i], 1e-3) << "line " << line[k] << " beam " << beam[k];  // the right point
    }
    seen[i] = 1;
    mixed[i] = label[k] == static_cast<double>(Label::kMixedPixel);
    any[i] = label[k] != static_cast<double>(Label::kKept);
  }
  const test::Kurt3DScore all = test::score_kurt3d(scan, any, seen);
  const test::Kurt3DScore sc = test::score_kurt3d(scan, mixed, seen);
  std::cout << "Kurt3D scan 0 through pipelines/kurt3d.yaml, labelled mixed_pixel: right corridor wall " << sc.wall_removed << "/"
            << sc.wall << "; returns inside depth jumps " << sc.jumps_removed() << "/" << sc.jumps()
            << ": on the line through their neighbours " << sc.on_line_removed << "/" << sc.on_line
            << ", off it and far from both lines beside (veils) " << sc.veils_removed << "/" << sc.veils << ", the rest "
            << sc.flat_removed << "/" << sc.flat << "; floor and ceiling interior " << sc.planar_removed << "/" << sc.planar
            << " (by any label: wall " << all.wall_removed << ", floor and ceiling " << all.planar_removed << ")\n";
  test::expect_kurt3d_bars(sc, 0.85, "pipelines/kurt3d.yaml");
}

TEST(Kurt3D, CleanCloudReadsAnOrganizedPcdAsLinesAndTheViewpointsRotationAndKeepsTheWall) {
  // Scan 0 written as a PCD (in our frame: x ahead, y left, z up, NaN for a no-return) with each
  // point's index, cleaned by `clean-cloud`: organized (HEIGHT 226 lines, WIDTH 360 beams) the
  // tests run as in the pipeline; unorganized, along the bands of a range image about the
  // scanner's z, which the PCD VIEWPOINT's rotation places in the cloud.
  const std::string k3d = std::string(PCDP_SHARED_DIR) + "/datasets/kurt3d_3dtk_nodding/";
  const test::Kurt3DScan scan = test::read_kurt3d_scan(k3d + "scan000.3d");
  ASSERT_EQ(scan.points.size(), test::Kurt3DScan::kLines * test::Kurt3DScan::kBeams) << k3d << "scan000.3d";
  const std::string dir = test::fresh_dir("kurt3d_clean_organized");
  // `rotated`: the points in a frame turned so that the scanner's forward axis is the cloud's z
  // (as in the 3DTK file's own frame, whose z is forward): the range image's pole straight ahead.
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(-kPi / 2, Eigen::Vector3d::UnitY()));
  // `shift`: added to every point, the coordinates written as float64 (a georeferenced cloud).
  const auto write = [&](const std::string& path, std::size_t height, bool rotated, const std::string& viewpoint,
                         const Eigen::Vector3d& shift = Eigen::Vector3d::Zero()) {
    const bool f8 = !shift.isZero();
    std::ostringstream o;
    o << "VERSION 0.7\nFIELDS x y z index\nSIZE " << (f8 ? "8 8 8" : "4 4 4") << " 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH "
      << scan.points.size() / height << "\nHEIGHT " << height << "\nVIEWPOINT " << viewpoint << "\nPOINTS " << scan.points.size()
      << "\nDATA ascii\n";
    o.precision(f8 ? 17 : 9);
    for (std::size_t i = 0; i < scan.points.size(); ++i) {
      if (!scan.valid[i]) {
        o << "nan nan nan " << i << "\n";
        continue;
      }
      Eigen::Vector3d p = io::uos_to_ours(scan.points[i] * 100.0);
      if (rotated) p = turn * p;
      p += shift;
      o << p.x() << " " << p.y() << " " << p.z() << " " << i << "\n";
    }
    test::write_text(path, o.str());
  };
  const auto removed_by = [&](const std::string& in, std::string& out, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args = {"clean-cloud", in, "-o", in + ".kept.pcd", "--removed", in + ".removed.pcd"};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = run_cli(args);
    out = r.out;
    EXPECT_EQ(r.exit_code, 0) << r.err;
    std::vector<char> removed(scan.points.size(), 0);
    if (r.exit_code != 0) return removed;
    const io::PcdTable t = io::read_pcd(in + ".removed.pcd");
    for (const double k : test::column(t, "index")) removed.at(static_cast<std::size_t>(k)) = 1;
    return removed;
  };
  std::string out;
  write(dir + "/organized.pcd", test::Kurt3DScan::kLines, false, "0 0 0 1 0 0 0");
  const test::Kurt3DScore org = test::score_kurt3d(scan, removed_by(dir + "/organized.pcd", out), scan.valid);
  EXPECT_NE(out.find("organized, 226 lines of 360 beams"), std::string::npos) << out;
  write(dir + "/unorganized.pcd", 1, false, "0 0 0 1 0 0 0");
  const test::Kurt3DScore uno = test::score_kurt3d(scan, removed_by(dir + "/unorganized.pcd", out), scan.valid);
  EXPECT_NE(out.find("resolution 0.0087 rad"), std::string::npos) << out;
  // The same cloud turned, its VIEWPOINT saying how: the same points go; without it, the range
  // image's elevation bands lie across the scan lines and the wall is cut.
  std::ostringstream vp;
  vp.precision(17);
  vp << "0 0 0 " << turn.w() << " " << turn.x() << " " << turn.y() << " " << turn.z();
  write(dir + "/turned.pcd", 1, true, vp.str());
  const std::vector<char> turned = removed_by(dir + "/turned.pcd", out);
  // The outputs carry the pose they were cleaned with, so cleaning or importing them again needs
  // nothing more.
  for (const std::string f : {"/turned.pcd.kept.pcd", "/turned.pcd.removed.pcd"}) {
    const io::PcdHeader h = io::read_pcd_header(dir + f);
    const double want[7] = {0, 0, 0, turn.w(), turn.x(), turn.y(), turn.z()};
    for (int k = 0; k < 7; ++k) EXPECT_NEAR(h.viewpoint[k], want[k], 1e-12) << f << " VIEWPOINT[" << k << "]";
  }
  write(dir + "/turned_unsaid.pcd", 1, true, "0 0 0 1 0 0 0");
  const test::Kurt3DScore unsaid = test::score_kurt3d(scan, removed_by(dir + "/turned_unsaid.pcd", out), scan.valid);
  const test::Kurt3DScore tur = test::score_kurt3d(scan, turned, scan.valid);
  const auto differ = [](const std::vector<char>& a, const std::vector<char>& b) {
    std::size_t d = 0;
    for (std::size_t i = 0; i < a.size(); ++i) d += (a[i] != 0) != (b[i] != 0);
    return d;
  };
  // --orientation says it where the PCD does not: the same points go.
  std::ostringstream q;
  q.precision(17);
  q << turn.w() << "," << turn.x() << "," << turn.y() << "," << turn.z();
  EXPECT_EQ(differ(removed_by(dir + "/turned_unsaid.pcd", out, {"--orientation", q.str()}), turned), 0u);
  // Organized and turned, the VIEWPOINT saying how: the organized result (the bearings and nods
  // come from the scanner's frame, the tests from ranges and points).
  const std::vector<char> org_mask = removed_by(dir + "/organized.pcd", out);
  write(dir + "/organized_turned.pcd", test::Kurt3DScan::kLines, true, vp.str());
  EXPECT_LE(differ(removed_by(dir + "/organized_turned.pcd", out), org_mask), 5u);
  // Georeferenced: the organized scan 500 km away, the VIEWPOINT there; float64 in, the same result.
  const Eigen::Vector3d far(512767.8, 5403698.8, 404.1);
  std::ostringstream fvp;
  fvp.precision(17);
  fvp << far.x() << " " << far.y() << " " << far.z() << " 1 0 0 0";
  write(dir + "/organized_far.pcd", test::Kurt3DScan::kLines, false, fvp.str(), far);
  EXPECT_LE(differ(removed_by(dir + "/organized_far.pcd", out, {"--resolution", "0.01"}), org_mask), 5u);
  EXPECT_NE(out.find("organized, 226 lines of 360 beams; --resolution not used"), std::string::npos) << out;
  // --unorganized reads the organized file as the unorganized cloud it also is.
  const std::vector<char> uno_mask = removed_by(dir + "/unorganized.pcd", out);
  EXPECT_EQ(differ(removed_by(dir + "/organized.pcd", out, {"--unorganized"}), uno_mask), 0u);
  EXPECT_NE(out.find("resolution 0.0087 rad"), std::string::npos) << out;
  std::cout << "Kurt3D scan 0 through clean-cloud, organized / unorganized / unorganized turned with its VIEWPOINT / turned "
               "without: wall "
            << org.wall_removed << " / " << uno.wall_removed << " / " << tur.wall_removed << " / " << unsaid.wall_removed << " of "
            << org.wall << "; on the line " << org.on_line_removed << " / " << uno.on_line_removed << " / " << tur.on_line_removed
            << " / " << unsaid.on_line_removed << " of " << org.on_line << "; veils " << org.veils_removed << " / "
            << uno.veils_removed << " / " << tur.veils_removed << " / " << unsaid.veils_removed << " of " << org.veils
            << "; floor and ceiling " << org.planar_removed << " / " << uno.planar_removed << " / " << tur.planar_removed << " / "
            << unsaid.planar_removed << " of " << org.planar << "\n";
  test::expect_kurt3d_bars(org, 0.8, "clean-cloud, organized");
  test::expect_kurt3d_bars(uno, 0.8, "clean-cloud, unorganized");
  test::expect_kurt3d_bars(tur, 0.8, "clean-cloud, unorganized and turned, the VIEWPOINT saying so");
  EXPECT_LE(std::abs(static_cast<long>(tur.wall_removed) - static_cast<long>(uno.wall_removed)), 3);
  EXPECT_GT(unsaid.wall_removed, 3 * uno.wall_removed);  // the orientation matters

  // Every cloud needs the scanner's orientation: a VIEWPOINT whose rotation is no rotation is an
  // input error naming the file and the field, and nothing is written; a malformed --orientation
  // is a configuration error found before any file is read.
  write(dir + "/bad.pcd", test::Kurt3DScan::kLines, false, "0 0 0 0 0 0 0");
  const auto r = run_cli({"clean-cloud", dir + "/bad.pcd", "-o", dir + "/bad.kept.pcd"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("bad.pcd: VIEWPOINT's rotation (qw qx qy qz = 0"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad.kept.pcd"));
  const auto r2 = run_cli({"clean-cloud", dir + "/bad.pcd", "-o", dir + "/bad.kept.pcd", "--orientation", "1,0,0"});
  EXPECT_EQ(r2.exit_code, 2) << r2.err;
  EXPECT_NE(r2.err.find("clean-cloud: --orientation '1,0,0' must be a quaternion qw,qx,qy,qz"), std::string::npos) << r2.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad.kept.pcd"));
  // `import cloud` takes the VIEWPOINT as the sensor pose: the same rule.
  const auto ri = run_cli({"import", "cloud", dir + "/bad.pcd", "--output-dir", dir + "/bad_import"});
  EXPECT_EQ(ri.exit_code, 3) << ri.err;
  EXPECT_NE(ri.err.find("bad.pcd: VIEWPOINT's rotation (qw qx qy qz = 0 0 0 0, norm 0) is not a rotation"), std::string::npos) << ri.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad_import"));
  const auto rv = run_cli({"import", "cloud", dir + "/bad.pcd", "--viewpoint", "0,0,0", "--output-dir", dir + "/bad_import"});
  EXPECT_EQ(rv.exit_code, 0) << rv.err;  // --viewpoint is the whole pose: position and the identity rotation
  const auto r3 = run_cli({"clean-cloud", dir + "/no_such.pcd", "-o", dir + "/bad.kept.pcd", "--orientation", "0,0,0,0"});
  EXPECT_EQ(r3.exit_code, 2) << r3.err;
  EXPECT_NE(r3.err.find("whose norm is at least 1e-9 (it has norm 0)"), std::string::npos) << r3.err;
  // A rotation given at any scale is a rotation (its norm is taken without overflow); one near
  // zero is refused with the numbers as written.
  const auto r4 = run_cli({"clean-cloud", dir + "/no_such.pcd", "-o", dir + "/bad.kept.pcd", "--orientation", "1e160,0,0,0"});
  EXPECT_EQ(r4.exit_code, 3) << r4.err;  // past the options: the missing file
  const auto r5 = run_cli({"clean-cloud", dir + "/no_such.pcd", "-o", dir + "/bad.kept.pcd", "--orientation", "1e-30,0,0,0"});
  EXPECT_EQ(r5.exit_code, 2) << r5.err;
  EXPECT_NE(r5.err.find("(it has norm 1e-30)"), std::string::npos) << r5.err;
}
