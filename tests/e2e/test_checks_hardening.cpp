// Run-level checks through the real binary (issue 33 items 8, 14, 18, 19): a run that keeps
// nothing fails before committing, smaller losses warn, pass headers are checked before the
// work, paths that are not UTF-8 reach report.json, simulate refuses scenes it cannot finish.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {

struct SimDir {
  sim::SimConfig cfg;
  std::string dir, yaml, out;
};

SimDir make_run(const std::string& extra_stages = "") {
  SimDir r;
  r.cfg = test::small_sim_config();
  r.dir = test::fresh_dir("data");
  r.out = r.dir + "/out";
  sim::write_run(sim::simulate(r.cfg), r.cfg, r.dir);
  r.yaml = r.dir + "/pipeline.yaml";
  test::write_text(r.yaml, test::pipeline_yaml(r.cfg, r.dir, r.out) + extra_stages);
  return r;
}

/// Rewrites the pose file with `shift` added to each stamp, keeping rows with stamp in [from, to).
void rewrite_poses(const std::string& path, double shift, double from = -1e300, double to = 1e300) {
  std::istringstream in(test::read_text(path));
  std::ostringstream out;
  out.precision(17);
  std::string line;
  std::getline(in, line);
  out << line << "\n";
  while (std::getline(in, line)) {
    const auto comma = line.find(',');
    const double t = std::stod(line.substr(0, comma));
    if (t < from || t >= to) continue;
    out << t + shift << line.substr(comma) << "\n";
  }
  test::write_text(path, out.str());
}

std::map<std::string, std::string> folder(const std::string& dir) {
  std::map<std::string, std::string> m;
  for (const auto& e : fs::directory_iterator(dir)) m[e.path().filename().string()] = test::read_text(e.path().string());
  return m;
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }
}  // namespace

// ---- item 14: silent success -----------------------------------------------------------------

TEST(ChecksHardening, ATimeBaseMismatchFailsBeforeCommittingAndNamesTheCause) {
  const SimDir r = make_run();
  ASSERT_EQ(run_cli({"run", r.yaml, "--quiet"}).exit_code, 0);
  const auto before = folder(r.out);

  rewrite_poses(r.dir + "/poses.csv", 1.6e9);  // poses in Unix time, scans from 100 s
  const auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "in-range returns (100.0 %) have no pose: the pose file " + r.dir + "/poses.csv spans 1600000099.99"))
      << res.err;
  EXPECT_TRUE(has(res.err, "the scans' stamps run 100 to ")) << res.err;
  EXPECT_TRUE(has(res.err, "a time-base mismatch")) << res.err;
  EXPECT_TRUE(has(res.err, "set allow_empty_output: true")) << res.err;
  EXPECT_EQ(folder(r.out), before) << "the output folder must keep its earlier run";

  // Allowed: written, with the cause as a warning in report.json and on stderr.
  const auto ok = run_cli({"run", r.yaml, "--quiet", "--set", "allow_empty_output=true"});
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(has(ok.err, "warning: run: ")) << ok.err;
  const auto rep = nlohmann::json::parse(test::read_text(r.out + "/report.json"));
  ASSERT_FALSE(rep["warnings"].empty());
  EXPECT_TRUE(has(rep["warnings"][0].get<std::string>(), "have no pose")) << rep["warnings"];
  EXPECT_EQ(rep["config"]["allow_empty_output"], true);
  EXPECT_EQ(rep["kept"], 0);
}

TEST(ChecksHardening, MostReturnsWithoutAPoseIsAnErrorASmallShareAWarning) {
  const SimDir r = make_run();
  const double t0 = r.cfg.t0, t1 = t0 + r.cfg.passes * r.cfg.lines_per_pass * r.cfg.scanner.line_period;
  const std::string poses = test::read_text(r.dir + "/poses.csv");

  rewrite_poses(r.dir + "/poses.csv", 0.0, -1e300, t0 + 0.3 * (t1 - t0));  // 70 % of the run without poses
  auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "have no pose")) << res.err;
  EXPECT_TRUE(has(res.err, "the poses cover part of the run")) << res.err;
  EXPECT_FALSE(fs::exists(r.out + "/report.json"));

  test::write_text(r.dir + "/poses.csv", poses);
  rewrite_poses(r.dir + "/poses.csv", 0.0, -1e300, t0 + 0.85 * (t1 - t0));  // about 15 %
  res = run_cli({"run", r.yaml, "--quiet"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_TRUE(has(res.err, "warning: run: ")) << res.err;
  EXPECT_TRUE(has(res.err, "have no pose")) << res.err;
  const auto rep = nlohmann::json::parse(test::read_text(r.out + "/report.json"));
  ASSERT_EQ(rep["warnings"].size(), 1u) << rep["warnings"];

  // The full pose file: no warning at all.
  test::write_text(r.dir + "/poses.csv", poses);
  res = run_cli({"run", r.yaml, "--quiet"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_EQ(res.err, "");
  EXPECT_TRUE(nlohmann::json::parse(test::read_text(r.out + "/report.json"))["warnings"].empty());
}

TEST(ChecksHardening, AllReturnsOutOfRangeIsAnError) {
  const SimDir r = make_run();
  const auto res = run_cli({"run", r.yaml, "--quiet", "--set", "sensor.range_max=0.2"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "the run keeps nothing: no return of ")) << res.err;
  EXPECT_TRUE(has(res.err, "fall outside sensor.range_min to range_max (0.1 to 0.2 m")) << res.err;
  EXPECT_FALSE(fs::exists(r.out + "/report.json"));
  EXPECT_FALSE(fs::exists(r.out + "/returns.pcd"));
}

TEST(ChecksHardening, ManyReturnsOutOfRangeWarn) {
  const SimDir r = make_run();
  const auto res = run_cli({"run", r.yaml, "--quiet", "--set", "sensor.range_max=6"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_TRUE(has(res.err, "warning: run: ")) << res.err;
  EXPECT_TRUE(has(res.err, "fall outside sensor.range_min to range_max (0.1 to 6 m)")) << res.err;
}

// ---- item 18: cheap checks of every pass before the heavy work --------------------------------

TEST(ChecksHardening, ABadPassHeaderIsFoundBeforeThePrepassReadsAnyPass) {
  const SimDir r = make_run("  - type: check_consistency\n");
  // Pass 0: a data error that only a full read finds. Pass 1: a header without most fields.
  Pass p = read_pass(r.dir + "/pass_000.pcd", 0);
  p.range[5] = -1.0f;
  sim::write_pass_pcd(p, r.dir + "/pass_000.pcd");
  test::write_text(r.dir + "/pass_001.pcd",
                   "VERSION .7\nFIELDS line beam range\nSIZE 4 4 4\nTYPE U U F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                   "POINTS 1\nDATA ascii\n0 0 1.5\n");
  const auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "pass_001.pcd: missing required field 'bearing'")) << res.err;
}

TEST(ChecksHardening, APassThatIsNotARegularFileIsRefusedUpFront) {
  const SimDir r = make_run("  - type: check_consistency\n");
  std::string y = test::read_text(r.yaml);
  y.replace(y.find(r.dir + "/pass_*.pcd"), r.dir.size() + 11, "[" + r.dir + "/pass_000.pcd, /dev/null]");
  test::write_text(r.yaml, y);
  const auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "/dev/null")) << res.err;
  EXPECT_TRUE(has(res.err, "not a regular file")) << res.err;
}

TEST(ChecksHardening, ATruncatedBinaryPassIsFoundFromItsHeader) {
  const SimDir r = make_run("  - type: check_consistency\n");
  Pass p = read_pass(r.dir + "/pass_000.pcd", 0);  // a data error the prepass would meet first
  p.range[5] = -1.0f;
  sim::write_pass_pcd(p, r.dir + "/pass_000.pcd");
  const std::string full = test::read_text(r.dir + "/pass_001.pcd");
  test::write_text(r.dir + "/pass_001.pcd", full.substr(0, full.size() - 100));
  const auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "pass_001.pcd: truncated")) << res.err;
}

// ---- item 8: paths are bytes, names are text ---------------------------------------------------

TEST(ChecksHardening, AFileNameThatIsNotUtf8RunsAndReachesTheReport) {
  const SimDir r = make_run();
  fs::rename(r.dir + "/pass_001.pcd", r.dir + "/pass_\xE9.pcd");  // a Latin-1 name, legal on Linux
  const std::string out = r.dir + "/out_\xE9";
  const auto res = run_cli({"run", r.yaml, "--quiet", "--output-dir", out});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  const auto rep = nlohmann::json::parse(test::read_text(out + "/report.json"));
  EXPECT_EQ(rep["config"]["input"]["scans"][1], r.dir + "/pass_\xEF\xBF\xBD.pcd");
  EXPECT_EQ(rep["config"]["output_dir"], r.dir + "/out_\xEF\xBF\xBD");
}

TEST(ChecksHardening, AStageNameThatIsNotUtf8IsAConfigError) {
  const SimDir r = make_run();
  test::write_text(r.yaml, test::read_text(r.yaml) + "    name: reg\xE9\n");
  const auto res = run_cli({"run", r.yaml, "--quiet"});
  EXPECT_EQ(res.exit_code, 2) << res.err;
  EXPECT_TRUE(has(res.err, "the value of 'stages[0].name': byte 3 (0xE9) is not valid UTF-8")) << res.err;
  test::write_text(r.yaml, test::pipeline_yaml(r.cfg, r.dir, r.out));
  const auto set = run_cli({"run", r.yaml, "--quiet", "--set", "stages.register.name=caf\xE9"});
  EXPECT_EQ(set.exit_code, 2) << set.err;
  EXPECT_TRUE(has(set.err, "byte 3 of the value of 'stages.register.name' is not valid UTF-8")) << set.err;
}

// ---- item 19: simulate bounds its work --------------------------------------------------------

TEST(ChecksHardening, SimulateRefusesASceneItCannotFinish) {
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/scene.yaml", "passes: 100\nlines_per_pass: 10000\nscanner: {beams: 181}\n");
  const auto res = run_cli({"simulate", dir + "/scene.yaml", "--output-dir", dir + "/out"});
  EXPECT_EQ(res.exit_code, 2) << res.err;
  EXPECT_TRUE(has(res.err, "scene.yaml: the scene needs passes x lines_per_pass x scanner.beams = 100 x 10000 x 181"))
      << res.err;
  EXPECT_FALSE(fs::exists(dir + "/out"));
}

TEST(ChecksHardening, SimulateRefusesASceneThatGivesNoReturn) {
  // The default mount stands on the ground and nods below the horizon: not one beam returns.
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/scene.yaml", "seed: 1\npasses: 1\nlines_per_pass: 20\n");
  const auto res = run_cli({"simulate", dir + "/scene.yaml", "--output-dir", dir + "/out"});
  EXPECT_EQ(res.exit_code, 3) << res.err;
  EXPECT_TRUE(has(res.err, "scene.yaml: every one of the 3620 simulated beams returned nothing")) << res.err;
  EXPECT_FALSE(fs::exists(dir + "/out"));
}
