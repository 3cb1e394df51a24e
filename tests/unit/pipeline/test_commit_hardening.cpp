// The output commit under fault injection: every filesystem step of a commit fails in turn, and
// the process is killed at every step; after each, the output folder holds exactly the complete
// old set or the complete new set (file lists and contents), and the next run removes the
// leftovers. Also: the lock, the signal cleanup, the single-file sets (merge, clean-cloud).
#include <algorithm>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;

namespace {

using Snapshot = std::map<std::string, std::string>;  // relative path -> content ("<dir>" for folders)

Snapshot snapshot(const std::string& dir) {
  Snapshot s;
  if (!fs::exists(dir)) {
    s["<absent>"] = "";
    return s;
  }
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(e.path(), dir).string();
    s[rel] = e.is_directory() ? "<dir>" : test::read_text(e.path().string());
  }
  return s;
}

// The hook: counts steps; fails step g_fail_at (errno g_fail_errno), kills at g_kill_at, and
// reports "no RENAME_EXCHANGE here" (EINVAL) for exchange steps when g_no_exchange.
int g_steps = 0, g_fail_at = 0, g_kill_at = 0, g_fail_errno = EIO;
bool g_no_exchange = false;
int hook(int step, const char* what) {
  g_steps = step;
  if (step == g_kill_at) ::kill(::getpid(), SIGKILL);
  if (step == g_fail_at) return g_fail_errno;
  if (g_no_exchange && std::strcmp(what, "exchange") == 0) return EINVAL;
  return 0;
}
void reset_hook() {
  g_steps = g_fail_at = g_kill_at = 0;
  g_fail_errno = EIO;
  g_no_exchange = false;
  io::detail::set_commit_step_hook(hook);
}

/// The old folder: products of an earlier run, one product this run does not write (map.bt),
/// the user's own file and folder.
void make_old_set(const std::string& out) {
  fs::create_directories(out + "/sub");
  test::write_text(out + "/returns.pcd", "old returns");
  test::write_text(out + "/report.json", "old report");
  test::write_text(out + "/map.bt", "old map");
  test::write_text(out + "/notes.txt", "the user's notes");
  test::write_text(out + "/sub/f.txt", "the user's sub file");
}

/// One run's output: stage three products and commit.
void run_commit(const std::string& out) {
  io::StagedOutputs s(out);
  test::write_text(s.staged_path("returns.pcd"), "new returns");
  test::write_text(s.staged_path("report.json"), "new report");
  test::write_text(s.staged_path("elevation.tif"), "new tif");
  s.commit();
}

Snapshot expected_new(const Snapshot& old) {
  Snapshot n = old;
  n.erase("<absent>");
  n["returns.pcd"] = "new returns";
  n["report.json"] = "new report";
  n["elevation.tif"] = "new tif";
  return n;
}

/// Each step failed in turn, then killed at each step; with or without an old folder, with or
/// without RENAME_EXCHANGE.
void fault_matrix(bool with_old, bool no_exchange) {
  const std::string base = test::fresh_dir(std::string(with_old ? "old" : "none") + (no_exchange ? "_noexch" : ""));
  const std::string out = base + "/out";
  const auto prepare = [&] {
    fs::remove_all(out);
    for (const auto& l : test::commit_leftovers(base, "out")) fs::remove_all(base + "/" + l);
    if (with_old) make_old_set(out);
  };
  prepare();
  const Snapshot old = snapshot(out), fresh = expected_new(old);
  // How many steps a commit has.
  reset_hook();
  g_no_exchange = no_exchange;
  run_commit(out);
  const int steps = g_steps;
  ASSERT_GE(steps, with_old ? 5 : 1);
  EXPECT_EQ(snapshot(out), fresh);
  EXPECT_TRUE(test::commit_leftovers(base, "out").empty());

  for (int k = 1; k <= steps; ++k) {
    SCOPED_TRACE("step " + std::to_string(k) + " of " + std::to_string(steps));
    // Fail step k.
    prepare();
    reset_hook();
    g_no_exchange = no_exchange;
    g_fail_at = k;
    bool threw = false;
    try {
      run_commit(out);
    } catch (const OutputError& e) {
      threw = true;
      EXPECT_NE(std::string(e.what()).find("output_dir"), std::string::npos) << e.what();
    }
    const Snapshot after = snapshot(out);
    EXPECT_TRUE(after == old || after == fresh) << "a mix after a failed step " << k;
    if (threw) {
      EXPECT_EQ(after, old) << "a commit that reports failure leaves the old set";
    }
    {  // the next run removes whatever was left, and the folder is still whole
      io::StagedOutputs next(out);
    }
    EXPECT_TRUE(test::commit_leftovers(base, "out").empty());
    EXPECT_EQ(snapshot(out), after);

    // Kill at step k.
    prepare();
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      reset_hook();
      g_no_exchange = no_exchange;
      g_kill_at = k;
      try {
        run_commit(out);
      } catch (...) {
        _exit(3);
      }
      _exit(0);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child was not killed at step " << k;
    const Snapshot killed = snapshot(out);
    {  // recovery by the next run into the folder
      io::StagedOutputs next(out);
    }
    EXPECT_TRUE(test::commit_leftovers(base, "out").empty());
    const Snapshot recovered = snapshot(out);
    EXPECT_TRUE(recovered == old || recovered == fresh) << "a mix after a kill at step " << k;
    // With RENAME_EXCHANGE the folder is whole even before the recovery.
    if (!no_exchange) {
      EXPECT_EQ(killed, recovered);
    }
  }
  io::detail::set_commit_step_hook(nullptr);
}

}  // namespace

TEST(CommitHardening, EveryStepFailedOrKilledLeavesTheOldOrTheNewSet) { fault_matrix(true, false); }
TEST(CommitHardening, IntoANewFolderEveryStepFailedOrKilled) { fault_matrix(false, false); }
TEST(CommitHardening, WithoutRenameExchangeEveryStepFailedOrKilled) { fault_matrix(true, true); }

TEST(CommitHardening, TheNewSetKeepsTheUsersFilesAsTheSameFiles) {
  const std::string out = test::fresh_dir() + "/out";
  make_old_set(out);
  const auto inode = [](const std::string& p) { return fs::hard_link_count(p); };
  run_commit(out);
  EXPECT_EQ(test::read_text(out + "/notes.txt"), "the user's notes");
  EXPECT_EQ(test::read_text(out + "/sub/f.txt"), "the user's sub file");
  EXPECT_EQ(test::read_text(out + "/map.bt"), "old map");
  EXPECT_EQ(inode(out + "/notes.txt"), 1u) << "the old set's link is gone";
}

TEST(CommitHardening, TemporariesOfKilledRunsOfEarlierVersionsAreNotCarriedOver) {
  const std::string out = test::fresh_dir() + "/out";
  make_old_set(out);
  for (const char* n : {".returns.pcd.tmp-123.body", ".report.json.tmp-9", ".elevation.tif.tmp-77.tmp-write.tif",
                        ".elevation.png.tmp-77.tmp-png"})
    test::write_text(out + "/" + n, "junk");
  test::write_text(out + "/.my.tmp-notes", "the user's");    // not a pid: kept
  test::write_text(out + "/.notes.tmp-2024", "the user's");  // not a product's temporary: kept
  run_commit(out);
  std::vector<std::string> hidden;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().filename().string()[0] == '.') hidden.push_back(e.path().filename().string());
  std::sort(hidden.begin(), hidden.end());
  EXPECT_EQ(hidden, (std::vector<std::string>{".my.tmp-notes", ".notes.tmp-2024"}));
}

std::string g_late_file;
int write_late(int, const char* what) {
  if (std::strcmp(what, "exchange") == 0) test::write_text(g_late_file, "written during the commit");
  return 0;
}

TEST(CommitHardening, AFileTheUserAddsDuringTheCommitMovesToTheNewSet) {
  const std::string out = test::fresh_dir() + "/out";
  make_old_set(out);
  g_late_file = out + "/late.txt";  // into the old folder, after the carry-over, before the swap
  io::detail::set_commit_step_hook(write_late);
  run_commit(out);
  io::detail::set_commit_step_hook(nullptr);
  EXPECT_EQ(test::read_text(out + "/late.txt"), "written during the commit");
  EXPECT_EQ(test::read_text(out + "/returns.pcd"), "new returns");
}

TEST(CommitHardening, AFolderNamedLikeAProductIsRefusedBeforeTheWork) {
  const std::string out = test::fresh_dir() + "/out";
  make_old_set(out);
  fs::create_directories(out + "/elevation.tif/inside");
  const Snapshot old = snapshot(out);
  io::StagedOutputs s(out);
  EXPECT_THROW(s.check_replaceable({"returns.pcd", "elevation.tif"}), OutputError);
  test::write_text(s.staged_path("elevation.tif"), "new tif");
  EXPECT_THROW(s.commit(), OutputError);  // the commit checks again
  EXPECT_EQ(snapshot(out), old);
}

TEST(CommitHardening, AnInputNamedLikeAProductIsRefusedBeforeTheWork) {
  const std::string out = test::fresh_dir() + "/out";
  make_old_set(out);
  test::write_text(out + "/pass_000.pcd", "the user's scan");
  const Snapshot old = snapshot(out);
  {  // owned after the inputs are named
    io::StagedOutputs s(out);
    s.protect_inputs({out + "/pass_000.pcd", out + "/../out/notes.txt"});
    EXPECT_NO_THROW(s.owns({"returns.pcd", "map.bt"}));
    EXPECT_THROW(s.owns({"returns.pcd", "pass_000.pcd"}), ConfigError);
  }
  {  // named after the products are staged, through another spelling of the folder
    io::StagedOutputs s(out);
    test::write_text(s.staged_path("pass_000.pcd"), "new");
    EXPECT_THROW(s.protect_inputs({fs::path(out).parent_path().string() + "/./out/pass_000.pcd"}), ConfigError);
  }
  {  // a product a command writes straight into the staging folder: the commit refuses it
    io::StagedOutputs s(out);
    s.protect_inputs({out + "/pass_000.pcd"});
    test::write_text(s.staging_dir() + "/pass_000.pcd", "new");
    EXPECT_THROW(s.commit(), ConfigError);
  }
  EXPECT_EQ(snapshot(out), old);
  {  // an input elsewhere, or inside the folder under another name, is no concern
    io::StagedOutputs s(out);
    s.protect_inputs({out + "/pass_000.pcd", out + "/mine/cloud.pcd"});
    test::write_text(s.staged_path("cloud.pcd"), "new");
    EXPECT_NO_THROW(s.commit());
  }
  EXPECT_EQ(test::read_text(out + "/pass_000.pcd"), "the user's scan");
}

/// Runs `fn` as an unprivileged user (nobody, forked, when this process is root: root may write
/// into read-only folders); its text is empty on success, else the failure.
std::string as_unprivileged(const std::string& owned_tree, const std::function<std::string()>& fn) {
  if (::geteuid() != 0) return fn();
  for (const auto& e : fs::recursive_directory_iterator(owned_tree)) (void)::lchown(e.path().c_str(), 65534, 65534);
  (void)::chown(owned_tree.c_str(), 65534, 65534);
  int fds[2];
  if (::pipe(fds) != 0) return "pipe failed";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    std::string r = !(::setgid(65534) == 0 && ::setuid(65534) == 0) ? "cannot become nobody"
                    : ::access(owned_tree.c_str(), W_OK | X_OK) != 0 ? "SKIP: nobody cannot reach " + owned_tree
                                                                       : fn();
    if (::write(fds[1], r.data(), r.size()) < 0) r.clear();
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string r;
  char buf[256];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) r.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? r : "the child died";
}

TEST(CommitHardening, AReadOnlyFolderIsRefusedAndReadOnlyLeftoversAreRemoved) {
  const std::string base = test::fresh_dir();
  ::chmod(base.c_str(), 0755);
  const std::string out = base + "/out";
  make_old_set(out);
  // A leftover of a killed run whose folders a copied mode made read-only.
  fs::create_directories(base + "/.out.pcdp-new-999/sub");
  test::write_text(base + "/.out.pcdp-new-999/sub/f", "old");
  const std::string result = as_unprivileged(base, [&]() -> std::string {
    ::chmod((base + "/.out.pcdp-new-999/sub").c_str(), 0555);
    ::chmod((base + "/.out.pcdp-new-999").c_str(), 0555);
    ::chmod(out.c_str(), 0555);
    try {
      io::StagedOutputs s(out);
      return "a read-only output folder was accepted";
    } catch (const OutputError& e) {
      if (std::string(e.what()).find("read-only") == std::string::npos) return std::string("message: ") + e.what();
    }
    ::chmod(out.c_str(), 0755);
    try {
      io::StagedOutputs s(out);
      test::write_text(s.staged_path("returns.pcd"), "new");
      s.commit();
    } catch (const std::exception& e) {
      return std::string("the writable folder failed: ") + e.what();
    }
    return fs::exists(base + "/.out.pcdp-new-999") ? "the read-only leftover stayed" : "";
  });
  if (result.rfind("SKIP", 0) == 0) GTEST_SKIP() << result;  // a parent folder closed to other users
  EXPECT_EQ(result, "");
  EXPECT_EQ(test::read_text(out + "/returns.pcd"), "new");
}

TEST(CommitHardening, AProductStagedTwiceIsABug) {
  const std::string out = test::fresh_dir() + "/out";
  io::StagedOutputs s(out);
  s.staged_path("map.bt");
  EXPECT_THROW(s.staged_path("map.bt"), std::logic_error);
}

TEST(CommitHardening, AFailedRunLeavesNoFolderItCreated) {
  const std::string base = test::fresh_dir();
  {
    io::StagedOutputs s(base + "/a/b/out");
    test::write_text(s.staged_path("returns.pcd"), "x");
  }  // not committed
  EXPECT_FALSE(fs::exists(base + "/a"));
  EXPECT_TRUE(fs::is_empty(base));
  // A parent that cannot be created (a name too long): the ones created before it go too.
  EXPECT_THROW(io::StagedOutputs(base + "/a/" + std::string(300, 'n') + "/out"), OutputError);
  EXPECT_TRUE(fs::is_empty(base));
}

TEST(CommitHardening, OutputPathsAreChecked) {
  EXPECT_THROW(io::check_output_path("output_dir", ""), ConfigError);
  EXPECT_THROW(io::check_output_path("output_dir", "a\nb"), ConfigError);
  EXPECT_THROW(io::check_output_path("output_dir", "/"), ConfigError);
  EXPECT_THROW(io::check_output_path("output_dir", ".."), ConfigError);
  EXPECT_NO_THROW(io::check_output_path("output_dir", "out/"));
  const std::string base = test::fresh_dir();
  test::write_text(base + "/file", "x");
  EXPECT_THROW(io::StagedOutputs(base + "/file"), OutputError);
  EXPECT_THROW(io::StagedOutputs(base + "/file/out"), OutputError);
  // A name that fits the filesystem but not with the lock file's additions: said so, not "must be writable".
  try {
    io::StagedOutputs s(base + "/" + std::string(250, 'n'));
    ADD_FAILURE() << "a 250-byte folder name was accepted";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("(250 bytes) is too long"), std::string::npos) << e.what();
  }
}

TEST(CommitHardening, OneRunAtATimePerOutputAndADeadHolderBlocksNothing) {
  const std::string base = test::fresh_dir();
  {
    io::StagedOutputs first(base + "/out");
    try {
      io::StagedOutputs second(base + "/out");
      ADD_FAILURE() << "a second run into the folder was let in";
    } catch (const OutputError& e) {
      EXPECT_NE(std::string(e.what()).find("another pcd_pipeline process (pid " + std::to_string(getpid()) + ")"),
                std::string::npos)
          << e.what();
    }
    io::StagedOutputs other(base + "/other");  // another folder: not blocked
  }
  // A holder killed with its lock: the kernel releases it.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    io::OutputLock hold(base + "/out");
    ::kill(::getpid(), SIGKILL);
    _exit(0);
  }
  waitpid(pid, nullptr, 0);
  EXPECT_TRUE(fs::exists(base + "/.out.pcdp-lock"));
  { io::StagedOutputs after(base + "/out"); }
  EXPECT_TRUE(test::commit_leftovers(base, "out").empty()) << "the lock file goes with its holder";
}

TEST(CommitHardening, SigtermRemovesTheStagedFilesAndExits143) {
  const std::string base = test::fresh_dir();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    io::install_signal_cleanup();
    io::StagedOutputs s(base + "/out");
    test::write_text(s.staged_path("returns.pcd") + ".body", std::string(100000, 'x'));
    fs::create_directories(s.staging_dir() + "/truth/deeper");
    test::write_text(s.staging_dir() + "/truth/deeper/f", "x");
    io::StagedFiles f;
    const std::string tmp = f.add("--png", base + "/m.png");
    test::write_text(tmp, "png");
    test::write_text(tmp + ".body", "a writer's own temporary");
    ::raise(SIGTERM);
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 143);
  EXPECT_TRUE(fs::is_empty(base)) << "staging folder, temporary file and lock files all removed";
}

TEST(CommitHardening, SingleFileSetsRollBackWhenAStepFails) {
  const std::string base = test::fresh_dir();
  const std::string tif = base + "/m.tif", png = base + "/m.png";
  test::write_text(tif, "old tif");  // the PNG does not exist yet
  for (bool no_exchange : {false, true}) {
    reset_hook();
    g_no_exchange = no_exchange;
    {
      io::StagedFiles f;
      test::write_text(f.add("-o", tif), "new tif");
      test::write_text(f.add("--png", png), "new png");
      f.commit();
    }
    const int steps = g_steps;
    test::write_text(tif, "old tif");
    fs::remove(png);
    for (int k = 1; k <= steps; ++k) {
      SCOPED_TRACE("step " + std::to_string(k));
      reset_hook();
      g_no_exchange = no_exchange;
      g_fail_at = k;
      io::StagedFiles f;
      test::write_text(f.add("-o", tif), "new tif");
      test::write_text(f.add("--png", png), "new png");
      EXPECT_THROW(f.commit(), OutputError);
      EXPECT_EQ(test::read_text(tif), "old tif");
      EXPECT_FALSE(fs::exists(png));
    }
  }
  io::detail::set_commit_step_hook(nullptr);
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(base)) entries += e.path().filename() == "m.tif" ? 1 : 100;
  EXPECT_EQ(entries, 1u) << "no temporary left";
  // A second writer of the same file is refused while the first holds it.
  io::StagedFiles first;
  first.add("-o", tif);
  io::StagedFiles second;
  EXPECT_THROW(second.add("-o", tif), OutputError);
}

TEST(CommitHardening, WriteFileAtomicReportsOutputErrors) {
  const std::string base = test::fresh_dir();
  test::write_text(base + "/file", "x");
  EXPECT_THROW(io::write_file_atomic(base + "/file/x.csv", "a"), OutputError);
  EXPECT_THROW(io::write_file_atomic(base + "/missing/x.csv", "a"), OutputError);
  fs::create_directories(base + "/dir.csv");
  EXPECT_THROW(io::write_file_atomic(base + "/dir.csv", "a"), OutputError);
  io::write_file_atomic(base + "/ok.csv", "a");
  EXPECT_EQ(test::read_text(base + "/ok.csv"), "a");
}
