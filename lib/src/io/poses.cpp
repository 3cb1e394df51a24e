#include "pcdp/io/poses.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {
constexpr double kMaxPoseCoordinate = 1e8;  // m
const char* const kColumns[] = {"stamp", "x", "y", "z", "roll", "pitch", "yaw"};

// Cells with the blanks around them trimmed; blanks inside a cell stay (and make it no number).
std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::size_t a = 0;
  while (true) {
    const std::size_t b = line.find(',', a);
    const std::string cell = line.substr(a, b == std::string::npos ? std::string::npos : b - a);
    const std::size_t first = cell.find_first_not_of(" \t\r"), last = cell.find_last_not_of(" \t\r");
    out.push_back(first == std::string::npos ? std::string() : cell.substr(first, last - first + 1));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  return out;
}

PoseTrack read_pose_csv_unguarded(const std::string& path, RpyOrder order) {
  require_regular_file(path, "pose file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the pose file (" + std::strerror(errno) + ")");
  const auto fail = [&](std::size_t line, const std::string& msg) {
    throw InputError(path + ":" + std::to_string(line) + ": " + msg);
  };

  std::string line;
  std::size_t lineno = 0;
  if (!std::getline(in, line)) throw InputError(path + ": the pose file is empty (expected the header stamp,x,y,z,roll,pitch,yaw)");
  ++lineno;
  const auto header = split_csv(line);
  if (header.size() < 7)
    fail(1, "header '" + line + "' must begin with stamp,x,y,z,roll,pitch,yaw");
  for (std::size_t c = 0; c < 7; ++c)
    if (header[c] != kColumns[c])
      fail(1, "header column " + std::to_string(c + 1) + " is '" + header[c] + "' but must be '" + kColumns[c] +
                  "' (header stamp,x,y,z,roll,pitch,yaw)");
  const std::size_t ncols = header.size();  // extra columns are allowed and ignored here

  std::vector<PoseSample> samples;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto cells = split_csv(line);
    if (cells.size() != ncols)
      fail(lineno, "has " + std::to_string(cells.size()) + " columns but the header has " + std::to_string(ncols));
    double v[7];
    for (std::size_t c = 0; c < 7; ++c) {
      char* end = nullptr;
      errno = 0;
      v[c] = std::strtod(cells[c].c_str(), &end);
      if (cells[c].empty() || end != cells[c].c_str() + cells[c].size())  // junk after the number, or a NUL
        fail(lineno, "column '" + std::string(kColumns[c]) + "': '" + cells[c] + "' is not a number");
      if (!std::isfinite(v[c]))
        fail(lineno, "column '" + std::string(kColumns[c]) + "': '" + cells[c] + "' is not finite (NaN/inf are not allowed in poses)");
      // No map frame reaches further (UTM northings stay below 1e7 m, geocentric coordinates
      // below 6.4e6 m); beyond, differences of positions overflow into NaN points.
      if (c >= 1 && c <= 3 && !(std::fabs(v[c]) <= kMaxPoseCoordinate))
        fail(lineno, "column '" + std::string(kColumns[c]) + "': " + cells[c] + " m is beyond +-1e8 m (no map frame reaches that far)");
    }
    if (!samples.empty() && !(v[0] > samples.back().stamp))
      fail(lineno, "stamp " + cells[0] + " is not after the previous stamp (" + std::to_string(samples.back().stamp) +
                       "); pose stamps must be strictly increasing");
    PoseSample s;
    s.stamp = v[0];
    s.position = {v[1], v[2], v[3]};
    s.orientation = Eigen::Quaterniond(rpy_to_matrix({v[4], v[5], v[6]}, order));
    samples.push_back(s);
  }
  if (samples.empty()) throw InputError(path + ": the pose file has a header but no poses");
  return PoseTrack(std::move(samples));
}
}  // namespace

PoseTrack read_pose_csv(const std::string& path, RpyOrder order) {
  try {
    return read_pose_csv_unguarded(path, order);
  } catch (const std::bad_alloc&) {
    throw InputError(path + ": out of memory while reading the pose file");
  }
}

}  // namespace pcdp::io
