#include "pcdp/import/3dtk.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {
constexpr double kDeg = 0.017453292519943295;
constexpr double kLinePeriod = 0.0133;

Eigen::Matrix3d C() {
  Eigen::Matrix3d c;
  c << 0, 0, 1, -1, 0, 0, 0, 1, 0;
  return c;
}

std::string sibling(const std::string& scan, const std::string& ext) {
  const auto dot = scan.rfind('.');
  return (dot == std::string::npos ? scan : scan.substr(0, dot)) + ext;
}
}  // namespace

Eigen::Vector3d uos_to_ours(const Eigen::Vector3d& p_cm) { return C() * p_cm / 100.0; }

std::size_t beams_per_line_from_geometry(const std::vector<Eigen::Vector3d>& pts, const std::string& file) {
  const std::size_t n = pts.size();
  const std::string ask = "; give the count with --beams-per-line N";
  // In-plane bearing of every point that has a direction (a point at the origin has none).
  std::vector<double> b(n, std::numeric_limits<double>::quiet_NaN());
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < n; ++i) {
    if (!pts[i].allFinite() || pts[i].isZero(0.0)) continue;
    const Eigen::Vector3d q = uos_to_ours(pts[i]);
    b[i] = std::atan2(q.y(), std::hypot(q.x(), q.z()));
    lo = std::min(lo, b[i]);
    hi = std::max(hi, b[i]);
  }
  if (!(hi > lo))
    throw InputError(file + ": cannot read the beams per scan line from the geometry (no two points with different bearings)" + ask);
  // Along a line the bearing moves by a beam step; from one line to the next it jumps back across
  // the field of view: more than half the span the scan covers.
  const double jump = 0.5 * (hi - lo);
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  // consecutive points with a direction
  std::vector<std::size_t> starts;                         // the point after each jump
  std::size_t prev = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(b[i])) continue;
    if (prev != n) {
      pairs.emplace_back(prev, i);
      if (std::fabs(b[i] - b[prev]) > jump) starts.push_back(i);
    }
    prev = i;
  }
  if (starts.empty()) return n;  // one line
  // The candidate: the most common distance between line starts (the first start counts from 0).
  std::map<std::size_t, std::size_t> votes;
  ++votes[starts[0]];
  for (std::size_t k = 1; k < starts.size(); ++k) ++votes[starts[k] - starts[k - 1]];
  std::size_t beams = 0, best = 0;
  for (const auto& [len, count] : votes)
    if (count > best) {
      beams = len;
      best = count;
    }
  // Every jump must fall on a line boundary and every boundary between points with a direction
  // must show a jump.
  for (const auto& [j, i] : pairs) {
    const bool boundary = i / beams != j / beams;
    const bool jumped = std::fabs(b[i] - b[j]) > jump;
    if (boundary != jumped)
      throw InputError(file + ": cannot read the beams per scan line from the geometry: most lines have " +
                       std::to_string(beams) + " beams, but the bearing " + (jumped ? "jumps back" : "does not jump back") +
                       " between points " + std::to_string(j + 1) + " and " + std::to_string(i + 1) + ask);
  }
  return beams;
}

Eigen::Isometry3d read_3dtk_pose(const std::string& scan, bool use_frames) {
  Eigen::Matrix3d R_uos;
  Eigen::Vector3d t_uos;
  if (use_frames) {
    const std::string path = sibling(scan, ".frames");
    require_regular_file(path, "slam6D frames file");
    std::ifstream in(path);
    if (!in) throw InputError(path + ": cannot open the slam6D frames file");
    std::string line, last;
    while (std::getline(in, line)) {
      std::istringstream is(line);
      std::vector<double> v;
      for (double x; is >> x;) v.push_back(x);
      if (v.size() >= 16) last = line;
    }
    std::istringstream is(last);
    double m[16];
    for (double& x : m)
      if (!(is >> x)) throw InputError(path + ": no line with a 4x4 matrix (16 numbers)");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R_uos(r, c) = m[c * 4 + r];  // column-major (OpenGL)
    t_uos = {m[12], m[13], m[14]};
  } else {
    const std::string path = sibling(scan, ".pose");
    require_regular_file(path, "3DTK pose file");
    std::ifstream in(path);
    double v[6];
    for (double& x : v)
      if (!(in >> x)) throw InputError(path + ": expected x y z (cm) and theta x y z (degrees)");
    t_uos = {v[0], v[1], v[2]};
    R_uos = rot_x(v[3] * kDeg) * rot_y(v[4] * kDeg) * rot_z(v[5] * kDeg);  // 3DTK EulerToMatrix4
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = C() * R_uos * C().transpose();
  T.translation() = C() * t_uos / 100.0;
  return T;
}

Imported3dtk import_3dtk(const std::vector<std::string>& scans, bool use_frames, std::size_t beams_per_line) {
  Imported3dtk out;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    require_regular_file(scans[k], "3DTK scan");
    std::ifstream in(scans[k]);
    if (!in) throw InputError(scans[k] + ": cannot open the 3DTK scan");
    std::vector<Eigen::Vector3d> pts;
    std::string line;
    std::size_t lineno = 0, header_width = 0;
    while (std::getline(in, line)) {
      ++lineno;
      std::istringstream is(line);
      double x, y, z;
      if (!(is >> x >> y >> z)) {
        if (lineno == 1) {  // the "W x H" header
          unsigned long w = 0, h = 0;
          char extra = 0;
          if (std::sscanf(line.c_str(), "%lu x %lu %c", &w, &h, &extra) == 2) header_width = w;
          continue;
        }
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        throw InputError(scans[k] + ":" + std::to_string(lineno) + ": expected x y z (cm)");
      }
      pts.push_back({x, y, z});
    }
    if (pts.empty()) throw InputError(scans[k] + ": no points");
    std::size_t beams = beams_per_line;
    if (beams == 0) {
      beams = beams_per_line_from_geometry(pts, scans[k]);
      if (header_width != 0 && header_width != beams)
        throw InputError(scans[k] + ":1: the header says " + std::to_string(header_width) +
                         " beams per line, the points' geometry " + std::to_string(beams) +
                         "; give the count with --beams-per-line N");
    } else if (header_width != 0 && header_width != beams) {
      // An override that both the header and the geometry contradict is a mistake, not a fix.
      std::size_t from_geometry = 0;
      try {
        from_geometry = beams_per_line_from_geometry(pts, scans[k]);
      } catch (const InputError&) {
        from_geometry = 0;  // the geometry cannot tell: the override decides
      }
      if (from_geometry == header_width)
        throw ConfigError(scans[k] + ": --beams-per-line " + std::to_string(beams) + " contradicts the header (" +
                          std::to_string(header_width) + " beams per line) and the points' geometry (" +
                          std::to_string(from_geometry) + ")");
    }
    if (pts.size() % beams != 0)
      throw InputError(scans[k] + ": " + std::to_string(pts.size()) + " points is not a whole number of " +
                       std::to_string(beams) + "-beam lines");
    const std::size_t lines = pts.size() / beams;
    if (lines >= 1000)  // scan k owns line numbers 1000 k .. 1000 k + 999
      throw InputError(scans[k] + ": " + std::to_string(lines) + " lines; at most 999 lines per scan are supported");
    Pass p;
    p.index = k;
    p.source = scans[k];
    p.organized = true;
    // Bearing of each beam index: a line fitted to the valid points' bearings (for no-returns).
    std::vector<double> bearing(pts.size(), std::numeric_limits<double>::quiet_NaN());
    std::vector<char> valid(pts.size());
    double sb = 0, sbb = 0, sn = 0, snb = 0, cnt = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double r_cm = pts[i].norm();
      valid[i] = r_cm > 0.0 && r_cm < 3276.0;
      if (!valid[i]) continue;
      const Eigen::Vector3d q = uos_to_ours(pts[i]);
      bearing[i] = std::atan2(q.y(), std::hypot(q.x(), q.z()));
      const double b = static_cast<double>(i % beams);
      sb += b;
      sbb += b * b;
      sn += bearing[i];
      snb += bearing[i] * b;
      cnt += 1;
    }
    const double slope = cnt > 2 ? (cnt * snb - sb * sn) / (cnt * sbb - sb * sb) : 0.0;
    const double icept = cnt > 2 ? (sn - slope * sb) / cnt : 0.0;
    const double t0 = 100.0 * static_cast<double>(k);
    for (std::size_t l = 0; l < lines; ++l) {
      std::vector<double> elev;
      for (std::size_t b = 0; b < beams; ++b) {
        const std::size_t i = l * beams + b;
        if (!valid[i]) continue;
        const Eigen::Vector3d q = uos_to_ours(pts[i]);
        elev.push_back(std::atan2(q.z(), q.x()));
      }
      double nod = 0.0;
      if (!elev.empty()) {
        std::nth_element(elev.begin(), elev.begin() + static_cast<long>(elev.size() / 2), elev.end());
        nod = elev[elev.size() / 2];
      }
      p.line_begin.push_back(p.range.size());
      for (std::size_t b = 0; b < beams; ++b) {
        const std::size_t i = l * beams + b;
        p.line.push_back(static_cast<std::uint32_t>(k * 1000 + l));
        p.beam.push_back(static_cast<std::uint32_t>(b));
        p.range.push_back(valid[i] ? static_cast<float>(pts[i].norm() / 100.0) : 0.0f);
        p.bearing.push_back(static_cast<float>(valid[i] ? bearing[i] : icept + slope * static_cast<double>(b)));
        p.amplitude.push_back(std::numeric_limits<float>::quiet_NaN());
        p.nod.push_back(static_cast<float>(nod));
        p.stamp.push_back(t0 + (static_cast<double>(l) + static_cast<double>(b) / static_cast<double>(beams)) * kLinePeriod);
      }
    }
    p.line_begin.push_back(p.range.size());
    p.label.assign(p.range.size(), Label::kKept);
    p.flags.assign(p.range.size(), 0);
    const Eigen::Isometry3d T = read_3dtk_pose(scans[k], use_frames);
    const Eigen::Quaterniond q(T.linear());
    // The pose is constant over the scan: samples every 0.25 s across its span (a sparser file
    // would be a gap that register's max_pose_gap refuses to interpolate across).
    const double span = static_cast<double>(lines) * kLinePeriod;
    for (double t = t0 - 0.25; t <= t0 + span + 0.25; t += 0.25) out.poses.push_back({t, T.translation(), q});
    out.passes.push_back(std::move(p));
  }
  return out;
}

}  // namespace pcdp::io
