#include "pcdp/import/rplidar.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {
constexpr double kPi = 3.14159265358979323846;

/// A CSV file read by column name; every row must have as many cells as the header.
struct Csv {
  std::string path;
  std::vector<std::string> names;
  std::vector<std::vector<std::string>> rows;
  std::vector<std::size_t> line_of;  ///< file line of each row

  std::size_t col(const std::string& name) const {
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return i;
    throw InputError(path + ":1: no column '" + name + "' in the header");
  }
  double num(std::size_t row, std::size_t c) const {
    const std::string& s = rows[row][c];
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v))
      throw InputError(path + ":" + std::to_string(line_of[row]) + ": column '" + names[c] + "': '" + s +
                       "' is not a finite number");
    return v;
  }
  long long integer(std::size_t row, std::size_t c) const {
    const std::string& s = rows[row][c];
    char* end = nullptr;
    const long long v = std::strtoll(s.c_str(), &end, 10);
    if (s.empty() || *end != '\0')
      throw InputError(path + ":" + std::to_string(line_of[row]) + ": column '" + names[c] + "': '" + s +
                       "' is not an integer");
    return v;
  }
};

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t a = 0;
  while (true) {
    const std::size_t b = line.find(',', a);
    out.push_back(line.substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  return out;
}

Csv read_csv(const std::string& path) {
  require_regular_file(path, "CSV export of a LaserScan bag");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open (expected the CSV export of a LaserScan bag)");
  Csv c;
  c.path = path;
  std::string line;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    auto cells = split(line);
    if (c.names.empty()) {
      c.names = std::move(cells);
      continue;
    }
    if (cells.size() != c.names.size())
      throw InputError(path + ":" + std::to_string(n) + ": " + std::to_string(cells.size()) + " cells, the header has " +
                       std::to_string(c.names.size()));
    c.rows.push_back(std::move(cells));
    c.line_of.push_back(n);
  }
  if (c.names.empty()) throw InputError(path + ": the file is empty (expected a header line)");
  return c;
}

double wrap(double a) { return std::atan2(std::sin(a), std::cos(a)); }
}  // namespace

double TiltGeometry::nod_rad(double reading) const { return -sign * scale * (reading - zero) * kPi / 180.0; }

void TiltGeometry::check(const std::string& what) const {
  if (sign != 1.0 && sign != -1.0)
    throw ConfigError(what + ": the tilt sign must be 1 or -1, not " + std::to_string(sign));
  if (!std::isfinite(scale) || scale == 0.0 || std::fabs(scale) > 1e6)
    throw ConfigError(what + ": the tilt scale (degrees per unit of the reading) must be finite and non-zero, not " +
                      std::to_string(scale));
  if (!std::isfinite(zero) || std::fabs(zero) > 1e12)
    throw ConfigError(what + ": the tilt zero (the reading at level) must be a finite number");
  if (!std::isfinite(axis_offset) || std::fabs(axis_offset) > 10.0)
    throw ConfigError(what + ": the axis offset must be within -10 .. 10 m, not " + std::to_string(axis_offset));
}

ImportedRplidar build_tilt_passes(const std::vector<TiltScan>& scans, const std::vector<TiltSample>& tilt,
                                  const RplidarImportParams& p, const std::string& source) {
  if (tilt.size() < 2) throw InputError(source + ": fewer than two tilt readings");
  for (std::size_t k = 0; k < tilt.size(); ++k) {
    if (tilt[k].t_ns < 0 || tilt[k].t_ns > kMaxBagTimeNs)
      throw InputError(source + ": tilt reading " + std::to_string(k) + ": bag time " + std::to_string(tilt[k].t_ns) +
                       " ns is outside 0 .. 4e18");
    if (k > 0 && tilt[k].t_ns < tilt[k - 1].t_ns)
      throw InputError(source + ": tilt reading " + std::to_string(k) + " goes back in time");
  }
  for (const TiltScan& s : scans)
    if (s.t_ns < 0 || s.t_ns > kMaxBagTimeNs)
      throw InputError(source + ": scan " + std::to_string(s.line) + ": bag time " + std::to_string(s.t_ns) +
                       " ns is outside 0 .. 4e18");
  const auto servo_at = [&](long long t, double& deg) {
    if (t < tilt.front().t_ns || t > tilt.back().t_ns) return false;
    const auto it = std::upper_bound(tilt.begin(), tilt.end(), t,
                                     [](long long v, const TiltSample& s) { return v < s.t_ns; });
    const std::size_t k = it == tilt.end() ? tilt.size() - 1 : static_cast<std::size_t>(it - tilt.begin());
    const std::size_t j = k - 1;
    const double span = static_cast<double>(tilt[k].t_ns - tilt[j].t_ns);
    const double w = span > 0 ? static_cast<double>(t - tilt[j].t_ns) / span : 0.0;
    deg = tilt[j].reading + w * (tilt[k].reading - tilt[j].reading);
    return true;
  };

  ImportedRplidar out;
  out.scans = scans.size();
  // Stamps are seconds from 10 s before the first scan (bag times are epoch ns).
  long long t0_ns = std::numeric_limits<long long>::max();
  for (const auto& s : scans) t0_ns = std::min(t0_ns, s.t_ns);
  if (scans.empty()) t0_ns = 0;
  t0_ns -= 10'000'000'000LL;
  out.t0_ns = t0_ns;
  long long prev_end_ns = std::numeric_limits<long long>::min();
  Pass cur;
  int dir_prev = 0;
  double deg_prev = std::nan("");
  std::size_t pass_index = 0;
  const auto close_pass = [&] {
    if (cur.range.empty()) return;
    cur.line_begin.push_back(cur.range.size());
    cur.label.assign(cur.range.size(), Label::kKept);
    cur.flags.assign(cur.range.size(), 0);
    cur.index = pass_index++;
    out.passes.push_back(std::move(cur));
    cur = Pass{};
  };
  for (const TiltScan& s : scans) {
    const std::size_t nb = s.range.size();
    if (nb == 0) {
      ++out.dropped_scans;  // an empty scan
      continue;
    }
    if (s.angle.size() != nb || s.intensity.size() != nb)
      throw InputError(source + ": scan " + std::to_string(s.line) + " has " + std::to_string(nb) + " ranges, " +
                       std::to_string(s.angle.size()) + " angles and " + std::to_string(s.intensity.size()) + " intensities");
    if (!(s.scan_time > 0.0 && s.scan_time < 10.0))
      throw InputError(source + ": scan " + std::to_string(s.line) + ": scan_time " + std::to_string(s.scan_time) +
                       " s is outside (0, 10)");
    const double n = static_cast<double>(nb);
    // Beam times: the sweep ends at the bag time. Receive times jitter (scans nominally 0.1 s long
    // arrive 0.05-0.3 s apart), so a sweep that would start before the previous one ended starts
    // at that end instead: stamps must increase from line to line.
    const long long t_end = s.t_ns;
    const long long t_start = std::max(t_end - static_cast<long long>(std::llround(s.scan_time * 1e9)), prev_end_ns);
    if (t_start >= t_end) {
      ++out.dropped_scans;  // arrived before the previous scan ended: no time left to place it
      continue;
    }
    // The tilt at every beam of the scan, or the scan is dropped.
    std::vector<long long> tb(nb);
    std::vector<double> deg(nb);
    bool ok = true;
    for (std::size_t k = 0; k < nb && ok; ++k) {
      const double frac = (static_cast<double>(k) + 0.5) / n;
      tb[k] = t_start + static_cast<long long>(std::llround(frac * static_cast<double>(t_end - t_start)));
      ok = servo_at(tb[k], deg[k]);
    }
    if (!ok) {
      ++out.dropped_scans;
      continue;
    }
    // A new pass where the tilt reverses.
    const double mid = deg[deg.size() / 2];
    if (!std::isnan(deg_prev) && std::fabs(mid - deg_prev) > 1e-9) {
      const int d = mid > deg_prev ? 1 : -1;
      if (dir_prev != 0 && d != dir_prev && cur.line_begin.size() >= p.min_pass_lines) close_pass();
      dir_prev = d;
    }
    deg_prev = mid;
    cur.line_begin.push_back(cur.range.size());
    // The encoder reading of the line, as the contract has it: the tilt at the line's last beam
    // through the geometry (rig default: nod positive up = servo_deg - 90 deg, since pitch about y
    // = -(servo_deg - 90) deg looks up for servo_deg > 90). register's skew correction
    // interpolates between line ends.
    const double nod_end = p.geometry.nod_rad(deg.back());
    for (std::size_t k = 0; k < nb; ++k) {
      cur.line.push_back(s.line);
      cur.beam.push_back(static_cast<std::uint32_t>(k));
      cur.stamp.push_back(static_cast<double>(tb[k] - t0_ns) * 1e-9);
      cur.range.push_back(s.range[k]);  // 0: no return
      cur.bearing.push_back(static_cast<float>(wrap(s.angle[k])));
      cur.nod.push_back(static_cast<float>(nod_end));
      cur.amplitude.push_back(s.range[k] == 0.0f ? 0.0f : s.intensity[k]);
    }
    out.beams += nb;
    prev_end_ns = t_end;
  }
  close_pass();
  if (out.passes.empty()) throw InputError(source + ": no scan lies within the tilt stream; nothing to import");
  return out;
}

ImportedRplidar import_rplidar(const std::string& dir, const RplidarImportParams& p) {
  namespace fs = std::filesystem;
  p.geometry.check("import rplidar");
  const Csv scans = read_csv((fs::path(dir) / "scans.csv").string());
  const Csv beams = read_csv((fs::path(dir) / "beams.csv").string());
  const Csv servo = read_csv((fs::path(dir) / "servo.csv").string());

  // The servo stream, in time order.
  std::vector<TiltSample> tilt;
  {
    const std::size_t ct = servo.col("bag_t_ns"), cd = servo.col("servo_deg");
    for (std::size_t r = 0; r < servo.rows.size(); ++r) {
      const long long t = servo.integer(r, ct);
      if (!tilt.empty() && t < tilt.back().t_ns)
        throw InputError(servo.path + ":" + std::to_string(servo.line_of[r]) + ": bag_t_ns goes back in time");
      const double d = servo.num(r, cd);
      if (d < 0.0 || d > 180.0)
        throw InputError(servo.path + ":" + std::to_string(servo.line_of[r]) + ": servo_deg " + servo.rows[r][cd] +
                         " is outside 0 .. 180");
      tilt.push_back({t, d});
    }
    if (tilt.size() < 2) throw InputError(servo.path + ": fewer than two servo angles");
  }

  // Scans: arrival time and sweep duration.
  struct ScanInfo {
    long long t_ns = 0;
    double scan_time = 0;
    std::size_t n = 0;
    bool seen = false;  ///< its beams were read
  };
  std::map<long long, ScanInfo> info;
  {
    const std::size_t ci = scans.col("scan_idx"), ct = scans.col("bag_t_ns"), cs = scans.col("scan_time"),
                      cn = scans.col("n_ranges");
    for (std::size_t r = 0; r < scans.rows.size(); ++r) {
      ScanInfo s;
      s.t_ns = scans.integer(r, ct);
      s.scan_time = scans.num(r, cs);
      if (!(s.scan_time > 0.0 && s.scan_time < 10.0))
        throw InputError(scans.path + ":" + std::to_string(scans.line_of[r]) + ": scan_time " + scans.rows[r][cs] +
                         " s is outside (0, 10)");
      const long long n = scans.integer(r, cn);
      if (n < 0) throw InputError(scans.path + ":" + std::to_string(scans.line_of[r]) + ": n_ranges is negative");
      s.n = static_cast<std::size_t>(n);
      const long long idx = scans.integer(r, ci);
      if (idx < 0 || idx > 0xffffffffLL)
        throw InputError(scans.path + ":" + std::to_string(scans.line_of[r]) + ": scan_idx is outside 0 .. 2^32-1");
      if (!info.emplace(idx, s).second)
        throw InputError(scans.path + ":" + std::to_string(scans.line_of[r]) + ": scan_idx appears twice");
    }
  }

  // The beams, scan by scan in file order.
  std::vector<TiltScan> list;
  const std::size_t bi = beams.col("scan_idx"), bb = beams.col("beam_idx"), ba = beams.col("angle_rad"),
                    br = beams.col("range_m"), bq = beams.col("intensity");
  std::size_t r = 0;
  while (r < beams.rows.size()) {
    const long long idx = beams.integer(r, bi);
    std::size_t end = r;
    while (end < beams.rows.size() && beams.integer(end, bi) == idx) ++end;
    const auto it = info.find(idx);
    if (it == info.end())
      throw InputError(beams.path + ":" + std::to_string(beams.line_of[r]) + ": scan_idx " + std::to_string(idx) +
                       " is not in scans.csv");
    ScanInfo& s = it->second;
    if (s.seen)
      throw InputError(beams.path + ":" + std::to_string(beams.line_of[r]) + ": the beams of scan " + std::to_string(idx) +
                       " are not on consecutive lines");
    s.seen = true;
    if (end - r != s.n)
      throw InputError(beams.path + ":" + std::to_string(beams.line_of[r]) + ": scan " + std::to_string(idx) + " has " +
                       std::to_string(end - r) + " beams, scans.csv says n_ranges " + std::to_string(s.n));
    TiltScan ts;
    ts.t_ns = s.t_ns;
    ts.scan_time = s.scan_time;
    ts.line = static_cast<std::uint32_t>(idx);
    for (std::size_t k = r; k < end; ++k) {
      if (beams.integer(k, bb) != static_cast<long long>(k - r))
        throw InputError(beams.path + ":" + std::to_string(beams.line_of[k]) + ": beam_idx " + beams.rows[k][bb] +
                         " should be " + std::to_string(k - r) + " (beams in scan order from 0)");
      const double a = beams.num(k, ba), rng = beams.num(k, br), q = beams.num(k, bq);
      if (rng < 0.0)
        throw InputError(beams.path + ":" + std::to_string(beams.line_of[k]) + ": range_m " + beams.rows[k][br] +
                         " is negative");
      // Pass files hold single precision; an amplitude is a received power, never negative.
      if (rng > std::numeric_limits<float>::max())
        throw InputError(beams.path + ":" + std::to_string(beams.line_of[k]) + ": range_m " + beams.rows[k][br] +
                         " is beyond any scanner's range (and a pass file's single precision)");
      if (!(q >= 0.0) || q > std::numeric_limits<float>::max())
        throw InputError(beams.path + ":" + std::to_string(beams.line_of[k]) + ": intensity " + beams.rows[k][bq] +
                         (q < 0.0 ? " is negative (an intensity is a received power)" : " is beyond a pass file's single precision"));
      ts.angle.push_back(a);
      ts.range.push_back(static_cast<float>(rng));
      ts.intensity.push_back(static_cast<float>(q));
    }
    list.push_back(std::move(ts));
    r = end;
  }
  // Empty scans have no beam rows: they count as read and dropped.
  for (const auto& [idx, s] : info) {
    if (s.seen) continue;
    if (s.n != 0)
      throw InputError(scans.path + ": scan " + std::to_string(idx) + " has n_ranges " + std::to_string(s.n) +
                       " but no rows in beams.csv");
    TiltScan ts;
    ts.t_ns = s.t_ns;
    ts.scan_time = s.scan_time;
    ts.line = static_cast<std::uint32_t>(idx);
    list.push_back(std::move(ts));
  }
  return build_tilt_passes(list, tilt, p, dir);
}

}  // namespace pcdp::io
