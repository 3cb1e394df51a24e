// report.json's record of a run (inputs and outputs with their sizes and SHA-256, start time,
// units, the label code table), checked through the CLI against the files on disk and an
// independent SHA-256 (sha256sum); and the CLI run from a working directory outside the repository.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>

#include "pcdp/io/pcd.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;

namespace {
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// SHA-256 of a file by coreutils' sha256sum: independent of the code under test.
std::string sha256sum(const std::string& path) {
  std::FILE* p = ::popen(("sha256sum -b -- " + quote(path)).c_str(), "r");
  if (!p) return "(popen failed)";
  char buf[128] = {};
  const std::size_t n = std::fread(buf, 1, 64, p);
  ::pclose(p);
  return std::string(buf, n);
}

/// A fresh folder outside the repository (and outside the build tree, which may be inside it).
struct AwayDir {
  fs::path path;
  explicit AwayDir(const std::string& tag) {
    path = fs::temp_directory_path() / ("pcdp-away-" + std::to_string(::getpid()) + "-" + tag);
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~AwayDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

/// Runs the CLI with `cwd` as its working directory.
test::CliResult run_cli_in(const fs::path& cwd, const std::vector<std::string>& args) {
  const std::string io = test::fresh_dir("cli-in");
  std::string cmd = "cd " + quote(cwd.string()) + " && " + quote(PCDP_CLI_PATH);
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote(io + "/stdout") + " 2>" + quote(io + "/stderr") + " </dev/null";
  const int status = std::system(cmd.c_str());
  test::CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = test::read_text(io + "/stdout");
  r.err = test::read_text(io + "/stderr");
  return r;
}

bool inside(const fs::path& p, const fs::path& dir) {
  const auto rel = fs::weakly_canonical(p).lexically_relative(fs::weakly_canonical(dir));
  return !rel.empty() && *rel.begin() != "..";
}
}  // namespace

TEST(Report, ListsEveryOutputAndInputWithItsSizeAndSha256) {
  const std::string out = test::fresh_dir() + "/out";
  const std::string yaml = std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml";
  const std::time_t before = std::time(nullptr);
  const auto res = test::run_cli({"run", yaml, "--output-dir", out, "-q"});
  const std::time_t after = std::time(nullptr);
  ASSERT_EQ(res.exit_code, 0) << res.err;
  const auto rep = nlohmann::json::parse(test::read_text(out + "/report.json"));

  // outputs: every file of the folder but report.json itself, each once, its size and hash right.
  std::set<std::string> on_disk, listed;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().filename() != "report.json") on_disk.insert(e.path().filename().string());
  ASSERT_TRUE(rep["outputs"].is_array());
  for (const auto& o : rep["outputs"]) {
    const std::string name = o["file"];
    EXPECT_TRUE(listed.insert(name).second) << name << " listed twice";
    const std::string path = out + "/" + name;
    ASSERT_TRUE(fs::is_regular_file(path)) << name;
    EXPECT_EQ(o["bytes"].get<std::uint64_t>(), fs::file_size(path)) << name;
    EXPECT_EQ(o["sha256"].get<std::string>(), sha256sum(path)) << name;
  }
  EXPECT_EQ(listed, on_disk);
  for (const char* must : {"returns.pcd", "cloud.pcd", "elevation.tif", "elevation.png", "map.bt"})
    EXPECT_TRUE(listed.count(must)) << must;

  // inputs: every pass file and the pose file, with their sizes and hashes.
  std::set<std::string> scans;
  for (const auto& f : rep["config"]["input"]["scans"]) scans.insert(f.get<std::string>());
  ASSERT_EQ(scans.size(), 4u);
  std::size_t n_scan = 0, n_poses = 0;
  for (const auto& i : rep["inputs"]) {
    const std::string f = i["file"];
    const std::string kind = i["kind"];
    if (kind == "scan") {
      ++n_scan;
      EXPECT_TRUE(scans.count(f)) << f;
    } else {
      ++n_poses;
      EXPECT_EQ(kind, "poses");
      EXPECT_EQ(f, rep["config"]["input"]["poses"].get<std::string>());
    }
    EXPECT_EQ(i["bytes"].get<std::uint64_t>(), fs::file_size(f)) << f;
    EXPECT_EQ(i["sha256"].get<std::string>(), sha256sum(f)) << f;
  }
  EXPECT_EQ(n_scan, 4u);
  EXPECT_EQ(n_poses, 1u);

  // started_at: UTC, ISO 8601, within the run.
  const std::string started = rep["started_at"];
  ASSERT_TRUE(std::regex_match(started, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)"))) << started;
  std::tm tm{};
  ASSERT_NE(strptime(started.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm), nullptr);
  const std::time_t t = timegm(&tm);
  EXPECT_GE(t, before);
  EXPECT_LE(t, after);

  // label_codes: the code table of pcdp/core/labels.hpp, in code order.
  ASSERT_EQ(rep["label_codes"].size(), kLabelCount);
  for (std::size_t c = 0; c < kLabelCount; ++c) {
    const auto& e = rep["label_codes"][c];
    EXPECT_EQ(e["code"].get<std::size_t>(), c);
    EXPECT_EQ(e["name"].get<std::string>(), label_name(static_cast<Label>(c)));
    EXPECT_EQ(e["meaning"].get<std::string>(), label_meaning(static_cast<Label>(c)));
    EXPECT_FALSE(e["meaning"].get<std::string>().empty());
  }
  // The histogram keeps its form (name -> count) and names only codes of the table.
  for (const auto& [k, v] : rep["labels"].items()) EXPECT_NO_THROW(label_from_name(k)) << k;

  // units: every field of the per-return products has one.
  for (const char* product : {"returns.pcd", "cloud.pcd"})
    for (const auto& f : io::read_pcd_header(out + "/" + product).fields)
      EXPECT_TRUE(rep["units"].contains(f.name)) << product << ": field " << f.name << " has no unit in report.json";
  EXPECT_EQ(rep["units"]["x"], "m");
  EXPECT_EQ(rep["units"]["stamp"], "s");
  EXPECT_EQ(rep["units"]["cov_zz"], "m^2");
}

TEST(AnyDirectory, SubcommandsWorkFromAFolderOutsideTheRepository) {
  AwayDir away("subcommands");
  ASSERT_FALSE(inside(away.path, PCDP_SOURCE_DIR)) << away.path << " is inside the repository";
  const std::string src = PCDP_SOURCE_DIR;

  // bench: its default scene and pipeline do not come from the working directory.
  auto r = run_cli_in(away.path, {"bench", "--passes", "1", "--reps", "1", "--geometric"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("whole run on 2 threads"), std::string::npos) << r.out;

  // A shipped pipeline without output_dir writes into out/<its name> of the working directory.
  r = run_cli_in(away.path, {"validate", src + "/pipelines/nodding_terrain.yaml"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("output_dir out/nodding_terrain"), std::string::npos) << r.out;
  r = run_cli_in(away.path, {"run", src + "/pipelines/nodding_terrain.yaml", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const fs::path out = away.path / "out" / "nodding_terrain";
  for (const char* f : {"returns.pcd", "cloud.pcd", "report.json", "elevation.tif", "map.bt"})
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  const auto rep = nlohmann::json::parse(test::read_text((out / "report.json").string()));
  EXPECT_EQ(rep["config"]["output_dir"], "out/nodding_terrain");

  // Relative paths on the command line are relative to the working directory: a scene and a
  // pipeline of the user's own, by relative paths.
  std::string scene = test::read_text(src + "/sample_scans/scene.yaml");
  ASSERT_NE(scene.find("\npasses: 4\n"), std::string::npos);
  scene.replace(scene.find("\npasses: 4\n"), 11, "\npasses: 1\n");
  test::write_text((away.path / "scene.yaml").string(), scene);
  r = run_cli_in(away.path, {"simulate", "scene.yaml", "--output-dir", "data", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  test::write_text((away.path / "mine.yaml").string(),
                   "input: {scans: data/pass_*.pcd, poses: data/poses.csv}\n"
                   "mount: {x: 0.5, y: 0.0, z: 1.64, roll: 0.0, pitch: 0.19775, yaw: 0.0}\nstages: [{type: register}]\n");
  r = run_cli_in(away.path, {"run", "mine.yaml", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_regular_file(away.path / "out" / "mine" / "returns.pcd"));
  r = run_cli_in(away.path, {"evaluate", "--truth", "data", "--run", "out/mine"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}
