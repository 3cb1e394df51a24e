// Outputs a user's mistake must not destroy or mix up, through the CLI: an output file named
// like an input, a re-import into a folder of an earlier import, a georeferenced cloud imported
// again, and the run's CRS in report.json.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "pcdp/io/pcd.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {

struct SimRun {
  sim::SimConfig cfg;
  std::string dir, yaml;
};

/// A small simulated run folder with a pipeline that fuses an elevation grid.
SimRun small_run(const std::string& tag, double faster = 0.0) {
  SimRun r;
  r.cfg = test::small_sim_config();
  r.cfg.motion.speed += faster;  // another drive over the same scene
  r.dir = test::fresh_dir(tag);
  const sim::SimResult s = sim::simulate(r.cfg);
  sim::write_run(s, r.cfg, r.dir);
  sim::write_truth(s, r.cfg, r.dir);  // for evaluate
  r.yaml = r.dir + "/pipeline.yaml";
  test::write_text(r.yaml, test::pipeline_yaml(r.cfg, r.dir, r.dir + "/out") + "  - type: fuse_elevation\n");
  return r;
}

std::vector<std::string> pass_files(const std::string& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().rfind("pass_", 0) == 0) v.push_back(e.path().filename().string());
  return v;
}

}  // namespace

TEST(OutputsGuard, AnOutputNamedLikeAnInputIsRefusedBeforeAnyWork) {
  const SimRun r = small_run("guard");
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  ASSERT_EQ(run_cli({"run", r.yaml, "-q", "--output-dir", r.dir + "/b", "--set", "input.scans=" + r.dir + "/pass_001.pcd"}).exit_code, 0);
  const std::string a = r.dir + "/out/elevation.tif", b = r.dir + "/b/elevation.tif";
  const std::string a_state = r.dir + "/out/elevation.state.tif";
  const std::string before_a = test::read_text(a), before_state = test::read_text(a_state), yaml = test::read_text(r.yaml);
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"merge", a, b, "-o", r.dir + "/m.tif", "--png", a}, "must end in .png"},
      {{"merge", a, b, "-o", r.dir + "/m.tif", "--png", r.dir + "/out/elevation.png.png"}, ""},  // fine: a new name
      {{"merge", a, b, "-o", a_state}, "is an input of the command"},
      {{"merge", a, b, "-o", r.dir + "/new.state.tif"}, "merge state"},
      {{"merge", a, b, "-o", b}, "is an input of the command"},
      {{"error-budget", r.yaml, "--svg", r.yaml}, "must end in .svg"},
      {{"evaluate", "--truth", r.dir, "--run", r.dir + "/out", "--json", r.dir + "/out/returns.pcd"}, "must end in .json"},
  };
  for (const auto& c : cases) {
    std::string line;
    for (const auto& s : c.args) line += s + " ";
    const auto res = run_cli(c.args);
    if (c.says.empty()) {
      EXPECT_EQ(res.exit_code, 0) << line << res.err;
      continue;
    }
    EXPECT_EQ(res.exit_code, 2) << line << res.err;
    EXPECT_NE(res.err.find(c.says), std::string::npos) << line << res.err;
  }
  EXPECT_EQ(test::read_text(a), before_a);
  EXPECT_EQ(test::read_text(a_state), before_state);
  EXPECT_EQ(test::read_text(r.yaml), yaml);
}

TEST(OutputsGuard, AnInputInTheOutputFolderUnderAProductsNameIsRefusedAndKept) {
  const SimRun r = small_run("inputs");
  fs::create_directories(r.dir + "/z");
  fs::copy_file(r.dir + "/pass_000.pcd", r.dir + "/z/cloud.pcd");
  fs::copy_file(r.dir + "/pass_000.pcd", r.dir + "/z/pass_000.pcd");
  const std::string scan = test::read_text(r.dir + "/pass_000.pcd");
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"run", r.yaml, "-q", "--set", "input.scans=" + r.dir + "/z/cloud.pcd", "--output-dir", r.dir + "/z"}, "as 'cloud.pcd'"},
      {{"import", "cloud", r.dir + "/z/pass_000.pcd", "--output-dir", r.dir + "/z"}, "as 'pass_000.pcd'"},
      {{"clean-cloud", r.dir + "/z/cloud.pcd", "-o", r.dir + "/z/./cloud.pcd"}, "is an input of the command"},
      {{"evaluate", "--truth", r.dir, "--run", r.dir + "/nosuch"}, "no such folder"},
  };
  for (const auto& c : cases) {
    std::string line;
    for (const auto& a : c.args) line += a + " ";
    const auto res = run_cli(c.args);
    EXPECT_EQ(res.exit_code, c.args[0] == "evaluate" ? 3 : 2) << line << res.err;
    EXPECT_NE(res.err.find(c.says), std::string::npos) << line << res.err;
  }
  EXPECT_EQ(test::read_text(r.dir + "/z/cloud.pcd"), scan);
  EXPECT_EQ(test::read_text(r.dir + "/z/pass_000.pcd"), scan);
  EXPECT_FALSE(fs::exists(r.dir + "/nosuch"));
  // A new run drops the earlier run's evaluation.json (it scored that set); the user's files stay.
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  ASSERT_EQ(run_cli({"evaluate", "--truth", r.dir, "--run", r.dir + "/out", "-q"}).exit_code, 0);
  ASSERT_TRUE(fs::exists(r.dir + "/out/evaluation.json"));
  test::write_text(r.dir + "/out/notes.txt", "mine");
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  EXPECT_FALSE(fs::exists(r.dir + "/out/evaluation.json"));
  EXPECT_TRUE(fs::exists(r.dir + "/out/notes.txt"));
  // Scored against another simulation (the same scanner and scene, another drive): refused.
  const SimRun other = small_run("inputs_other", 0.2);
  const auto res = run_cli({"evaluate", "--truth", other.dir, "--run", r.dir + "/out", "-q"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_NE(res.err.find("the run read none of the"), std::string::npos) << res.err;
  EXPECT_FALSE(fs::exists(r.dir + "/out/evaluation.json"));
}

TEST(OutputsGuard, ARunWithoutTheGridDropsAnEarlierMergeState) {
  const SimRun r = small_run("state");
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  ASSERT_TRUE(fs::exists(r.dir + "/out/elevation.state.tif"));
  // The same run without fuse_elevation: neither the grid nor its merge state stays.
  std::string text = test::read_text(r.yaml);
  text = text.substr(0, text.find("  - type: fuse_elevation"));
  test::write_text(r.yaml, text);
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  EXPECT_FALSE(fs::exists(r.dir + "/out/elevation.tif"));
  EXPECT_FALSE(fs::exists(r.dir + "/out/elevation.state.tif"));
}

TEST(OutputsGuard, TheCrsIsInTheReportsConfiguration) {
  const SimRun r = small_run("crs");
  ASSERT_EQ(run_cli({"run", r.yaml, "-q", "--set", "crs=EPSG:32632"}).exit_code, 0);
  const auto j = nlohmann::json::parse(test::read_text(r.dir + "/out/report.json"));
  EXPECT_EQ(j["config"]["crs"], "EPSG:32632");
  // A CRS whose axes point west and south is refused at configuration time.
  const auto bad = run_cli({"validate", r.yaml, "--set", "crs=EPSG:2046"});
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("west and south"), std::string::npos) << bad.err;
}

TEST(OutputsGuard, AReimportReplacesTheEarlierPassesAndPoses) {
  const std::string dir = test::fresh_dir("reimport");
  const std::string data = std::string(PCDP_SHARED_DIR) + "/datasets/kurt3d_3dtk_nodding";
  if (!fs::exists(data + "/scan000.3d")) GTEST_SKIP() << "no Kurt3D data set";
  const std::string out = dir + "/import";
  ASSERT_EQ(run_cli({"import", "3dtk", data + "/scan000.3d", data + "/scan001.3d", data + "/scan002.3d", "--output-dir", out}).exit_code, 0);
  ASSERT_EQ(pass_files(out).size(), 3u);
  test::write_text(out + "/notes.txt", "mine");
  // A smaller import into the same folder: only its own pass stays; the user's file stays too.
  const std::string cloud = dir + "/c.pcd";
  test::write_text(cloud, "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                          "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 0 0\n2 0.1 0\n3 0.3 0.1\n");
  const auto res = run_cli({"import", "cloud", cloud, "--output-dir", out});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_EQ(pass_files(out).size(), 1u);
  EXPECT_EQ(test::read_text(out + "/notes.txt"), "mine");
}

TEST(OutputsGuard, AGeoreferencedCloudComesBackInMapCoordinates) {
  // A cloud with "# map_origin" (a georeferenced run's cloud.pcd): import cloud adds the origin
  // back, so a --viewpoint in map coordinates fits it and the poses are in the map frame.
  const std::string dir = test::fresh_dir("mapcloud");
  const std::string cloud = dir + "/cloud.pcd";
  test::write_text(cloud, "# .PCD v0.7\n# map_origin 500000 5300000 0\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                          "COUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n"
                          "10 0 0\n11 0.5 0\n12 1 0.1\n13 1.5 0.2\n");
  const auto res = run_cli({"import", "cloud", cloud, "--viewpoint", "500000,5300000,2", "--output-dir", dir + "/import"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  const std::string poses = test::read_text(dir + "/import/poses.csv");
  EXPECT_NE(poses.find("500000"), std::string::npos) << poses;
  EXPECT_NE(poses.find("5300000"), std::string::npos) << poses;
}

TEST(OutputsGuard, AGridWithoutASurfaceIsSaid) {
  const SimRun r = small_run("nosurface");
  const auto res = run_cli({"run", r.yaml, "-q", "--set", "stages.fuse_elevation.min_support=1000"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_NE(res.err.find("no cell of the elevation grid has a surface"), std::string::npos) << res.err;
  const auto j = nlohmann::json::parse(test::read_text(r.dir + "/out/report.json"));
  EXPECT_NE(j["warnings"].dump().find("elevation.tif holds no elevation"), std::string::npos) << j["warnings"].dump();
  // The default run has surfaces and no such warning.
  ASSERT_EQ(run_cli({"run", r.yaml, "-q"}).exit_code, 0);
  const auto k = nlohmann::json::parse(test::read_text(r.dir + "/out/report.json"));
  EXPECT_EQ(k["warnings"].dump().find("holds no elevation"), std::string::npos);
}
