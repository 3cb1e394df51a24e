// End-to-end: `import carmen` and `import 3dtk --beams-per-line` through the real CLI, and the
// whole fr079 log through pipelines/carmen_fr079.yaml with the label counts docs/real_data.md gives.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;

namespace {
const std::string kFr079 = std::string(PCDP_SHARED_DIR) + "/datasets/carmen_corrected_radish/freiburg-079-corrected.log.gz";
}

TEST(ImportCarmenCli, Fr079ThroughTheShippedPipelineRejectsWhatDocsSay) {
  const std::string dir = test::fresh_dir();
  auto r = test::run_cli({"import", "carmen", kFr079, "--output-dir", dir + "/import"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("imported 4791 FLASER message(s) as planar passes, 1724760 returns (36004 at or beyond the maximum range"),
            std::string::npos)
      << r.out;
  EXPECT_TRUE(fs::exists(dir + "/import/pass_0000.pcd"));
  EXPECT_TRUE(fs::exists(dir + "/import/pass_4790.pcd"));  // names sort in time order
  EXPECT_FALSE(fs::exists(dir + "/import/pass_4791.pcd"));
  r = test::run_cli({"run", std::string(PCDP_SOURCE_DIR) + "/pipelines/carmen_fr079.yaml", "--set",
                     "input.scans=" + dir + "/import/pass_*.pcd", "--set", "input.poses=" + dir + "/import/poses.csv",
                     "--output-dir", dir + "/out", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rep = nlohmann::json::parse(test::read_text(dir + "/out/report.json"));
  const auto& labels = rep["labels"];
  std::printf("fr079, every scan: kept %lld, no_return %lld, mixed_pixel %lld, inconsistent %lld\n",
              labels["kept"].get<long long>(), labels["no_return"].get<long long>(),
              labels["mixed_pixel"].get<long long>(), labels["inconsistent"].get<long long>());
  EXPECT_EQ(rep["input_returns"].get<long long>(), 1724760);
  EXPECT_EQ(labels["no_return"].get<long long>(), 36004);  // the 81.91 m sentinel
  EXPECT_EQ(labels["no_pose"].get<long long>(), 0);        // every scan has its own pose
  EXPECT_EQ(labels["out_of_range"].get<long long>(), 0);
  // docs/real_data.md: 39,081 mixed pixels (2.27 %) and 27 inconsistent; a margin for detector changes.
  EXPECT_GT(labels["mixed_pixel"].get<long long>(), 1724760 / 200);
  EXPECT_LT(labels["mixed_pixel"].get<long long>(), 1724760 * 4 / 100);
  EXPECT_LT(labels["inconsistent"].get<long long>(), 1724760 / 1000);
}

TEST(ImportCarmenCli, BadLogsExitThreeNamingTheLineAndWriteNothing) {
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/bad.log", "PARAM a b\nFLASER 2 1.0 2.0 0 0 0 0 0 0 1.0 host\n");
  auto r = test::run_cli({"import", "carmen", dir + "/bad.log", "--output-dir", dir + "/out"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("bad.log:2: FLASER has 12 fields, expected 13"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out/poses.csv"));
  r = test::run_cli({"import", "carmen", dir + "/bad.log", dir + "/bad.log", "--output-dir", dir + "/out"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("import carmen: expected one log"), std::string::npos) << r.err;
  r = test::run_cli({"import", "carmen", dir + "/bad.log", "--output-dir", dir + "/out", "--beams-per-line", "181"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--beams-per-line is for 3dtk scans"), std::string::npos) << r.err;
  r = test::run_cli({"import", "carmne", dir + "/bad.log", "--output-dir", dir + "/out"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("did you mean 'carmen'"), std::string::npos) << r.err;
}

TEST(Import3dtkCli, BeamsPerLineOverridesAHeaderTheGeometryContradicts) {
  // A 3DTK scan of 20 lines of 181 beams whose header claims 360: refused, then imported with
  // the explicit count.
  const std::string dir = test::fresh_dir();
  std::string text = "360 x 20\n";
  char buf[96];
  for (int l = 0; l < 20; ++l)
    for (int b = 0; b < 181; ++b) {
      const double n = (-10.0 + l) * M_PI / 180, be = -M_PI / 2 + M_PI * b / 180.0, r = 400.0;
      // uos (cm): x = -y_ours, y = z_ours, z = x_ours
      std::snprintf(buf, sizeof buf, "%.5f %.5f %.5f\n", -r * std::sin(be), r * std::cos(be) * std::sin(n),
                    r * std::cos(be) * std::cos(n));
      text += buf;
    }
  test::write_text(dir + "/scan000.3d", text);
  test::write_text(dir + "/scan000.pose", "0 0 0\n0 0 0\n");
  auto r = test::run_cli({"import", "3dtk", dir + "/scan000.3d", "--output-dir", dir + "/out"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("scan000.3d:1: the header says 360 beams per line, the points' geometry 181"), std::string::npos) << r.err;
  r = test::run_cli({"import", "3dtk", dir + "/scan000.3d", "--output-dir", dir + "/out", "--beams-per-line", "181"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("imported 1 3DTK scan(s), 3620 returns"), std::string::npos) << r.out;
  const io::PcdTable t = io::read_pcd(dir + "/out/pass_000.pcd");
  EXPECT_EQ(t.header.width, 181u);
  EXPECT_EQ(t.header.height, 20u);
  r = test::run_cli({"import", "3dtk", dir + "/scan000.3d", "--output-dir", dir + "/out2", "--beams-per-line", "360"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("3620 points is not a whole number of 360-beam lines"), std::string::npos) << r.err;
}
