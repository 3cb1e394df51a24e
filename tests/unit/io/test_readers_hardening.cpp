// Hostile inputs to the readers: size arithmetic that overflows, headers that repeat or disagree,
// junk around numbers, non-regular files, extra fields named like output fields.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <set>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;

namespace {

const std::string kRequired = "line beam range bearing amplitude nod stamp";

std::string error_of_poses(const std::string& content) {
  const std::string path = test::fresh_dir("readers") + "/poses.csv";
  test::write_text(path, content);
  try {
    io::read_pose_csv(path, RpyOrder::kXyz);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// A header whose padding fields ('_', SIZE 8, COUNT up to 1e6) make one point `point_bytes` long
// (the 7 required fields take 32 of them).
std::string padded_header(std::uint64_t point_bytes, std::uint64_t width, std::uint64_t height, const char* data) {
  std::string fields = "FIELDS " + kRequired, size = "SIZE 4 4 4 4 4 4 8", type = "TYPE U U F F F F F",
              count = "COUNT 1 1 1 1 1 1 1";
  std::uint64_t left = point_bytes - 32;
  while (left > 0) {
    const std::uint64_t c = std::min<std::uint64_t>(left / 8, 1000000);
    if (c == 0) break;
    fields += " _";
    size += " 8";
    type += " U";
    count += " " + std::to_string(c);
    left -= 8 * c;
  }
  EXPECT_EQ(left, 0u) << "point_bytes must be 32 + a multiple of 8";
  return "VERSION 0.7\n" + fields + "\n" + size + "\n" + type + "\n" + count + "\nWIDTH " + std::to_string(width) +
         "\nHEIGHT " + std::to_string(height) + "\nPOINTS " + std::to_string(width * height) + "\nDATA " + data + "\n";
}

const char* kAsciiHeader =
    "VERSION 0.7\nFIELDS line beam range bearing amplitude nod stamp\nSIZE 4 4 4 4 4 4 8\nTYPE U U F F F F F\n"
    "COUNT 1 1 1 1 1 1 1\n";
const char* kRow = "0 0 1.5 0 10 0 1.0";

std::string one_point_ascii(const std::string& header = kAsciiHeader, const std::string& size_lines =
                                                                           "WIDTH 1\nHEIGHT 1\nPOINTS 1\n") {
  return header + size_lines + "DATA ascii\n" + kRow + "\n";
}

}  // namespace

// Item 1: points x point bytes wraps to 0 (2^33 x 2^31 and 2^25 x 2^8 x 2^31): refused by the header,
// naming the file and the line, before anything is allocated.
TEST(ReadersHardening, PcdSizeArithmeticThatOverflowsIsRefused) {
  const std::uint64_t pb = 1ull << 31;
  for (const auto& wh : {std::pair<std::uint64_t, std::uint64_t>{1ull << 33, 1}, {1ull << 25, 1ull << 8}}) {
    for (const char* data : {"binary", "binary_compressed", "ascii"}) {
      const std::string e = test::pass_read_error(padded_header(pb, wh.first, wh.second, data));
      EXPECT_NE(e.find("p.pcd: header line"), std::string::npos) << data << ": " << e;
      EXPECT_NE(e.find("overflow 64-bit arithmetic"), std::string::npos) << data << ": " << e;
    }
  }
}

// The ascii variant of the crash: sum(COUNT) x points x 2 wrapped to 0 and the columns were sized by
// the header's claim (2.1 GB from a 481 KB file).
TEST(ReadersHardening, AsciiPcdIsNeverSizedByTheHeadersClaim) {
  // 1074 padding fields of COUNT ~1e6, SIZE 1: 2^30 values per point, 2^33 points.
  std::string fields = "FIELDS " + kRequired, size = "SIZE 4 4 4 4 4 4 8", type = "TYPE U U F F F F F",
              count = "COUNT 1 1 1 1 1 1 1";
  std::uint64_t left = (1ull << 30) - 7;
  while (left > 0) {
    const std::uint64_t c = std::min<std::uint64_t>(left, 1000000);
    fields += " _";
    size += " 1";
    type += " U";
    count += " " + std::to_string(c);
    left -= c;
  }
  const std::string h = "VERSION 0.7\n" + fields + "\n" + size + "\n" + type + "\n" + count +
                        "\nWIDTH 8589934592\nHEIGHT 1\nPOINTS 8589934592\nDATA ascii\n";
  const std::string e = test::pass_read_error(h + std::string(1000, '0'));
  EXPECT_NE(e.find("p.pcd: header line"), std::string::npos) << e;
  EXPECT_NE(e.find("POINTS"), std::string::npos) << e;

  // Within 64 bits but beyond what the file holds in any encoding: refused by the header too.
  const std::string big = padded_header(32 + 8 * 1000000, 1000, 1, "ascii") + "0 0 1.5 0 10 0 1.0\n";
  const std::string e2 = test::pass_read_error(big);
  EXPECT_NE(e2.find("truncated: the header claims 1000 points (8000032000 bytes)"), std::string::npos) << e2;
  EXPECT_NE(e2.find("too few for any PCD encoding"), std::string::npos) << e2;
}

// Item 9: the duplicate-name check is O(n log n); the field count is bounded (10,000).
TEST(ReadersHardening, ManyFieldsAreCheckedFastAndBounded) {
  const auto many = [](std::size_t n, bool dup_at_end) {
    std::string fields = "FIELDS " + kRequired, size = "SIZE 4 4 4 4 4 4 8", type = "TYPE U U F F F F F";
    std::string row = kRow;
    for (std::size_t i = 7; i < n; ++i) {
      fields += " f" + std::to_string(dup_at_end && i + 1 == n ? 7 : i);
      size += " 1";
      type += " U";
      row += " 0";
    }
    return "VERSION 0.7\n" + fields + "\n" + size + "\n" + type + "\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n" + row + "\n";
  };
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(test::pass_read_error(many(10000, false)), "(no error)");
  const std::string dup = test::pass_read_error(many(10000, true));
  EXPECT_NE(dup.find("p.pcd: header line 2 (FIELDS): field 'f7' appears twice in FIELDS"), std::string::npos) << dup;
  const std::string over = test::pass_read_error(many(70000, false));
  EXPECT_NE(over.find("header line 2 (FIELDS): 70000 fields; at most 10000 are supported"), std::string::npos) << over;
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(s, 5.0) << "three headers of 10,000 to 70,000 fields";
  // Padding fields may repeat.
  const std::string pad = std::string("VERSION 0.7\nFIELDS ") + kRequired +
                          " _ _\nSIZE 4 4 4 4 4 4 8 1 1\nTYPE U U F F F F F U U\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n" +
                          kRow + " 0 0\n";
  EXPECT_EQ(test::pass_read_error(pad), "(no error)");
}

// Item 13: repeated header keys, HEIGHT 0 with points, junk in numbers, NUL bytes, trailing bytes.
TEST(ReadersHardening, PcdHeaderIsStrict) {
  EXPECT_EQ(test::pass_read_error(one_point_ascii()), "(no error)");
  std::string e = test::pass_read_error(one_point_ascii(kAsciiHeader, "WIDTH 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"));
  EXPECT_NE(e.find("p.pcd: header line 7 (WIDTH): a second WIDTH line (the first is header line 6)"), std::string::npos) << e;
  for (const char* key : {"VERSION 0.7\n", "SIZE 4 4 4 4 4 4 8\n", "TYPE U U F F F F F\n", "COUNT 1 1 1 1 1 1 1\n",
                          "FIELDS line beam range bearing amplitude nod stamp\n", "COLUMNS line beam range bearing amplitude nod stamp\n",
                          "VIEWPOINT 0 0 0 1 0 0 0\nVIEWPOINT 0 0 0 1 0 0 0\n"}) {
    e = test::pass_read_error(one_point_ascii(std::string(kAsciiHeader) + key));
    EXPECT_NE(e.find(": a second "), std::string::npos) << key << e;
  }
  e = test::pass_read_error(one_point_ascii(kAsciiHeader, "WIDTH 1\nHEIGHT 1\nPOINTS 1\nPOINTS 1\n"));
  EXPECT_NE(e.find("a second POINTS line"), std::string::npos) << e;
  // WIDTH 5 HEIGHT 0: POINTS 0 agrees with the product, but no file has 5 points in 0 rows.
  e = test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 5\nHEIGHT 0\nPOINTS 0\nDATA ascii\n");
  EXPECT_NE(e.find("p.pcd: header line 7 (HEIGHT): HEIGHT 0 with WIDTH 5"), std::string::npos) << e;
  e = test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 5\nHEIGHT 0\nDATA ascii\n");
  EXPECT_NE(e.find("HEIGHT 0 with WIDTH 5"), std::string::npos) << e;
  e = test::pass_read_error(one_point_ascii(kAsciiHeader, "WIDTH 1\nHEIGHT 1\nPOINTS 2\n"));
  EXPECT_NE(e.find("header line 8 (POINTS): POINTS 2 disagrees with WIDTH x HEIGHT = 1 x 1"), std::string::npos) << e;
  // An empty file as PCL writes it (WIDTH 0 HEIGHT 0) and as we write it (WIDTH 0 HEIGHT 1) stay valid.
  EXPECT_EQ(test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 0\nHEIGHT 0\nPOINTS 0\nDATA ascii\n"), "(no error)");
  EXPECT_EQ(test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 0\nHEIGHT 1\nPOINTS 0\nDATA ascii\n"), "(no error)");
  // Junk after a number, and a NUL that used to end the number early.
  for (const std::string& bad : std::vector<std::string>{"WIDTH 1junk", "WIDTH 1.0", "WIDTH 0x1", "WIDTH 1 1", std::string("WIDTH 1\0junk", 12)}) {
    e = test::pass_read_error(one_point_ascii(kAsciiHeader, bad + "\nHEIGHT 1\nPOINTS 1\n"));
    EXPECT_NE(e.find("p.pcd: header line 6"), std::string::npos) << bad << ": " << e;
  }
  e = test::pass_read_error(one_point_ascii(std::string(kAsciiHeader) + "VIEWPOINT 0 0 0 1 0 0 0.1junk\n"));
  EXPECT_NE(e.find("'0.1junk' is not a finite number"), std::string::npos) << e;
  std::string h = kAsciiHeader;
  h.replace(h.find("SIZE 4 4 4 4 4 4 8"), 18, "SIZE 4 4 4 4 4 4 8x");
  e = test::pass_read_error(one_point_ascii(h));
  EXPECT_NE(e.find("header line 3 (SIZE): field 'stamp': SIZE '8x' must be 1, 2, 4 or 8"), std::string::npos) << e;
  h = kAsciiHeader;
  h.replace(h.find("COUNT 1 1 1 1 1 1 1"), 19, "COUNT 1 1 1 1 1 1 1junk");
  e = test::pass_read_error(one_point_ascii(h));
  EXPECT_NE(e.find("header line 5 (COUNT): field 'stamp': COUNT '1junk'"), std::string::npos) << e;
  e = test::pass_read_error(one_point_ascii(std::string(kAsciiHeader) + "SIZE 4\n"));
  EXPECT_NE(e.find("a second SIZE line"), std::string::npos) << e;
}

TEST(ReadersHardening, PcdDataIsStrict) {
  // A NUL in an ascii data line used to end the line silently.
  std::string e = test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n" + kRow +
                               std::string(" 7\0 junk\n", 9));
  EXPECT_NE(e.find("p.pcd: data line 1: holds a NUL byte"), std::string::npos) << e;
  // Junk suffixes and values a float32 cannot hold.
  for (const char* bad : {"1.5junk", "1e39", "1e999", "-4e38"}) {
    std::string row = kRow;
    row.replace(row.find("1.5"), 3, bad);
    e = test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n" + row + "\n");
    EXPECT_NE(e.find(std::string("field 'range': '") + bad + "' is not a valid F4 value"), std::string::npos) << e;
  }
  // FLT_MAX as printed with 9 digits still reads.
  std::string row = kRow;
  row.replace(row.find("10 "), 3, "3.40282347e+38 ");
  EXPECT_EQ(test::pass_read_error(std::string(kAsciiHeader) + "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n" + row + "\n"), "(no error)");
  // Trailing bytes after binary_compressed data (a literal run of 32 bytes encodes one point).
  std::string body = std::string(kAsciiHeader) + "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n";
  const std::uint32_t csize = 33, usize = 32;
  body.append(reinterpret_cast<const char*>(&csize), 4);
  body.append(reinterpret_cast<const char*>(&usize), 4);
  body.push_back('\x1f');
  body.append(32, '\0');
  EXPECT_EQ(test::pass_read_error(body), "(no error)");
  EXPECT_EQ(test::pass_read_error(body + std::string(5, '\0')), "(no error)");  // PCL 1.7's zero padding
  e = test::pass_read_error(body + std::string(3, '\0') + "junk");
  EXPECT_NE(e.find("p.pcd: binary_compressed: the file holds 7 bytes after the 33 compressed bytes"), std::string::npos) << e;
}

// Item 13 sibling: the pose CSV took "0.1 5" for 0.15 (blanks inside a cell were dropped) and stopped a
// number at a NUL.
TEST(ReadersHardening, PoseCsvNumbersAreStrict) {
  const std::string head = "stamp,x,y,z,roll,pitch,yaw\n";
  EXPECT_EQ(error_of_poses(head + " 1.0 , 2,3,4,0,0,0\r\n2,2,3,4,0,0,0\n"), "(no error)");
  std::string e = error_of_poses(head + "1.0,0.1 5,3,4,0,0,0\n");
  EXPECT_NE(e.find("poses.csv:2: column 'x': '0.1 5' is not a number"), std::string::npos) << e;
  e = error_of_poses(head + "1.0,0.1junk,3,4,0,0,0\n");
  EXPECT_NE(e.find("poses.csv:2: column 'x': '0.1junk' is not a number"), std::string::npos) << e;
  e = error_of_poses(head + std::string("1.0,0.1\0junk,3,4,0,0,0\n", 23));
  EXPECT_NE(e.find("poses.csv:2: column 'x'"), std::string::npos) << e;
  e = error_of_poses("st amp,x,y,z,roll,pitch,yaw\n1,0,0,0,0,0,0\n");
  EXPECT_NE(e.find("poses.csv:1: header column 1 is 'st amp'"), std::string::npos) << e;
}

// Item 10: a FIFO, a device, a directory or a symlink loop is refused before it is opened.
TEST(ReadersHardening, NonRegularFilesAreRefusedUpFront) {
  const std::string dir = test::fresh_dir("readers");
  const std::string fifo = dir + "/fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::create_symlink("loop_b", dir + "/loop_a");
  fs::create_symlink("loop_a", dir + "/loop_b");
  const auto pcd_error = [](const std::string& p) {
    try {
      io::read_pcd(p);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  const auto pose_error = [](const std::string& p) {
    try {
      io::read_pose_csv(p, RpyOrder::kXyz);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(pcd_error(fifo).find("fifo: is a FIFO (named pipe"), std::string::npos) << pcd_error(fifo);
  EXPECT_NE(pose_error(fifo).find("a pose file must be a regular file"), std::string::npos) << pose_error(fifo);
  EXPECT_NE(pcd_error("/dev/zero").find("/dev/zero: is a character device"), std::string::npos);
  EXPECT_NE(pose_error("/dev/zero").find("/dev/zero: is a character device"), std::string::npos);
  EXPECT_NE(pcd_error(dir).find("is a directory, not a PCD file"), std::string::npos);
  EXPECT_NE(pose_error(dir).find("is a directory, not a pose file"), std::string::npos);
  EXPECT_NE(pcd_error(dir + "/loop_a").find("a symlink loop?"), std::string::npos) << pcd_error(dir + "/loop_a");
  EXPECT_NE(pcd_error(dir + "/none.pcd").find("none.pcd: cannot open the PCD file (No such file"), std::string::npos);
  EXPECT_EQ(io::regular_file_problem(dir + "/fifo", "x").rfind("is a FIFO", 0), 0u);
  test::write_text(dir + "/f.txt", "x");
  EXPECT_EQ(io::regular_file_problem(dir + "/f.txt", "x"), "");
  fs::create_symlink("f.txt", dir + "/link");
  EXPECT_EQ(io::regular_file_problem(dir + "/link", "x"), "") << "a symlink to a regular file is one";
}

// Item 5: input extra fields named like output fields are written as input_<name>, so the run's
// returns.pcd reads back.
TEST(ReadersHardening, ExtraFieldsNamedLikeOutputFieldsAreRenamed) {
  Pass p = test::line_pass({1.0f, 2.0f, 3.0f}, {10.0f, 20.0f, 30.0f});
  const std::vector<std::string> names = {"x", "input_x", "label", "flags", "pass", "echo", "sigma_h", "cov_xx"};
  for (std::size_t k = 0; k < names.size(); ++k) {
    ExtraField e;
    e.field = {names[k], 'U', 2, 1};
    for (std::size_t i = 0; i < p.size(); ++i) {
      const std::uint16_t v = static_cast<std::uint16_t>(100 * k + i);
      e.data.push_back(static_cast<std::uint8_t>(v & 0xff));
      e.data.push_back(static_cast<std::uint8_t>(v >> 8));
    }
    p.extra.push_back(e);
  }
  const std::string path = test::fresh_dir("readers") + "/returns.pcd";
  io::ReturnsWriter w(path);
  w.append(p);
  w.close();
  const io::PcdTable t = io::read_pcd(path);
  const std::vector<std::string> expected = {"input_input_x", "input_x", "input_label", "input_flags",
                                             "input_pass",    "echo",    "input_sigma_h", "input_cov_xx"};
  for (std::size_t k = 0; k < expected.size(); ++k) {
    const auto v = test::column(t, expected[k]);
    ASSERT_EQ(v.size(), 3u) << expected[k];
    EXPECT_EQ(v[2], 100.0 * static_cast<double>(k) + 2) << expected[k];
  }
  EXPECT_EQ(test::column(t, "x").size(), 3u);
}

// Every seed of the fuzz corpora (the overflow headers among them) ends in an InputError or is read,
// never anything else: the fuzz targets' contract, checked in every build.
TEST(ReadersHardening, FuzzCorpusSeedsFailCleanly) {
  std::size_t seeds = 0;
  for (const char* target : {"pcd", "pose_csv"}) {
    for (const auto& e : fs::directory_iterator(std::string(PCDP_SOURCE_DIR) + "/tests/fuzz/corpus/" + target)) {
      ++seeds;
      try {
        if (std::string(target) == "pcd") read_pass(e.path().string(), 0);
        else io::read_pose_csv(e.path().string(), RpyOrder::kXyz);
      } catch (const InputError&) {
      } catch (const std::exception& x) {
        ADD_FAILURE() << e.path() << ": " << x.what();
      }
    }
  }
  EXPECT_GE(seeds, 15u);
}
