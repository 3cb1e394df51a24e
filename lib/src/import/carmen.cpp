#include "pcdp/import/carmen.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string_view>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFlaserDefaultMaxRange = 80.0;        // CARMEN's FLASER reader: SICK LMS maximum
constexpr std::size_t kMaxLineBytes = 64u << 20;       // longer is not a log line
constexpr std::size_t kMaxReadings = 1u << 20;         // per message
constexpr double kPoseHalfSpan = 1e-3;                 // s, see the header

struct Message {
  std::size_t lineno = 0;
  double stamp = 0.0;
  double x = 0.0, y = 0.0, theta = 0.0;
  double start_angle = 0.0, resolution = 0.0, max_range = 0.0;  // max_range 0: FLASER (decided at the end)
  std::vector<float> ranges, remissions;
};

/// One log line split on blanks, with the position of each field for messages.
class Fields {
 public:
  Fields(const std::string& path, std::size_t lineno, std::string_view line) : path_(path), lineno_(lineno) {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      const std::size_t b = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
      if (i > b) tok_.push_back(line.substr(b, i - b));
    }
  }
  std::size_t size() const { return tok_.size(); }
  std::string_view operator[](std::size_t k) const { return tok_[k]; }

  [[noreturn]] void fail(std::size_t k, const std::string& what, const std::string& rule) const {
    std::string msg = path_ + ":" + std::to_string(lineno_) + ": " + std::string(tok_[0]) + " field " +
                      std::to_string(k + 1) + " (" + what + ")";
    if (k < tok_.size()) msg += " '" + std::string(tok_[k].substr(0, 40)) + (tok_[k].size() > 40 ? "...'" : "'");
    throw InputError(msg + ": " + rule);
  }
  [[noreturn]] void fail_count(std::size_t expected, const std::string& why) const {
    throw InputError(path_ + ":" + std::to_string(lineno_) + ": " + std::string(tok_[0]) + " has " +
                     std::to_string(tok_.size()) + " fields, expected " + std::to_string(expected) + " (" + why + ")");
  }

  double number(std::size_t k, const std::string& what) const {
    const std::string s(tok_[k]);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    // Decimal only: strtod would also take hexadecimal ("0x10" = 16, "0x1p4").
    if (s.empty() || end != s.c_str() + s.size() || s.find_first_of("xX") != std::string::npos) fail(k, what, "not a number");
    if (!std::isfinite(v)) fail(k, what, "not a finite number");
    return v;
  }
  std::size_t count(std::size_t k, const std::string& what, std::size_t max) const {
    const std::string_view s = tok_[k];
    if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string_view::npos)
      fail(k, what, "not a whole number from 0 to " + std::to_string(max));
    const std::size_t v = std::stoul(std::string(s));
    if (v > max) fail(k, what, "not a whole number from 0 to " + std::to_string(max));
    return v;
  }

 private:
  const std::string& path_;
  std::size_t lineno_;
  std::vector<std::string_view> tok_;
};

void read_ranges(const Fields& f, std::size_t first, std::size_t n, const char* what, std::vector<float>& out) {
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::string name = std::string(what) + " " + std::to_string(i + 1) + " of " + std::to_string(n);
    const double r = f.number(first + i, name);
    if (r < 0.0 || r > std::numeric_limits<float>::max()) f.fail(first + i, name, "must be at least 0 and fit a float");
    out[i] = static_cast<float>(r);
  }
}

// FLASER n r_1..r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp
Message parse_flaser(const Fields& f, std::size_t lineno) {
  if (f.size() < 2) f.fail_count(11, "FLASER n, n readings, x y theta odom_x odom_y odom_theta timestamp host logger_timestamp");
  const std::size_t n = f.count(1, "num_readings", kMaxReadings);
  if (n == 0) f.fail(1, "num_readings", "a laser message needs at least one reading");
  if (f.size() != n + 11)
    f.fail_count(n + 11, std::to_string(n) +
                             " readings, then x y theta odom_x odom_y odom_theta timestamp host logger_timestamp");
  Message m;
  m.lineno = lineno;
  read_ranges(f, 2, n, "range", m.ranges);
  std::size_t k = 2 + n;
  m.x = f.number(k++, "laser x, m");
  m.y = f.number(k++, "laser y, m");
  m.theta = f.number(k++, "laser theta, rad");
  f.number(k++, "odom_x, m");
  f.number(k++, "odom_y, m");
  f.number(k++, "odom_theta, rad");
  m.stamp = f.number(k++, "timestamp, s");
  ++k;  // host
  f.number(k, "logger timestamp, s");
  // 180 degrees from -90: an even count leaves the last beam out, an odd count logs both ends.
  m.start_angle = -0.5 * kPi;
  m.resolution = n % 2 == 0 ? kPi / static_cast<double>(n) : (n > 1 ? kPi / static_cast<double>(n - 1) : 0.0);
  return m;
}

// ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r.. m e.. laser_x
// laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety side_safety turn_axis
// timestamp host logger_timestamp
Message parse_robotlaser(const Fields& f, std::size_t lineno) {
  const char* layout =
      "type start_angle fov resolution max_range accuracy remission_mode n, n readings, m, m remissions, laser_x "
      "laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety side_safety turn_axis timestamp host "
      "logger_timestamp";
  if (f.size() < 10) f.fail_count(24, layout);
  Message m;
  m.lineno = lineno;
  f.count(1, "laser_type", 1000);
  m.start_angle = f.number(2, "start_angle, rad");
  const double fov = f.number(3, "fov, rad");
  m.resolution = f.number(4, "angular_resolution, rad");
  m.max_range = f.number(5, "max_range, m");
  f.number(6, "accuracy, m");
  f.count(7, "remission_mode", 1000);
  if (std::fabs(m.start_angle) > 2.0 * kPi) f.fail(2, "start_angle, rad", "must lie within +-2 pi");
  if (!(fov > 0.0 && fov <= 2.0 * kPi + 1e-9)) f.fail(3, "fov, rad", "must be more than 0 and at most 2 pi");
  if (!(m.resolution > 0.0 && m.resolution <= fov)) f.fail(4, "angular_resolution, rad", "must be more than 0 and at most the fov");
  if (!(m.max_range > 0.0)) f.fail(5, "max_range, m", "must be more than 0");
  const std::size_t n = f.count(8, "num_readings", kMaxReadings);
  if (n == 0) f.fail(8, "num_readings", "a laser message needs at least one reading");
  if (f.size() < 10 + n) f.fail_count(n + 24, layout);
  read_ranges(f, 9, n, "range", m.ranges);
  const std::size_t r = f.count(9 + n, "num_remissions", kMaxReadings);
  if (r != 0 && r != n) f.fail(9 + n, "num_remissions", "must be 0 or num_readings (" + std::to_string(n) + ")");
  if (f.size() != n + r + 24) f.fail_count(n + r + 24, layout);
  m.remissions.resize(r);
  for (std::size_t i = 0; i < r; ++i) {
    const double e = f.number(10 + n + i, "remission " + std::to_string(i + 1));
    if (std::fabs(e) > std::numeric_limits<float>::max()) f.fail(10 + n + i, "remission", "does not fit a float");
    m.remissions[i] = static_cast<float>(e);
  }
  std::size_t k = 10 + n + r;
  m.x = f.number(k++, "laser_x, m");
  m.y = f.number(k++, "laser_y, m");
  m.theta = f.number(k++, "laser_theta, rad");
  for (const char* what : {"robot_x, m", "robot_y, m", "robot_theta, rad", "tv, m/s", "rv, rad/s", "forward_safety_dist, m",
                           "side_safety_dist, m", "turn_axis"})
    f.number(k++, what);
  m.stamp = f.number(k++, "timestamp, s");
  ++k;  // host
  f.number(k, "logger timestamp, s");
  return m;
}

/// Reads the (gzip or plain) file line by line through zlib.
class LineReader {
 public:
  explicit LineReader(const std::string& path) : path_(path), gz_(gzopen(path.c_str(), "rb")), chunk_(1u << 17) {
    if (!gz_) throw InputError(path + ": cannot open the CARMEN log");
  }
  ~LineReader() { gzclose(gz_); }
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// The next line without its newline; false at the end of the file.
  bool next(std::string& line) {
    for (;;) {
      const std::size_t nl = buf_.find('\n', pos_);
      if (nl != std::string::npos || (eof_ && pos_ < buf_.size())) {
        const std::size_t end = nl != std::string::npos ? nl : buf_.size();
        line.assign(buf_, pos_, end - pos_);
        pos_ = end + 1;
        ++lineno_;
        if (line.find('\0') != std::string::npos)
          throw InputError(path_ + ":" + std::to_string(lineno_) + ": a NUL byte: not a text CARMEN log");
        return true;
      }
      if (eof_) return false;
      buf_.erase(0, pos_);
      pos_ = 0;
      if (buf_.size() > kMaxLineBytes)
        throw InputError(path_ + ":" + std::to_string(lineno_ + 1) + ": a line longer than " +
                         std::to_string(kMaxLineBytes >> 20) + " MiB is not a CARMEN message");
      const int got = gzread(gz_, chunk_.data(), static_cast<unsigned>(chunk_.size()));
      if (got <= 0) {
        check_error();
        eof_ = true;
      } else {
        buf_.append(chunk_.data(), static_cast<std::size_t>(got));
      }
    }
  }
  std::size_t lineno() const { return lineno_; }

 private:
  void check_error() {
    int err = Z_OK;
    const char* msg = gzerror(gz_, &err);
    if (err == Z_BUF_ERROR)
      throw InputError(path_ + ": after line " + std::to_string(lineno_) + ": the gzip stream ends early (truncated file)");
    if (err != Z_OK)
      throw InputError(path_ + ": after line " + std::to_string(lineno_) + ": the gzip stream is corrupt (" +
                       (msg ? msg : "zlib error") + ")");
  }
  std::string path_;
  gzFile gz_;
  std::vector<char> chunk_;
  std::string buf_;
  std::size_t pos_ = 0, lineno_ = 0;
  bool eof_ = false;
};

}  // namespace

ImportedCarmen import_carmen(const std::string& path) {
  require_regular_file(path, "CARMEN log");
  std::vector<Message> flaser, robotlaser;
  double param_max = 0.0;
  {
    LineReader in(path);
    std::string line;
    while (in.next(line)) {
      const std::size_t lineno = in.lineno();
      const std::size_t b = line.find_first_not_of(" \t\r");
      if (b == std::string::npos || line[b] == '#') continue;
      const std::string_view word = std::string_view(line).substr(b, line.find_first_of(" \t\r", b) - b);
      if (word == "FLASER") {
        flaser.push_back(parse_flaser(Fields(path, lineno, line), lineno));
      } else if (word == "ROBOTLASER1") {
        robotlaser.push_back(parse_robotlaser(Fields(path, lineno, line), lineno));
      } else if (word == "PARAM") {
        const Fields f(path, lineno, line);
        if (f.size() >= 3 && f[1] == "robot_front_laser_max") {
          param_max = f.number(2, "robot_front_laser_max, m");
          if (!(param_max > 0.0)) f.fail(2, "robot_front_laser_max, m", "must be more than 0");
        }
      }
    }
  }
  ImportedCarmen out;
  out.max_range = param_max > 0.0 ? param_max : kFlaserDefaultMaxRange;
  std::vector<Message>& msgs = robotlaser.empty() ? flaser : robotlaser;
  out.message = robotlaser.empty() ? "FLASER" : "ROBOTLASER1";
  if (!robotlaser.empty()) out.skipped_flaser = flaser.size();
  if (msgs.empty()) throw InputError(path + ": no FLASER or ROBOTLASER1 message: not a CARMEN laser log");
  for (std::size_t k = 1; k < msgs.size(); ++k)
    if (msgs[k].stamp < msgs[k - 1].stamp) ++out.reordered;
  std::stable_sort(msgs.begin(), msgs.end(), [](const Message& a, const Message& b) { return a.stamp < b.stamp; });
  for (std::size_t k = 1; k < msgs.size(); ++k)
    if (!(msgs[k].stamp > msgs[k - 1].stamp))
      throw InputError(path + ":" + std::to_string(msgs[k].lineno) + ": " + out.message + " timestamp " +
                       std::to_string(msgs[k].stamp) + " equals that of line " + std::to_string(msgs[k - 1].lineno) +
                       ": two scans at one time cannot both have their pose");
  if (msgs.size() > std::numeric_limits<std::uint32_t>::max())
    throw InputError(path + ": more laser messages than line numbers (2^32)");

  out.passes.reserve(msgs.size());
  for (std::size_t k = 0; k < msgs.size(); ++k) {
    const Message& m = msgs[k];
    const double max_range = m.max_range > 0.0 ? m.max_range : out.max_range;
    const std::size_t n = m.ranges.size();
    Pass p;
    p.index = k;
    p.source = path + ":" + std::to_string(m.lineno);
    p.organized = true;
    p.line_begin = {0, n};
    p.line.assign(n, static_cast<std::uint32_t>(k));
    p.nod.assign(n, 0.0f);
    p.stamp.assign(n, m.stamp);
    p.label.assign(n, Label::kKept);
    p.flags.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const bool no_return = m.ranges[i] >= max_range;
      out.max_range_readings += no_return ? 1 : 0;
      p.beam.push_back(static_cast<std::uint32_t>(i));
      p.range.push_back(no_return ? 0.0f : m.ranges[i]);
      p.bearing.push_back(static_cast<float>(m.start_angle + static_cast<double>(i) * m.resolution));
      p.amplitude.push_back(m.remissions.empty() ? std::numeric_limits<float>::quiet_NaN() : m.remissions[i]);
    }
    out.passes.push_back(std::move(p));
    // The pose, constant over a short span around the scan's stamp (see the header).
    double half = kPoseHalfSpan;
    if (k > 0) half = std::min(half, 0.25 * (m.stamp - msgs[k - 1].stamp));
    if (k + 1 < msgs.size()) half = std::min(half, 0.25 * (msgs[k + 1].stamp - m.stamp));
    PoseSample s;
    s.position = {m.x, m.y, 0.0};
    s.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(m.theta, Eigen::Vector3d::UnitZ()));
    s.stamp = m.stamp - half;
    out.poses.push_back(s);
    s.stamp = m.stamp + half;
    out.poses.push_back(s);
    const std::size_t j = out.poses.size() - 2;
    if (!(out.poses[j + 1].stamp > out.poses[j].stamp) || (j > 0 && !(out.poses[j].stamp > out.poses[j - 1].stamp)))
      throw InputError(path + ":" + std::to_string(m.lineno) + ": " + out.message +
                       " timestamp too close to its neighbour's for two pose samples between them");
  }
  return out;
}

}  // namespace pcdp::io
