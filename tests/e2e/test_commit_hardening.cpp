// The output commit through the CLI: a run killed at each step of its commit leaves the
// complete old or new set; two runs into one folder; products written twice; a folder named
// like a product; signals; output paths that cannot be written (exit 4) in every subcommand.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include "pcdp/io/atomic_file.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {

using Snapshot = std::map<std::string, std::string>;

Snapshot snapshot(const std::string& dir, bool skip_report = true) {
  Snapshot s;
  if (!fs::exists(dir)) return {{"<absent>", ""}};
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(e.path(), dir).string();
    // report.json holds timings: compared by presence only
    s[rel] = e.is_directory() ? "<dir>" : (skip_report && rel == "report.json") ? "<report>" : test::read_text(e.path().string());
  }
  return s;
}

struct Data {
  std::string dir, yaml, out;
};

/// A small simulated run and a pipeline writing every kind of product.
Data make_data(const std::string& stages = "  - type: fuse_elevation\n  - type: fuse_octomap\n") {
  Data d;
  d.dir = test::fresh_dir();
  const sim::SimConfig cfg = test::small_sim_config();
  const sim::SimResult r = sim::simulate(cfg);
  sim::write_run(r, cfg, d.dir);
  d.out = d.dir + "/out";
  d.yaml = d.dir + "/p.yaml";
  test::write_text(d.yaml, test::pipeline_yaml(cfg, d.dir, d.out) + stages);
  return d;
}

/// Runs the CLI with an environment variable set.
test::CliResult run_with_env(const char* name, const std::string& value, const std::vector<std::string>& args) {
  ::setenv(name, value.c_str(), 1);
  test::CliResult r = run_cli(args);
  ::unsetenv(name);
  return r;
}

}  // namespace

TEST(CommitHardeningCli, ARunKilledOrFailedAtEachCommitStepLeavesTheOldOrTheNewSet) {
  Data d = make_data();
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  test::write_text(d.out + "/notes.txt", "mine");
  // The new run differs: another fusion resolution.
  const std::vector<std::string> args = {"run", d.yaml, "-q", "--set", "stages.fuse_elevation.resolution=0.2"};
  const Snapshot old = snapshot(d.out);
  ASSERT_EQ(run_cli(args).exit_code, 0);
  const Snapshot fresh = snapshot(d.out);
  ASSERT_NE(old, fresh);
  ASSERT_EQ(fresh.count("notes.txt"), 1u);
  int steps = 0;
  for (int k = 1; k < 40; ++k) {
    SCOPED_TRACE("step " + std::to_string(k));
    // Back to the old set.
    fs::remove_all(d.out);
    ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
    test::write_text(d.out + "/notes.txt", "mine");
    ASSERT_EQ(snapshot(d.out), old);
    const auto killed = run_with_env("PCDP_TEST_COMMIT_FAULT", "kill:" + std::to_string(k), args);
    const Snapshot after_kill = snapshot(d.out);
    EXPECT_TRUE(after_kill == old || after_kill == fresh) << "a mix after a kill at step " << k;
    if (killed.exit_code == 0) {  // past the last step: the run went through
      EXPECT_EQ(after_kill, fresh);
      steps = k - 1;
      break;
    }
    EXPECT_TRUE(killed.exit_code == -1 || killed.exit_code == 128 + SIGKILL) << "killed by SIGKILL: " << killed.exit_code;
    fs::remove_all(d.out);
    ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0) << "the next run cleans up after the killed one";
    EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty());
    test::write_text(d.out + "/notes.txt", "mine");
    const auto failed = run_with_env("PCDP_TEST_COMMIT_FAULT", "fail:" + std::to_string(k), args);
    const Snapshot after_fail = snapshot(d.out);
    if (failed.exit_code == 0) {
      EXPECT_EQ(after_fail, fresh) << "a step after the swap failed: the new set is in place";
    } else {
      EXPECT_EQ(failed.exit_code, 4) << failed.err;
      EXPECT_EQ(after_fail, old) << failed.err;
    }
  }
  EXPECT_GE(steps, 3) << "carry over notes.txt, exchange, remove the old set";
}

TEST(CommitHardeningCli, TwoRunsIntoOneFolderTheSecondRefusesAtOnce) {
  Data d = make_data();
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  const Snapshot before = snapshot(d.out, false);
  {
    io::OutputLock held(d.out);  // another process is writing the folder
    const auto r = run_cli({"run", d.yaml, "-q"});
    EXPECT_EQ(r.exit_code, 4);
    EXPECT_NE(r.err.find("another pcd_pipeline process (pid " + std::to_string(getpid()) + ") is writing this output now"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(snapshot(d.out, false), before);
  }
  // Two real processes started together: one wins, the other refuses; the folder is one whole set.
  const std::string yaml = d.yaml;
  pid_t pids[2];
  for (pid_t& pid : pids) {
    pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      execl(PCDP_CLI_PATH, PCDP_CLI_PATH, "run", yaml.c_str(), "-q", static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  int codes[2];
  for (int i = 0; i < 2; ++i) {
    int status = 0;
    waitpid(pids[i], &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    codes[i] = WEXITSTATUS(status);
  }
  EXPECT_TRUE(codes[0] == 0 || codes[1] == 0);
  EXPECT_TRUE((codes[0] == 0 || codes[0] == 4) && (codes[1] == 0 || codes[1] == 4));
  EXPECT_TRUE(fs::exists(d.out + "/returns.pcd") && fs::exists(d.out + "/map.bt"));
  EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty());
}

TEST(CommitHardeningCli, MergeCommitsItsOutputsAsASetAndLocksThem) {
  Data d = make_data("  - type: fuse_elevation\n");
  // Two grids of disjoint passes (merge refuses the same grid twice).
  ASSERT_EQ(run_cli({"run", d.yaml, "-q", "--set", "input.scans=" + d.dir + "/pass_000.pcd"}).exit_code, 0);
  ASSERT_EQ(run_cli({"run", d.yaml, "-q", "--output-dir", d.dir + "/out2", "--set",
                     "input.scans=" + d.dir + "/pass_001.pcd"}).exit_code, 0);
  const std::string a = d.out + "/elevation.tif", b = d.dir + "/out2/elevation.tif";
  ASSERT_EQ(run_cli({"merge", a, b, "-o", d.dir + "/m.tif", "--png", d.dir + "/m.png"}).exit_code, 0);
  test::write_text(d.dir + "/m.tif", "old tif");
  // The PNG cannot be written: refused before the work, the .tif untouched.
  fs::remove(d.dir + "/m.png");
  fs::create_directories(d.dir + "/m.png");
  auto r = run_cli({"merge", a, b, "-o", d.dir + "/m.tif", "--png", d.dir + "/m.png"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("m.png is a folder"), std::string::npos) << r.err;
  EXPECT_EQ(test::read_text(d.dir + "/m.tif"), "old tif");
  fs::remove(d.dir + "/m.png");
  // Every step of the commit failed in turn: both old (the .tif old, no PNG).
  for (int k = 1; k <= 2; ++k) {
    r = run_with_env("PCDP_TEST_COMMIT_FAULT", "fail:" + std::to_string(k),
                     {"merge", a, b, "-o", d.dir + "/m.tif", "--png", d.dir + "/m.png"});
    EXPECT_EQ(r.exit_code, 4) << r.err;
    EXPECT_EQ(test::read_text(d.dir + "/m.tif"), "old tif");
    EXPECT_FALSE(fs::exists(d.dir + "/m.png"));
  }
  {
    io::OutputLock held(d.dir + "/m.tif");
    r = run_cli({"merge", a, b, "-o", d.dir + "/m.tif"});
    EXPECT_EQ(r.exit_code, 4);
    EXPECT_NE(r.err.find("another pcd_pipeline process"), std::string::npos) << r.err;
  }
  for (const auto& e : fs::directory_iterator(d.dir))
    EXPECT_EQ(e.path().filename().string().find(".pcdp-"), std::string::npos) << e.path();
}

TEST(CommitHardeningCli, AStageListWritingAProductTwiceIsAConfigError) {
  Data d = make_data("  - type: fuse_octomap\n  - type: fuse_octomap\n    name: map2\n");
  auto r = run_cli({"validate", d.yaml});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("stage 'map2' (fuse_octomap) writes map.bt, which stage 'fuse_octomap' (fuse_octomap) writes too"),
            std::string::npos)
      << r.err;
  r = run_cli({"run", d.yaml, "-q"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(d.out));
}

TEST(CommitHardeningCli, AFolderNamedLikeAProductFailsBeforeTheWorkAndKeepsTheOldSet) {
  Data d = make_data();
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  fs::remove(d.out + "/elevation.png");
  fs::create_directories(d.out + "/elevation.png/photos");
  const Snapshot before = snapshot(d.out, false);
  const auto r = run_cli({"run", d.yaml, "-q"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_NE(r.err.find("elevation.png: a folder has the name of an output of this run"), std::string::npos) << r.err;
  EXPECT_EQ(snapshot(d.out, false), before);
  EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty());
}

TEST(CommitHardeningCli, LeftoversOfKilledRunsAreRemovedAndSigtermCleansUp) {
  Data d = make_data();
  fs::create_directories(d.dir + "/.out.pcdp-new-999999/sub");
  test::write_text(d.dir + "/.out.pcdp-new-999999/returns.pcd.body", "junk");
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty());
  // SIGTERM mid-run: exit 143, nothing staged is left, the old set stays.
  const Snapshot before = snapshot(d.out, false);
  test::write_text(d.dir + "/long.yaml", test::read_text(d.yaml) + "  - type: check_consistency\n");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string y = d.dir + "/long.yaml";
    execl(PCDP_CLI_PATH, PCDP_CLI_PATH, "run", y.c_str(), "-q", static_cast<char*>(nullptr));
    _exit(127);
  }
  bool staged = false;
  for (int i = 0; i < 5000 && !staged; ++i) {
    staged = !test::commit_leftovers(d.dir, "out").empty();
    if (!staged) usleep(200);
  }
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) != 0) {  // (a run that finished first is no test of the signal)
    EXPECT_EQ(WEXITSTATUS(status), 143);
    EXPECT_EQ(snapshot(d.out, false), before);
  }
  // The handler removes the staging folder and the lock file; a worker thread still writing
  // while it does may recreate a file in the staging folder: the next run removes that.
  // (The single-threaded case is exact: test_commit_hardening.cpp, unit.)
  ASSERT_EQ(run_cli({"validate", d.yaml, "-q"}).exit_code, 0);
  for (const auto& l : test::commit_leftovers(d.dir, "out")) EXPECT_EQ(l.rfind(".out.pcdp-new-", 0), 0u) << l;
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty()) << "no staging folder, no lock file";
}

TEST(CommitHardeningCli, OutputPathsAreCheckedUpFront) {
  Data d = make_data();
  auto r = run_cli({"run", d.yaml, "--output-dir", ""});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  r = run_cli({"run", d.yaml, "--set", "output_dir=a\nb"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("output_dir"), std::string::npos) << r.err;
  test::write_text(d.dir + "/nl.yaml", "input: {scans: " + d.dir + "/pass_*.pcd}\noutput_dir: \"x\\ny\"\nstages:\n  - type: register\n");
  r = run_cli({"validate", d.dir + "/nl.yaml"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("key 'output_dir': the path contains a control character"), std::string::npos) << r.err;
  // A failed run leaves no folder it created.
  test::write_text(d.dir + "/pass_001.pcd", "garbage");
  r = run_cli({"run", d.yaml, "-q", "--output-dir", d.dir + "/new/a/b"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_FALSE(fs::exists(d.dir + "/new"));
}

TEST(CommitHardeningCli, UnwritableOutputsExitWith4InEverySubcommand) {
  Data d = make_data("  - type: fuse_elevation\n");
  ASSERT_EQ(run_cli({"run", d.yaml, "-q", "--set", "input.scans=" + d.dir + "/pass_000.pcd"}).exit_code, 0);
  ASSERT_EQ(run_cli({"run", d.yaml, "-q", "--output-dir", d.dir + "/out2", "--set",
                     "input.scans=" + d.dir + "/pass_001.pcd"}).exit_code, 0);
  const std::string tif2 = d.dir + "/out2/elevation.tif";  // a second grid (merge refuses one grid twice)
  const std::string file = d.dir + "/a_file";
  test::write_text(file, "x");
  const std::string through = file + "/x";  // a path through a file
  const std::string tif = d.out + "/elevation.tif";
  const std::string cloud = d.out + "/cloud.pcd";
  const std::string scene = d.dir + "/scene.yaml";
  test::write_text(scene, "passes: 1\nlines_per_pass: 5\nscanner: {beams: 11, subrays: 1}\n");
  const std::vector<std::vector<std::string>> cases = {
      {"run", d.yaml, "-q", "--output-dir", through},
      {"run", d.yaml, "-q", "--output-dir", file},
      {"merge", tif, tif2, "-o", through + ".tif"},
      {"merge", tif, tif2, "-o", d.dir + "/m.tif", "--png", through + ".png"},
      {"simulate", scene, "--output-dir", through},
      {"clean-cloud", cloud, "-o", through + ".pcd"},  // the extension names the format (.pcd, .ply, .las)
      {"clean-cloud", cloud, "-o", d.dir + "/c.pcd", "--removed", through + ".las"},
      {"amplitude-model", "--svg", through},
      {"amplitude-model", "--profile-csv", through},
      {"error-budget", d.yaml, "--svg", through + ".svg"},
      {"error-budget", d.yaml, "--csv", through + ".csv"},
      {"plan-nod", "--csv", through},
      {"evaluate", "--truth", d.dir, "--run", d.out, "--json", through + ".json"},
      {"import", "rplidar", d.dir + "/none", "--output-dir", through},
  };
  for (const auto& args : cases) {
    const auto r = run_cli(args);
    std::string line;
    for (const auto& a : args) line += a + " ";
    EXPECT_EQ(r.exit_code, 4) << line << "\n" << r.err;
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << line << "\n" << r.err;
    EXPECT_NE(r.err.find(file), std::string::npos) << "names the path: " << line << "\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(d.dir + "/m.tif")) << "merge checks its outputs before the work";
  EXPECT_FALSE(fs::exists(d.dir + "/c.pcd"));
  // A full disk (a file size limit, EFBIG, stands in for ENOSPC): exit 4, the old set stays.
  const Snapshot before = snapshot(d.out, false);
  const std::string cmd = "ulimit -f 64; trap '' XFSZ; exec '" + std::string(PCDP_CLI_PATH) + "' run '" + d.yaml +
                          "' -q 2>'" + d.dir + "/err.txt'";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 4) << test::read_text(d.dir + "/err.txt");
  EXPECT_NE(test::read_text(d.dir + "/err.txt").find("File too large"), std::string::npos);
  EXPECT_EQ(snapshot(d.out, false), before);
  EXPECT_TRUE(test::commit_leftovers(d.dir, "out").empty());
  // A read-only folder (not for root, who may write anyway).
  if (::geteuid() != 0) {
    fs::create_directories(d.dir + "/ro");
    fs::permissions(d.dir + "/ro", fs::perms::owner_read | fs::perms::owner_exec);
    const auto r = run_cli({"run", d.yaml, "-q", "--output-dir", d.dir + "/ro/out"});
    EXPECT_EQ(r.exit_code, 4) << r.err;
    fs::permissions(d.dir + "/ro", fs::perms::owner_all);
  }
}

// The new set is complete and only new: a product that an earlier run wrote and this run does not
// (map.ot once write_ot is off, elevation.png once png is off) does not stay beside the new files;
// the user's own files do.
TEST(CommitHardeningCli, AnEarlierRunsProductThatThisRunDoesNotWriteDoesNotStay) {
  Data d = make_data("  - type: fuse_elevation\n  - type: fuse_octomap\n    write_ot: true\n");
  ASSERT_EQ(run_cli({"run", d.yaml, "-q"}).exit_code, 0);
  ASSERT_TRUE(fs::exists(d.out + "/map.ot") && fs::exists(d.out + "/elevation.png"));
  test::write_text(d.out + "/notes.txt", "mine");
  const auto r = run_cli({"run", d.yaml, "-q", "--set", "stages.fuse_octomap.write_ot=false", "--set",
                          "stages.fuse_elevation.png=false"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(d.out + "/map.bt") && fs::exists(d.out + "/elevation.tif"));
  EXPECT_FALSE(fs::exists(d.out + "/map.ot"));
  EXPECT_FALSE(fs::exists(d.out + "/elevation.png"));
  EXPECT_EQ(test::read_text(d.out + "/notes.txt"), "mine");
}

// An output folder that is a mount point (a container volume, say) cannot be swapped: refused
// before any work with exit 4 and the fix (a folder inside it), its contents untouched. Needs the
// right to mount a tmpfs (root); skipped elsewhere.
TEST(CommitHardeningCli, AnOutputFolderThatIsAMountPointIsRefusedBeforeTheWork) {
  Data d = make_data("  - type: fuse_elevation\n");
  fs::create_directories(d.out);
  if (std::system(("mount -t tmpfs pcdp-test " + d.out + " 2>/dev/null").c_str()) != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here";
  test::write_text(d.out + "/keep.txt", "volume content");
  const auto r = run_cli({"run", d.yaml, "-q"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("is a mount point"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("/run"), std::string::npos) << r.err;
  EXPECT_EQ(test::read_text(d.out + "/keep.txt"), "volume content");
  EXPECT_FALSE(fs::exists(d.out + "/returns.pcd"));
  // A folder inside the mount commits as usual.
  EXPECT_EQ(run_cli({"run", d.yaml, "-q", "--output-dir", d.out + "/run"}).exit_code, 0);
  EXPECT_TRUE(fs::exists(d.out + "/run/returns.pcd"));
  EXPECT_EQ(std::system(("umount " + d.out).c_str()), 0);
}
