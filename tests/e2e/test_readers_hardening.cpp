// End-to-end: hostile inputs to the readers end with a clear message and the right exit code (3 for
// data, 2 for the pipeline file), never a crash, a hang or `internal error`.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <tuple>

#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;

namespace {

const std::string kSource = PCDP_SOURCE_DIR;
const std::string kPipeline = kSource + "/pipelines/nodding_terrain.yaml";

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Like test::run_cli, with a time limit (a reader that blocks on a FIFO must fail the test, not hang
// it) and a chosen stdin.
test::CliResult run_cli_limited(const std::vector<std::string>& args, const std::string& stdin_redirect = "</dev/null") {
  const std::string dir = test::fresh_dir("cli");
  std::string cmd = "timeout -k 5 30 " + quote(PCDP_CLI_PATH);
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote(dir + "/stdout") + " 2>" + quote(dir + "/stderr") + " " + stdin_redirect;
  const int status = std::system(cmd.c_str());
  test::CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = test::read_text(dir + "/stdout");
  r.err = test::read_text(dir + "/stderr");
  return r;
}

test::CliResult run_sample(const std::vector<std::string>& sets, const std::string& out,
                           const std::string& stdin_redirect = "</dev/null") {
  std::vector<std::string> args = {"run", kPipeline, "--output-dir", out};
  for (const auto& s : sets) {
    args.push_back("--set");
    args.push_back(s);
  }
  return run_cli_limited(args, stdin_redirect);
}

void expect_input_error(const test::CliResult& r, const std::string& needle, int code = 3) {
  EXPECT_EQ(r.exit_code, code) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err << "\nexpected: " << needle;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
}

// A copy of a sample pass with extra fields (U2, value 1000 k + point index) appended.
void add_extras(const std::string& src, const std::string& dst, const std::vector<std::string>& names) {
  const io::PcdTable t = io::read_pcd(src);
  std::vector<io::PcdField> fields = t.header.fields;
  for (const auto& n : names) fields.push_back({n, 'U', 2, 1});
  io::PcdWriter w(dst + ".tmp", fields);
  std::vector<std::uint8_t> row(w.point_bytes());
  for (std::uint64_t p = 0; p < t.header.points; ++p) {
    std::size_t off = 0;
    for (std::size_t i = 0; i < t.header.fields.size(); ++i) {
      const std::size_t b = t.header.fields[i].bytes();
      std::memcpy(row.data() + off, t.columns[i].data() + p * b, b);
      off += b;
    }
    for (std::size_t k = 0; k < names.size(); ++k) {
      const auto v = static_cast<std::uint16_t>((1000 * k + p) & 0xffff);
      std::memcpy(row.data() + off, &v, 2);
      off += 2;
    }
    w.append(row.data(), 1);
  }
  w.close(t.header.height);
  fs::rename(dst + ".tmp", dst);
}

}  // namespace

// Items 10 and 15: FIFOs, devices, directories and symlink loops as inputs are refused up front.
TEST(ReadersHardeningCli, NonRegularInputsAreRefusedUpFront) {
  const std::string dir = test::fresh_dir("inputs");
  const std::string fifo = dir + "/fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string out = dir + "/out";

  expect_input_error(run_sample({"input.poses=" + fifo}, out), "input.poses: '" + fifo + "' is a FIFO");
  expect_input_error(run_sample({"input.poses=/dev/zero"}, out), "input.poses: '/dev/zero' is a character device");
  expect_input_error(run_sample({"input.scans=[" + fifo + "]"}, out), "input.scans: '" + fifo + "' is a FIFO");
  expect_input_error(run_sample({"input.scans=[/dev/zero]"}, out), "is a character device");
  // /dev/stdin, whatever stdin is: a character device here, a pipe in the second run.
  expect_input_error(run_sample({"input.scans=[/dev/stdin]"}, out), "input.scans: '/dev/stdin' is a character device");
  expect_input_error(run_sample({"input.scans=[/dev/stdin]"}, out, "3<>" + quote(fifo) + " <" + quote(fifo)), "input.scans: '/dev/stdin' is a FIFO");
  // A glob that matches a symlink loop.
  fs::create_directories(dir + "/loop");
  fs::create_symlink("b.pcd", dir + "/loop/a.pcd");
  fs::create_symlink("a.pcd", dir + "/loop/b.pcd");
  expect_input_error(run_sample({"input.scans=" + dir + "/loop/*.pcd"}, out), "a.pcd' cannot open the pass file (Too many levels of symbolic links); a symlink loop?");
  // The pipeline file: exit 2.
  auto r = run_cli_limited({"run", fifo});
  expect_input_error(r, fifo + ": is a FIFO", 2);
  r = run_cli_limited({"validate", "/dev/zero"});
  expect_input_error(r, "/dev/zero: is a character device", 2);
  r = run_cli_limited({"run", dir});
  expect_input_error(r, "is a directory, not a pipeline file", 2);
  EXPECT_FALSE(fs::exists(out)) << "nothing written";

  // Merge inputs, import inputs, the calibration CSV, clean-cloud's input.
  r = run_cli_limited({"merge", fifo, "/dev/zero", "-o", dir + "/m.tif"});
  expect_input_error(r, fifo + ": is a FIFO");
  r = run_cli_limited({"merge", dir, dir, "-o", dir + "/m.tif"});
  expect_input_error(r, "is a directory, not a GeoTIFF");
  r = run_cli_limited({"import", "3dtk", fifo, "--output-dir", dir + "/imp"});
  expect_input_error(r, fifo + ": is a FIFO");
  r = run_cli_limited({"import", "octomap", "/dev/zero", "--output-dir", dir + "/imp"});
  expect_input_error(r, "/dev/zero: is a character device");
  r = run_cli_limited({"import", "cloud", fifo, "--output-dir", dir + "/imp"});
  expect_input_error(r, fifo + ": is a FIFO");
  r = run_cli_limited({"calibrate-range", fifo});
  expect_input_error(r, fifo + ": is a FIFO");
  r = run_cli_limited({"clean-cloud", "/dev/zero", "-o", dir + "/c.pcd"});
  expect_input_error(r, "/dev/zero: is a character device");
}

// Item 1 through the CLI: the overflowing header made `run` and `clean-cloud` segfault (binary) or
// run out of memory (ascii). Padding fields of COUNT up to 1e6 make a point `point_bytes` long.
TEST(ReadersHardeningCli, OverflowingPcdHeaderIsAnInputError) {
  const std::string dir = test::fresh_dir("overflow");
  const auto header = [](std::uint64_t point_bytes, std::uint64_t width, std::uint64_t height, const char* data) {
    std::string fields = "FIELDS line beam range bearing amplitude nod stamp x y z", size = "SIZE 4 4 4 4 4 4 8 4 4 4",
                type = "TYPE U U F F F F F F F F", count = "COUNT 1 1 1 1 1 1 1 1 1 1";
    std::uint64_t left = point_bytes - 44;
    while (left >= 8) {
      const std::uint64_t c = std::min<std::uint64_t>(left / 8, 1000000);
      fields += " _";
      size += " 8";
      type += " U";
      count += " " + std::to_string(c);
      left -= 8 * c;
    }
    return "VERSION 0.7\n" + fields + "\n" + size + "\n" + type + "\n" + count + "\nWIDTH " + std::to_string(width) +
           "\nHEIGHT " + std::to_string(height) + "\nPOINTS " + std::to_string(width * height) + "\nDATA " + data + "\n";
  };
  struct Case {
    std::uint64_t point_bytes, width, height;
    const char* rule;
  };
  // The file (2^25 points of 2^39 bytes: 68,720 padding fields), and a product that wraps
  // within the field bound (2^33 points of 2^31 bytes).
  for (const Case& c : {Case{(1ull << 39) + 4, 1ull << 25, 1, "fields; at most 10000 are supported"},
                        Case{(1ull << 31) + 4, 1ull << 25, 1ull << 8, "overflow 64-bit arithmetic"}}) {
    for (const char* data : {"binary", "ascii", "binary_compressed"}) {
      const std::string pcd = dir + "/overflow_" + data + ".pcd";
      test::write_text(pcd, header(c.point_bytes, c.width, c.height, data) + std::string(64, '0'));
      auto r = run_sample({"input.scans=[" + pcd + "]"}, dir + "/out");
      expect_input_error(r, pcd + ": header line");
      expect_input_error(r, c.rule);
      r = run_cli_limited({"clean-cloud", pcd, "-o", dir + "/c.pcd"});
      expect_input_error(r, pcd + ": header line");
      expect_input_error(r, c.rule);
    }
  }
}

// Item 5: extra input fields named like output fields are renamed input_<name>; the run's returns.pcd
// reads back, and every extra value travels with its return.
TEST(ReadersHardeningCli, ExtraFieldsNamedLikeOutputFieldsKeepReturnsPcdReadable) {
  const std::string dir = test::fresh_dir("extras");
  const std::vector<std::string> names = {"x", "label", "pass", "flags", "sigma_h", "echo"};
  for (int k = 0; k < 4; ++k) {
    const std::string name = "/pass_00" + std::to_string(k) + ".pcd";
    add_extras(kSource + "/sample_scans" + name, dir + name, names);
  }
  const auto r = run_sample({"input.scans=" + dir + "/pass_*.pcd"}, dir + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const io::PcdTable t = io::read_pcd(dir + "/out/returns.pcd");  // used to fail: field 'x' appears twice
  const auto line = test::column(t, "line"), beam = test::column(t, "beam"), pass = test::column(t, "pass");
  ASSERT_GT(line.size(), 0u);
  const std::vector<std::string> renamed = {"input_x", "input_label", "input_pass", "input_flags", "input_sigma_h", "echo"};
  // Where each return was in its file: (pass, line, beam) -> point index.
  std::map<std::tuple<int, int, int>, std::uint64_t> where;
  for (int k = 0; k < 4; ++k) {
    const io::PcdTable s = io::read_pcd(dir + "/pass_00" + std::to_string(k) + ".pcd");
    const auto sl = test::column(s, "line"), sb = test::column(s, "beam");
    for (std::size_t p = 0; p < sl.size(); ++p) where[{k, static_cast<int>(sl[p]), static_cast<int>(sb[p])}] = p;
  }
  ASSERT_EQ(where.size(), line.size());
  for (std::size_t k = 0; k < renamed.size(); ++k) {
    const auto v = test::column(t, renamed[k]);
    ASSERT_EQ(v.size(), line.size()) << renamed[k];
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::uint64_t p = where.at({static_cast<int>(pass[i]), static_cast<int>(line[i]), static_cast<int>(beam[i])});
      wrong += v[i] != static_cast<double>((1000 * k + p) & 0xffff);
    }
    EXPECT_EQ(wrong, 0u) << renamed[k];
  }
  EXPECT_EQ(test::column(t, "label").size(), line.size());
  EXPECT_EQ(test::column(t, "pass").back(), 3.0);
}
