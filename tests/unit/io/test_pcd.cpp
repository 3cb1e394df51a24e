#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
const char* kHeader =
    "# test\nVERSION 0.7\nFIELDS line beam range bearing amplitude nod stamp\nSIZE 4 4 4 4 4 4 8\n"
    "TYPE U U F F F F F\nCOUNT 1 1 1 1 1 1 1\n";

std::string ascii_pcd(const std::vector<std::string>& rows, const std::string& header = kHeader) {
  std::string s = header + "WIDTH " + std::to_string(rows.size()) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
                  std::to_string(rows.size()) + "\nDATA ascii\n";
  for (const auto& r : rows) s += r + "\n";
  return s;
}

const std::vector<std::string> kRows = {"0 0 1.5 -0.1 100 0.2 10.000", "0 1 0 0.0 0 0.2 10.001",
                                        "0 2 2.5 0.1 80 0.2 10.002", "1 0 3.0 -0.1 90 0.25 10.010",
                                        "1 1 nan 0.0 0 0.25 10.011", "1 2 3.5 0.1 70 0.25 10.012"};
}  // namespace

TEST(Pcd, AsciiPassIsReadInLineBeamOrder) {
  std::vector<std::string> shuffled = {kRows[4], kRows[0], kRows[5], kRows[2], kRows[1], kRows[3]};
  const std::string path = test::fresh_dir() + "/p.pcd";
  test::write_text(path, ascii_pcd(shuffled));
  const Pass p = read_pass(path, 3);
  ASSERT_EQ(p.size(), 6u);
  EXPECT_EQ(p.index, 3u);
  EXPECT_EQ(p.line_count(), 2u);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(p.line[i], i / 3);
    EXPECT_EQ(p.beam[i], i % 3);
  }
  EXPECT_FLOAT_EQ(p.range[0], 1.5f);
  EXPECT_TRUE(std::isnan(p.range[4]));
  EXPECT_DOUBLE_EQ(p.stamp[5], 10.012);
}

TEST(Pcd, BinaryRoundTripThroughOurWriterKeepsEveryValue) {
  sim::SimConfig cfg = test::small_sim_config();
  cfg.passes = 1;
  cfg.lines_per_pass = 7;
  const auto run = sim::simulate(cfg);
  const std::string path = test::fresh_dir() + "/p.pcd";
  sim::write_pass_pcd(run.passes[0].pass, path);
  const io::PcdHeader h = io::read_pcd_header(path);
  EXPECT_EQ(h.width, static_cast<std::uint64_t>(cfg.scanner.beams));
  EXPECT_EQ(h.height, 7u);
  const Pass p = read_pass(path, 0);
  const Pass& q = run.passes[0].pass;
  ASSERT_EQ(p.size(), q.size());
  EXPECT_TRUE(p.organized);
  for (std::size_t i = 0; i < p.size(); ++i) {
    EXPECT_EQ(p.line[i], q.line[i]);
    EXPECT_EQ(std::memcmp(&p.range[i], &q.range[i], 4), 0);
    EXPECT_EQ(p.stamp[i], q.stamp[i]);
  }
}

TEST(Pcd, ExtraFieldsAreCarried) {
  const std::string header =
      "VERSION 0.7\nFIELDS line beam range bearing amplitude nod stamp echo\nSIZE 4 4 4 4 4 4 8 2\n"
      "TYPE U U F F F F F U\nCOUNT 1 1 1 1 1 1 1 1\n";
  const std::string path = test::fresh_dir() + "/p.pcd";
  test::write_text(path, ascii_pcd({"0 1 1.5 0 10 0 1.0 7", "0 0 1.5 0 10 0 0.9 9"}, header));
  const Pass p = read_pass(path, 0);
  ASSERT_EQ(p.extra.size(), 1u);
  EXPECT_EQ(p.extra[0].field.name, "echo");
  std::uint16_t first;
  std::memcpy(&first, p.extra[0].data.data(), 2);
  EXPECT_EQ(first, 9);  // reordered with its return (beam 0 first)
}

TEST(Pcd, HeaderAndDataErrorsNameTheRule) {
  EXPECT_NE(test::pass_read_error("").find("the file is empty"), std::string::npos);
  EXPECT_NE(test::pass_read_error("VERSION 0.7\nFIELDS x\n").find("no DATA line"), std::string::npos);
  std::string e = test::pass_read_error(ascii_pcd(kRows).replace(ascii_pcd(kRows).find("SIZE 4 4 4 4 4 4 8"), 18, "SIZE 4 4 4 4 4 4"));
  EXPECT_NE(e.find("SIZE has 6 entries but FIELDS has 7"), std::string::npos) << e;
  // Missing field.
  std::string h2 = "VERSION 0.7\nFIELDS line beam range bearing amplitude stamp\nSIZE 4 4 4 4 4 8\nTYPE U U F F F F\n";
  e = test::pass_read_error(ascii_pcd({"0 0 1 0 1 1"}, h2));
  EXPECT_NE(e.find("missing required field 'nod'"), std::string::npos) << e;
  // Wrong type: stamp as float32.
  std::string h3 = std::string(kHeader);
  h3.replace(h3.find("SIZE 4 4 4 4 4 4 8"), 18, "SIZE 4 4 4 4 4 4 4");
  e = test::pass_read_error(ascii_pcd(kRows, h3));
  EXPECT_NE(e.find("field 'stamp' has type F4 but must be F8"), std::string::npos) << e;
  // Ascii: header claims more points than the file holds.
  std::string s = ascii_pcd(kRows);
  s = s.substr(0, s.rfind("1 2 3.5"));
  e = test::pass_read_error(s);
  EXPECT_NE(e.find("truncated: the header claims 6 points"), std::string::npos) << e;
  EXPECT_NE(e.find("holds 5 points"), std::string::npos) << e;
  // Bad value.
  e = test::pass_read_error(ascii_pcd({"0 0 abc 0 1 0 1"}));
  EXPECT_NE(e.find("field 'range': 'abc' is not a valid F4 value"), std::string::npos) << e;
  e = test::pass_read_error(ascii_pcd({"-1 0 1 0 1 0 1"}));
  EXPECT_NE(e.find("field 'line': '-1' is not a valid U4 value"), std::string::npos) << e;
  // WIDTH x HEIGHT disagrees with POINTS.
  s = ascii_pcd(kRows);
  s.replace(s.find("POINTS 6"), 8, "POINTS 7");
  EXPECT_NE(test::pass_read_error(s).find("POINTS 7 disagrees with WIDTH x HEIGHT"), std::string::npos);
  // A header claiming billions of points is refused before any allocation.
  s = ascii_pcd(kRows);
  s.replace(s.find("WIDTH 6"), 7, "WIDTH 4000000000");
  s.replace(s.find("POINTS 6"), 8, "POINTS 4000000000");
  e = test::pass_read_error(s);
  EXPECT_NE(e.find("claims 4000000000 points"), std::string::npos) << e;
}

TEST(Pcd, TruncatedAndOverlongBinary) {
  sim::SimConfig cfg = test::small_sim_config();
  cfg.passes = 1;
  cfg.lines_per_pass = 3;
  const auto run = sim::simulate(cfg);
  const std::string dir = test::fresh_dir();
  const std::string path = dir + "/p.pcd";
  sim::write_pass_pcd(run.passes[0].pass, path);
  const std::string full = test::read_text(path);
  test::write_text(path, full.substr(0, full.size() - 100));
  try {
    read_pass(path, 0);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated: the header claims 273 points (8736 bytes)"), std::string::npos) << e.what();
  }
  test::write_text(path, full + "xx");
  try {
    read_pass(path, 0);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("2 bytes after the last"), std::string::npos) << e.what();
  }
}

TEST(Pcd, ContractViolationsNameFieldLineAndBeam) {
  auto rows = kRows;
  rows[2] = "0 2 -2.5 0.1 80 0.2 10.002";
  std::string e = test::pass_read_error(ascii_pcd(rows));
  EXPECT_NE(e.find("field 'range', line 0 beam 2: -2.5"), std::string::npos) << e;
  rows = kRows;
  rows[2] = "0 2 2.5 0.1 80 0.2 nan";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("field 'stamp', line 0 beam 2: stamp is not finite"), std::string::npos);
  rows = kRows;
  rows[2] = "0 2 2.5 inf 80 0.2 10.002";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("field 'bearing', line 0 beam 2"), std::string::npos);
  rows = kRows;
  rows[2] = "0 2 2.5 0.1 80 0.3 10.002";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("differs within the line"), std::string::npos);
  rows = kRows;
  rows[2] = "0 2 2.5 0.1 80 0.2 9.0";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("stamps must not decrease along a line"), std::string::npos);
  rows = kRows;
  rows[5] = "1 2 3.5 0.1 70 0.25 10.002";
  rows[4] = "1 1 nan 0.0 0 0.25 10.001";
  rows[3] = "1 0 3.0 -0.1 90 0.25 10.0";
  e = test::pass_read_error(ascii_pcd(rows));
  EXPECT_NE(e.find("from line to line"), std::string::npos) << e;
  rows = kRows;
  rows[1] = "0 0 0 0.0 0 0.2 10.001";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("line 0 beam 0: appears twice"), std::string::npos);
  rows = kRows;
  rows[0] = "0 0 1.5 -0.1 -3 0.2 10.000";
  EXPECT_NE(test::pass_read_error(ascii_pcd(rows)).find("field 'amplitude', line 0 beam 0"), std::string::npos);
}

TEST(Lzf, DecodesLiteralsAndOverlappingBackReferences) {
  // Literal "ab" then a back reference of length 6 at distance 2: "abababab".
  const std::uint8_t in[] = {1, 'a', 'b', (4 << 5), 1};
  std::uint8_t out[8];
  ASSERT_TRUE(io::lzf_decompress(in, sizeof in, out, sizeof out));
  EXPECT_EQ(std::string(reinterpret_cast<char*>(out), 8), "abababab");
  // Wrong expected size, reference before the start, and truncated input all fail.
  std::uint8_t big[9];
  EXPECT_FALSE(io::lzf_decompress(in, sizeof in, big, sizeof big));
  const std::uint8_t bad_ref[] = {0, 'a', (1 << 5), 5};
  EXPECT_FALSE(io::lzf_decompress(bad_ref, sizeof bad_ref, out, 4));
  const std::uint8_t trunc[] = {5, 'a', 'b'};
  EXPECT_FALSE(io::lzf_decompress(trunc, sizeof trunc, out, 6));
}

TEST(Pcd, NanAndInfInEveryNumericField) {
  // range NaN means no return and amplitude NaN means "not measured": both are valid;
  // everything else non-finite is refused, naming the field.
  const char* fields[] = {"line", "beam", "range", "bearing", "amplitude", "nod", "stamp"};
  for (int f = 0; f < 7; ++f) {
    for (const char* bad : {"nan", "inf", "-inf"}) {
      std::vector<std::string> rows = kRows;
      std::istringstream in(rows[3]);
      std::vector<std::string> cells;
      for (std::string c; in >> c;) cells.push_back(c);
      cells[static_cast<std::size_t>(f)] = bad;
      std::string row;
      for (const auto& c : cells) row += c + " ";
      rows[3] = row;
      const std::string e = test::pass_read_error(ascii_pcd(rows));
      const bool allowed = (f == 2 || f == 4) && std::string(bad) == "nan";
      if (allowed) {
        EXPECT_EQ(e, "(no error)") << fields[f] << " " << bad;
      } else {
        EXPECT_NE(e.find(std::string("'") + fields[f] + "'"), std::string::npos) << fields[f] << " " << bad << ": " << e;
      }
    }
  }
}

TEST(Pcd, BinaryCompressedWithABadLength) {
  const std::string header =
      "VERSION 0.7\nFIELDS line beam range bearing amplitude nod stamp\nSIZE 4 4 4 4 4 4 8\nTYPE U U F F F F F\n"
      "COUNT 1 1 1 1 1 1 1\nWIDTH 10\nHEIGHT 1\nPOINTS 10\nDATA binary_compressed\n";
  std::string body = header;
  const std::uint32_t csize = 500, usize = 320;  // 10 points x 32 bytes; 500 compressed bytes claimed
  body.append(reinterpret_cast<const char*>(&csize), 4);
  body.append(reinterpret_cast<const char*>(&usize), 4);
  body.append(40, '\x01');
  std::string e = test::pass_read_error(body);
  EXPECT_NE(e.find("binary_compressed declares 500 compressed bytes but 40 follow"), std::string::npos) << e;
  // A wrong uncompressed size.
  body = header;
  const std::uint32_t c2 = 40, u2 = 999;
  body.append(reinterpret_cast<const char*>(&c2), 4);
  body.append(reinterpret_cast<const char*>(&u2), 4);
  body.append(40, '\x01');
  e = test::pass_read_error(body);
  EXPECT_NE(e.find("uncompressed size 999 disagrees with the header claims 10 points (320 bytes)"), std::string::npos) << e;
  // Garbage that does not decode.
  body = header;
  const std::uint32_t c3 = 8, u3 = 320;
  body.append(reinterpret_cast<const char*>(&c3), 4);
  body.append(reinterpret_cast<const char*>(&u3), 4);
  body.append("\xff\xff\xff\xff\xff\xff\xff\xff", 8);
  e = test::pass_read_error(body);
  EXPECT_NE(e.find("corrupt LZF data (does not decode to 320 bytes)"), std::string::npos) << e;
}

// Regression for a fuzz_pcd finding: a header whose DATA line is the last byte of the file (no newline)
// used to put the data offset past the end, and "bytes available" wrapped around to 2^64.
TEST(Pcd, DataLineWithoutTrailingNewlineIsAnEmptyBodyNotACrash) {
  const std::string head = std::string(kHeader) + "WIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  for (const char* data : {"DATA ascii", "DATA binary", "DATA binary_compressed"}) {
    const std::string msg = test::pass_read_error(head + data);
    EXPECT_NE(msg, "(no error)") << data;
    EXPECT_NE(msg.find("p.pcd"), std::string::npos) << msg;
  }
}
