// `shard` through the real CLI on the sample pipeline (check_consistency, fuse_elevation,
// fuse_octomap): products byte-identical to the one-machine `run` for every shard count and any
// completion order; a missing, duplicated or truncated partial refused naming the task to rerun;
// bad plans exit 2.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "pcdp/io/atomic_file.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using pcdp::test::run_cli;

namespace {

const std::string kPipeline = std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml";

/// report.json without what differs between runs by design: timings, thread count, output paths
/// and the shard section.
nlohmann::json stripped(const std::string& path) {
  static const std::set<std::string> drop = {"seconds", "started_at", "phases", "threads", "output_dir", "outputs",
                                             "timings", "cpu_seconds", "shard"};
  std::function<nlohmann::json(const nlohmann::json&)> strip = [&](const nlohmann::json& j) -> nlohmann::json {
    if (j.is_object()) {
      nlohmann::json o = nlohmann::json::object();
      for (auto it = j.begin(); it != j.end(); ++it) {
        const std::string& k = it.key();
        if (drop.count(k) || (k.size() > 8 && k.compare(k.size() - 8, 8, "_seconds") == 0)) continue;
        o[k] = strip(it.value());
      }
      return o;
    }
    if (j.is_array()) {
      nlohmann::json a = nlohmann::json::array();
      for (const auto& v : j) a.push_back(strip(v));
      return a;
    }
    return j;
  };
  return strip(nlohmann::json::parse(pcdp::test::read_text(path)));
}

/// The one-machine run, made once.
const std::string& reference() {
  static const std::string dir = [] {
    const std::string d = pcdp::test::fresh_dir("shard_reference") + "/out";
    const auto r = run_cli({"run", kPipeline, "-q", "-j", "2", "--output-dir", d});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return d;
  }();
  return dir;
}

void expect_same_products(const std::string& out) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(reference())) names.push_back(e.path().filename().string());
  ASSERT_GE(names.size(), 7u);
  for (const auto& n : names) {
    ASSERT_TRUE(fs::exists(out + "/" + n)) << n;
    if (n == "report.json") {
      const auto a = stripped(reference() + "/" + n), b = stripped(out + "/" + n);
      EXPECT_EQ(a, b) << "report.json differs beyond timings, paths and the shard section";
      const auto full = nlohmann::json::parse(pcdp::test::read_text(out + "/" + n));
      EXPECT_TRUE(full.contains("shard"));
    } else {
      EXPECT_TRUE(pcdp::test::read_text(reference() + "/" + n) == pcdp::test::read_text(out + "/" + n))
          << n << " differs from the one-machine run";
    }
  }
  std::size_t count = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(out)) ++count;
  EXPECT_EQ(count, names.size());
}

}  // namespace

TEST(Shard, LocalEqualsTheOneMachineRunForEveryShardCount) {
  for (int n = 1; n <= 4; ++n) {  // the sample has 4 passes; 5 is a bad plan (below)
    const std::string d = pcdp::test::fresh_dir("shard_local_" + std::to_string(n));
    const auto r = run_cli({"shard", kPipeline, "--shards", std::to_string(n), "--work-dir", d + "/w", "--output-dir",
                            d + "/out", "--local"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    SCOPED_TRACE("shards " + std::to_string(n));
    expect_same_products(d + "/out");
    EXPECT_TRUE(fs::exists(d + "/w/plan.json"));
    EXPECT_TRUE(fs::exists(d + "/w/jobs/evidence.sh"));
    EXPECT_TRUE(fs::exists(d + "/w/jobs/passes.sh"));
    EXPECT_TRUE(fs::exists(d + "/w/jobs/reduce.sh"));
  }
}

TEST(Shard, TasksCompletingInReverseOrderGiveTheSameProducts) {
  const std::string d = pcdp::test::fresh_dir("shard_reverse"), w = d + "/w";
  ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "4", "--work-dir", w, "--output-dir", d + "/out"}).exit_code, 0);
  EXPECT_FALSE(fs::exists(d + "/out"));  // planned only
  for (const std::string phase : {"evidence", "passes"})
    for (int t = 3; t >= 0; --t) {
      const auto r = run_cli({"shard-task", w, phase, std::to_string(t)});
      ASSERT_EQ(r.exit_code, 0) << phase << " " << t << ": " << r.err;
    }
  const auto r = run_cli({"shard-task", w, "reduce"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_products(d + "/out");
}

TEST(Shard, AMissingOrDuplicatedPartialIsRefusedNamingTheTaskAndARerunCompletes) {
  const std::string d = pcdp::test::fresh_dir("shard_missing"), w = d + "/w";
  ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "3", "--work-dir", w, "--output-dir", d + "/out", "--local"}).exit_code, 0);
  fs::remove_all(d + "/out");
  fs::remove(w + "/passes/task-0001.part");
  auto r = run_cli({"shard-task", w, "reduce"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("task-0001.part: missing"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("pcd_pipeline shard-task " + w + " passes 1"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("passes 0"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(d + "/out"));
  // A copy of another task's partial in its place: a duplicate, named.
  fs::copy_file(w + "/passes/task-0000.part", w + "/passes/task-0001.part");
  r = run_cli({"shard-task", w, "reduce"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("holds task 0 (a duplicate)"), std::string::npos) << r.err;
  // A truncated evidence partial: the passes tasks refuse it.
  const std::string ev = w + "/evidence/task-0002.part";
  const std::string text = pcdp::test::read_text(ev);
  pcdp::test::write_text(ev, text.substr(0, text.size() / 2));
  r = run_cli({"shard-task", w, "passes", "1"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("task-0002.part"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
  // Rerunning only the named tasks completes the job.
  ASSERT_EQ(run_cli({"shard-task", w, "evidence", "2"}).exit_code, 0);
  ASSERT_EQ(run_cli({"shard-task", w, "passes", "1"}).exit_code, 0);
  r = run_cli({"shard-task", w, "reduce"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_products(d + "/out");
}

TEST(Shard, ATaskStartedInAnotherFolderReadsThePlansFiles) {
  // Scans given relative to the folder the plan is made in (--set): a task started elsewhere (a
  // container's working directory) reads those, not whatever that folder holds.
  const std::string d = pcdp::test::fresh_dir("shard_cwd"), w = d + "/w";
  fs::create_directories(d + "/scans");
  fs::create_directories(d + "/elsewhere/scans");
  for (const auto& e : fs::directory_iterator(std::string(PCDP_SOURCE_DIR) + "/sample_scans"))
    if (e.path().extension() == ".pcd") {
      fs::copy_file(e.path(), d + "/scans/" + e.path().filename().string());
      pcdp::test::write_text(d + "/elsewhere/scans/" + e.path().filename().string(), "not a pass");
    }
  ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--output-dir", d + "/out", "--set",
                     "input.scans=scans/pass_*.pcd"}, d).exit_code, 0);
  for (const char* phase : {"evidence", "passes"})
    for (const char* t : {"0", "1"}) {
      const auto r = run_cli({"shard-task", w, phase, t}, d + "/elsewhere");
      ASSERT_EQ(r.exit_code, 0) << phase << " " << t << ": " << r.err;
    }
  const auto r = run_cli({"shard-task", w, "reduce"}, d + "/elsewhere");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(pcdp::test::read_text(reference() + "/cloud.pcd") == pcdp::test::read_text(d + "/out/cloud.pcd"));
  // The folder the plan was made in, gone: an input error saying so, not an internal error.
  fs::rename(d, d + ".moved");
  const auto gone = run_cli({"shard-task", d + ".moved/w", "passes", "0"}, d + ".moved");
  EXPECT_EQ(gone.exit_code, 3) << gone.err;
  EXPECT_NE(gone.err.find("the folder the plan was made in"), std::string::npos) << gone.err;
  fs::remove_all(d + ".moved");
}

TEST(Shard, BadPlansExit2) {
  const std::string d = pcdp::test::fresh_dir("shard_bad"), w = d + "/w";
  auto r = run_cli({"shard", kPipeline, "--shards", "5", "--work-dir", w, "--local"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--shards 5 is more than the 4 pass(es)"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(w + "/plan.json"));
  r = run_cli({"shard", kPipeline, "--shards", "0", "--work-dir", w});
  EXPECT_EQ(r.exit_code, 2);
  ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--output-dir", d + "/out"}).exit_code, 0);
  // The same work dir for another pipeline (a --set changes it), or another shard count.
  r = run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--set", "sensor.min_amplitude=20"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("holds the plan of another run"), std::string::npos) << r.err;
  r = run_cli({"shard", kPipeline, "--shards", "3", "--work-dir", w, "--output-dir", d + "/out"});
  EXPECT_EQ(r.exit_code, 2);
  // The same plan again is fine; a task index beyond the plan is exit 2.
  EXPECT_EQ(run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--output-dir", d + "/out"}).exit_code, 0);
  r = run_cli({"shard-task", w, "passes", "2"});
  EXPECT_EQ(r.exit_code, 2);
  r = run_cli({"shard-task", w, "sideways", "0"});
  EXPECT_EQ(r.exit_code, 2);
}

TEST(Shard, TheReduceMakesTheRunLevelChecksOfRun) {
  const std::string d = pcdp::test::fresh_dir("shard_keeps_nothing");
  const auto one = run_cli({"run", kPipeline, "-q", "--set", "sensor.range_max=0.2", "--output-dir", d + "/run"});
  const auto r = run_cli({"shard", kPipeline, "--shards", "2", "--set", "sensor.range_max=0.2", "--work-dir", d + "/w",
                          "--output-dir", d + "/out", "--local"});
  EXPECT_EQ(one.exit_code, 3);
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("the run keeps nothing"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(d + "/out"));
}

TEST(Shard, TheReduceTakesOnlyTheRecordsItsTasksWroteAndOneCopyOfATaskRunsAtATime) {
  const std::string d = pcdp::test::fresh_dir("shard_records"), w = d + "/w";
  ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--output-dir", d + "/out", "--local"}).exit_code, 0);
  fs::remove_all(d + "/out");
  const std::string rec = w + "/passes/task-0001.part.cloud.pcd", whole = pcdp::test::read_text(rec);
  // Truncated, or the other task's record in its place: refused, naming the task to rerun.
  pcdp::test::write_text(rec, whole.substr(0, whole.size() / 2));
  auto r = run_cli({"shard-task", w, "reduce"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("task-0001.part.cloud.pcd: not the record task 1 wrote"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("rerun task 1 of phase 'passes'"), std::string::npos) << r.err;
  fs::copy_file(w + "/passes/task-0000.part.cloud.pcd", rec, fs::copy_options::overwrite_existing);
  r = run_cli({"shard-task", w, "reduce"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_FALSE(fs::exists(d + "/out"));
  // While one copy of a task runs (its lock held), a second refuses at once and leaves nothing.
  {
    pcdp::io::OutputLock held(w + "/passes/task-0001.part");
    r = run_cli({"shard-task", w, "passes", "1"});
    EXPECT_EQ(r.exit_code, 4) << r.err;
    EXPECT_NE(r.err.find("another pcd_pipeline process"), std::string::npos) << r.err;
  }
  for (const auto& e : fs::directory_iterator(w + "/passes"))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
  // A killed copy's temporaries (SIGKILL: no cleanup ran) go when the task runs again.
  pcdp::test::write_text(w + "/passes/task-0001.part.tmp.99999", "x");
  pcdp::test::write_text(w + "/passes/task-0001.part.cloud.pcd.tmp.99999.body", "x");
  ASSERT_EQ(run_cli({"shard-task", w, "passes", "1"}).exit_code, 0);
  EXPECT_FALSE(fs::exists(w + "/passes/task-0001.part.tmp.99999"));
  EXPECT_FALSE(fs::exists(w + "/passes/task-0001.part.cloud.pcd.tmp.99999.body"));
  // A plan written by another version: said so, and `shard` replaces it.
  {
    std::string plan = pcdp::test::read_text(w + "/plan.bin");
    const auto at = plan.find("pcdp.shard_plan.2");
    ASSERT_NE(at, std::string::npos);
    plan[at + 16] = '1';
    pcdp::test::write_text(w + "/plan.bin", plan);
    r = run_cli({"shard-task", w, "passes", "1"});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("a plan made by another version of pcd_pipeline"), std::string::npos) << r.err;
    ASSERT_EQ(run_cli({"shard", kPipeline, "--shards", "2", "--work-dir", w, "--output-dir", d + "/out"}).exit_code, 0);
  }
  // An index past any plan is a configuration error, not an internal one.
  r = run_cli({"shard-task", w, "passes", "99999999999999999999"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("beyond any plan's tasks"), std::string::npos) << r.err;
  // Rerunning the named task completes the job.
  ASSERT_EQ(run_cli({"shard-task", w, "passes", "1"}).exit_code, 0);
  r = run_cli({"shard-task", w, "reduce"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_same_products(d + "/out");
}
