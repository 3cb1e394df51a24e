// The elevation products from the command line against hostile sizes and inputs (issue 33,
// items 3, 6 and 13): a run at 5 mm on the sample fits in 600 MB of address space (the dense
// writer needed 1.65 GB); a pose jump past the grid's limit exits 3 naming the stage and the
// size; merge refuses the same grid twice and junk metadata, exit 3, naming the file and field.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;
using test::run_cli;

namespace {
const std::string kSource = PCDP_SOURCE_DIR;

/// run_cli in a child process whose address space (inherited by the tool) is limited to `bytes`.
test::CliResult run_cli_limited(const std::vector<std::string>& args, std::size_t bytes) {
  const std::string dir = test::fresh_dir("limited");
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    rlimit r{};
    r.rlim_cur = r.rlim_max = bytes;
    setrlimit(RLIMIT_AS, &r);
    try {
      const test::CliResult res = run_cli(args);
      test::write_text(dir + "/err", res.err);
      std::fflush(nullptr);
      _exit(res.exit_code);
    } catch (...) {  // the test process itself ran out under the limit: the tool could not start
      _exit(127);
    }
  }
  int status = 0;
  waitpid(pid, &status, 0);
  test::CliResult res;
  res.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  res.err = test::read_text(dir + "/err");
  return res;
}

/// The sample's poses with x and y moved by `dx` from the middle of the list on (a pose jump).
std::string jumped_poses(const std::string& dir, double dx) {
  std::ifstream in(kSource + "/sample_scans/poses.csv");
  std::string line, out;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (i == 0 || i < lines.size() / 2) {
      out += lines[i] + "\n";
      continue;
    }
    std::stringstream ss(lines[i]);
    std::vector<std::string> f;
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    char buf[64];
    for (int k = 1; k <= 2; ++k) {
      std::snprintf(buf, sizeof buf, "%.17g", std::stod(f[static_cast<std::size_t>(k)]) + dx);
      f[static_cast<std::size_t>(k)] = buf;
    }
    for (std::size_t k = 0; k < f.size(); ++k) out += (k ? "," : "") + f[k];
    out += "\n";
  }
  const std::string path = dir + "/poses.csv";
  test::write_text(path, out);
  return path;
}
}  // namespace

// Item 3: the sample at 5 mm (a 5,339 x 7,035-cell bounding box) in 600 MB of address space: the
// dense writer and picture needed 1.65 GB of resident memory. The file is sparse tiles.
TEST(GridsHardeningCli, AFineGridOnTheSampleCostsWhatItObserved) {
  PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED();
  const std::string dir = test::fresh_dir();
  const auto r = run_cli_limited({"run", kSource + "/pipelines/nodding_terrain.yaml", "--output-dir", dir + "/out", "-q",
                                  "--set", "stages.fuse_elevation.resolution=0.005"},
                                 std::size_t{600} << 20);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string report = test::read_text(dir + "/out/report.json");
  EXPECT_NE(report.find("\"png_cells_per_pixel\": 16"), std::string::npos);  // 7,035 cells: 4 x 4 a pixel
  EXPECT_LT(std::filesystem::file_size(dir + "/out/elevation.tif"), std::uintmax_t{8} << 20);
}

// Item 3: a 1.4 km pose jump at 1 mm spans up to 1.4 million cells each way, past the limit of
// 65,536 tiles: exit 3 naming the stage, the pass and the size, not an out-of-memory crash. On one
// thread and on several (the stage's two paths).
TEST(GridsHardeningCli, APoseJumpPastTheGridLimitIsAnInputErrorNamingTheStage) {
  PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED();
  const std::string dir = test::fresh_dir();
  const std::string poses = jumped_poses(dir, 1000.0);
  for (const char* threads : {"1", "2"}) {
    const auto r = run_cli_limited({"run", kSource + "/pipelines/nodding_terrain.yaml", "--output-dir", dir + "/out", "-q",
                                    "--threads", threads, "--set", "input.poses=" + poses, "--set",
                                    "stages.fuse_elevation.resolution=0.001", "--set", "stages.fuse_elevation.png=false"},
                                   std::size_t{1} << 30);
    EXPECT_EQ(r.exit_code, 3) << r.err;
    // Found as the pass that makes the jump is fused, not after the run: the error names it.
    EXPECT_NE(r.err.find("stage 'fuse_elevation' (fuse_elevation): with pass " + kSource + "/sample_scans/pass_"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find(".pcd: elevation.tif: the observed cells span "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("the limit is 65536 tiles"), std::string::npos) << r.err;
  }
}

// Items 6 and 13: merge refuses the same grid twice (one file, or a copy) and a grid whose
// metadata holds junk, exit 3, naming the files and the field.
TEST(GridsHardeningCli, MergeRefusesTheSameGridTwiceAndJunkMetadata) {
  const std::string dir = test::fresh_dir();
  auto r = run_cli({"run", kSource + "/pipelines/nodding_terrain.yaml", "--output-dir", dir + "/a", "-q", "--set",
                    "input.scans=" + kSource + "/sample_scans/pass_000.pcd", "--set", "stages.fuse_elevation.png=false"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string a = dir + "/a/elevation.tif";
  r = run_cli({"merge", a, a, "-o", dir + "/m.tif"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("are the same file"), std::string::npos) << r.err;
  std::filesystem::copy_file(a, dir + "/copy.tif");
  std::filesystem::copy_file(dir + "/a/elevation.state.tif", dir + "/copy.state.tif");  // what merge reads
  r = run_cli({"merge", a, dir + "/copy.tif", "-o", dir + "/m.tif"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("hold the same bytes"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/m.tif"));
  // PCDP_RESOLUTION 0.10000000000000001 -> 0.1junk followed by blanks' worth of junk: same length.
  std::string bytes = test::read_text(dir + "/a/elevation.state.tif");
  const std::string from = ">0.10000000000000001<", to = ">0.1junk000000000000<";
  const std::size_t at = bytes.find(from);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, from.size(), to);
  test::write_text(dir + "/junk.state.tif", bytes);
  std::filesystem::copy_file(a, dir + "/junk.tif");
  r = run_cli({"merge", a, dir + "/junk.tif", "-o", dir + "/m.tif"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find(dir + "/junk.state.tif: GDAL metadata item PCDP_RESOLUTION = '0.1junk000000000000' is not a number"),
            std::string::npos)
      << r.err;
}

// Running out of memory is a documented data error (exit 3, "out of memory"), never an internal
// error: the sample run under a sweep of address-space limits, from too small to start the tool
// to enough. Each limit ends in success, the out-of-memory error, or (below what the dynamic
// loader needs) a failure to start; at least one limit reaches the tool's own message.
TEST(GridsHardeningCli, OutOfMemoryIsAnInputErrorNeverAnInternalError) {
  PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED();
  const std::string dir = test::fresh_dir();
  int out_of_memory = 0, ok = 0;
  for (std::size_t mb = 30; mb <= 120; mb += 6) {
    const auto r = run_cli_limited({"run", kSource + "/pipelines/nodding_terrain.yaml", "--output-dir", dir + "/out", "-q"},
                                   mb << 20);
    EXPECT_EQ(r.err.find("internal error"), std::string::npos) << mb << " MB: " << r.err;
    if (r.exit_code == 3) {
      EXPECT_NE(r.err.find("out of memory"), std::string::npos) << mb << " MB: " << r.err;  // the tool's or a reader's words
      ++out_of_memory;
    } else if (r.exit_code == 0) {
      ++ok;
    } else {
      EXPECT_TRUE(r.exit_code == 127 || r.exit_code == -1 || r.exit_code > 128 || r.exit_code == 4)
          << mb << " MB: exit " << r.exit_code << " " << r.err;
    }
  }
  EXPECT_GT(out_of_memory, 0);
  EXPECT_GT(ok, 0);
}
