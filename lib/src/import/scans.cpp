#include "pcdp/import/scans.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "pcdp/io/las.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/pcd.hpp"

namespace pcdp::io {

namespace {
constexpr double kLinePeriod = 0.0133;
constexpr std::size_t kLinesPerScan = 1000000;  // scan k owns line numbers k * 1e6 ... (uint32: 4294 scans)
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double bearing_of(const Eigen::Vector3d& p) { return std::atan2(p.y(), std::hypot(p.x(), p.z())); }
double nod_of(const Eigen::Vector3d& p) { return std::atan2(p.z(), p.x()); }
/// The bearing of a point within the scan plane of nod `n`, over the full circle: a scanner that
/// sees a little past +-90 degrees (SICK: 180.x degree field) has points behind the nod axis there.
double plane_bearing(const Eigen::Vector3d& p, double n) {
  return std::atan2(p.y(), p.x() * std::cos(n) + p.z() * std::sin(n));
}
Eigen::Vector3d rebuild(double r, double b, double n) {
  return {r * std::cos(n) * std::cos(b), r * std::sin(b), r * std::sin(n) * std::cos(b)};
}

double median_of(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// The nod of a line: median over points away from the scan's ends (cos b > 0.3), else all.
double line_nod(const std::vector<Eigen::Vector3d>& line) {
  std::vector<double> inner, all;
  for (const auto& p : line) {
    if (!p.allFinite() || p.norm() <= 0) continue;
    all.push_back(nod_of(p));
    if (std::cos(bearing_of(p)) > 0.3) inner.push_back(nod_of(p));
  }
  return median_of(inner.empty() ? all : inner);
}

/// A pose held constant over a scan's span, sampled every 0.25 s (register interpolates).
void constant_pose(std::vector<PoseSample>& out, const Eigen::Isometry3d& T, double t0, double span) {
  const Eigen::Quaterniond q(T.linear());
  for (double t = t0 - 0.25; t <= t0 + span + 0.25; t += 0.25) out.push_back({t, T.translation(), q});
}
}  // namespace

std::vector<std::vector<Eigen::Vector3d>> split_lines(const std::vector<Eigen::Vector3d>& pts,
                                                      std::vector<std::size_t>* starts) {
  std::vector<std::vector<Eigen::Vector3d>> lines;
  double last = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double b = bearing_of(pts[i]);
    if (lines.empty() || b < last - 0.5) {
      lines.emplace_back();
      if (starts) starts->push_back(i);
    }
    lines.back().push_back(pts[i]);
    last = b;
  }
  return lines;
}

Pass sensor_lines_to_pass(const std::vector<std::vector<Eigen::Vector3d>>& lines,
                          const std::vector<std::vector<float>>& intensity, std::size_t k, const std::string& source,
                          double max_residual, bool rows, LineRecovery& rec) {
  rec = LineRecovery{};
  std::vector<double> residuals;
  // Fit each line. Its points that do not rebuild within max_residual leave it and become lines of
  // their own (right after it), so no point moves by more than max_residual.
  struct Out {
    std::vector<Eigen::Vector3d> pts;
    std::vector<float> amp;
    double nod;
  };
  std::vector<Out> outs;
  for (std::size_t l = 0; l < lines.size(); ++l) {
    const auto& line = lines[l];
    const std::vector<float>* amp = intensity.size() == lines.size() ? &intensity[l] : nullptr;
    const double nod = line_nod(line);
    ++rec.lines;
    if (!std::isfinite(nod)) {  // a line of no-returns only
      outs.push_back({line, amp ? *amp : std::vector<float>{}, 0.0});
      continue;
    }
    Out fit{{}, {}, nod};
    std::vector<Out> loose;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const auto& p = line[i];
      const float a = amp ? (*amp)[i] : std::numeric_limits<float>::quiet_NaN();
      if (p.allFinite() && p.norm() > 0) {
        const double e = (rebuild(p.norm(), plane_bearing(p, nod), nod) - p).norm();
        if (e > max_residual) {
          loose.push_back({{p}, {a}, nod_of(p)});
          continue;
        }
        residuals.push_back(e);
        rec.max_residual = std::max(rec.max_residual, e);
      }
      fit.pts.push_back(p);
      fit.amp.push_back(a);
    }
    if (!amp) fit.amp.clear();
    if (!loose.empty()) ++rec.split_lines;
    rec.loose_points += loose.size();
    if (!fit.pts.empty()) outs.push_back(std::move(fit));
    for (auto& o : loose) {
      if (!amp) o.amp.clear();
      outs.push_back(std::move(o));
    }
  }
  rec.median_residual = residuals.empty() ? 0.0 : median_of(residuals);
  if (outs.size() >= kLinesPerScan)
    throw InputError(source + ": " + std::to_string(outs.size()) + " scan lines; at most " +
                     std::to_string(kLinesPerScan - 1) + " per scan are supported (points that fit no line count one each)");
  // Beams: the column of an organized cloud, else the index on one bearing grid if every point
  // falls on it, else the position along the line.
  std::vector<double> steps;
  for (const auto& o : outs)
    for (std::size_t i = 1; i < o.pts.size(); ++i)
      if (o.pts[i].allFinite() && o.pts[i - 1].allFinite()) {
        const double d = plane_bearing(o.pts[i], o.nod) - plane_bearing(o.pts[i - 1], o.nod);
        if (d > 1e-6) steps.push_back(d);
      }
  const double step = median_of(steps);
  double bmin = std::numeric_limits<double>::infinity();
  for (const auto& o : outs)
    for (const auto& p : o.pts)
      if (p.allFinite() && p.norm() > 0) bmin = std::min(bmin, plane_bearing(p, o.nod));
  bool grid = !rows && std::isfinite(step) && rec.loose_points == 0;
  std::size_t width = 0;
  std::vector<std::vector<long>> beam_of(outs.size());
  for (std::size_t l = 0; grid && l < outs.size(); ++l) {
    std::vector<char> used;
    for (const auto& p : outs[l].pts) {
      const double g = (plane_bearing(p, outs[l].nod) - bmin) / step;
      const long b = std::lround(g);
      if (!p.allFinite() || std::fabs(g - static_cast<double>(b)) > 0.25 || b < 0 || b > 100000) {
        grid = false;
        break;
      }
      if (static_cast<std::size_t>(b) >= used.size()) used.resize(static_cast<std::size_t>(b) + 1, 0);
      if (used[static_cast<std::size_t>(b)]) {
        grid = false;
        break;
      }
      used[static_cast<std::size_t>(b)] = 1;
      beam_of[l].push_back(b);
      width = std::max(width, static_cast<std::size_t>(b) + 1);
    }
  }
  rec.organized = grid || (rows && rec.loose_points == 0);

  Pass p;
  p.index = k;
  p.source = source;
  p.organized = rec.organized;
  if (k >= 4294) throw InputError(source + ": at most 4294 scans can be imported at once (line numbers are 32-bit)");
  const double t0 = 1e5 * static_cast<double>(k);  // a scan may hold up to 1e6 lines of 13.3 ms
  const auto put = [&](std::size_t l, std::uint32_t beam, float range, double bearing, float amp, double nod, double frac) {
    p.line.push_back(static_cast<std::uint32_t>(k * kLinesPerScan + l));
    p.beam.push_back(beam);
    p.range.push_back(range);
    p.bearing.push_back(static_cast<float>(bearing));
    p.amplitude.push_back(amp);
    p.nod.push_back(static_cast<float>(nod));
    p.stamp.push_back(t0 + (static_cast<double>(l) + frac) * kLinePeriod);
  };
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t l = 0; l < outs.size(); ++l) {
    const Out& o = outs[l];
    p.line_begin.push_back(p.range.size());
    const auto amp_at = [&](std::size_t i) { return o.amp.size() == o.pts.size() ? o.amp[i] : nanf; };
    if (grid) {
      std::vector<long> slot(width, -1);
      for (std::size_t i = 0; i < o.pts.size(); ++i) slot[static_cast<std::size_t>(beam_of[l][i])] = static_cast<long>(i);
      for (std::size_t b = 0; b < width; ++b) {
        const double frac = (static_cast<double>(b) + 1.0) / static_cast<double>(width + 1);
        if (slot[b] < 0) {
          put(l, static_cast<std::uint32_t>(b), 0.0f, bmin + static_cast<double>(b) * step, nanf, o.nod, frac);
        } else {
          const auto& q = o.pts[static_cast<std::size_t>(slot[b])];
          put(l, static_cast<std::uint32_t>(b), static_cast<float>(q.norm()), plane_bearing(q, o.nod), amp_at(static_cast<std::size_t>(slot[b])), o.nod, frac);
        }
      }
    } else {
      double last_b = std::isfinite(bmin) ? bmin : 0.0;
      for (std::size_t i = 0; i < o.pts.size(); ++i) {
        const auto& q = o.pts[i];
        const bool ok = q.allFinite() && q.norm() > 0;
        const double b = ok ? plane_bearing(q, o.nod) : last_b;
        last_b = b;
        put(l, static_cast<std::uint32_t>(i), ok ? static_cast<float>(q.norm()) : 0.0f, b, ok ? amp_at(i) : nanf, o.nod,
            (static_cast<double>(i) + 1.0) / static_cast<double>(o.pts.size() + 1));
      }
    }
  }
  p.line_begin.push_back(p.range.size());
  p.label.assign(p.range.size(), Label::kKept);
  p.flags.assign(p.range.size(), 0);
  return p;
}

Eigen::Vector3d estimate_nod_origin(const std::vector<Eigen::Vector3d>& pts) {
  std::vector<Eigen::Vector3d> finite;
  for (const auto& p : pts)
    if (p.allFinite() && p.norm() > 0) finite.push_back(p);
  const auto cost = [&](const Eigen::Vector3d& o) {
    std::vector<Eigen::Vector3d> moved(finite.size());
    for (std::size_t i = 0; i < finite.size(); ++i) moved[i] = finite[i] - o;
    const auto lines = split_lines(moved);
    double sum = 0.0;
    std::size_t n = 0;
    for (std::size_t l = 0; l < lines.size(); l += 5) {
      const double nod = line_nod(lines[l]);
      if (!std::isfinite(nod)) continue;
      for (const auto& p : lines[l]) {
        sum += (rebuild(p.norm(), plane_bearing(p, nod), nod) - p).norm();
        ++n;
      }
    }
    return n ? sum / static_cast<double>(n) : std::numeric_limits<double>::infinity();
  };
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  double c = cost(best);
  for (double step = 0.25; step >= 0.001; step /= 2) {
    for (bool moved = true; moved;) {
      moved = false;
      for (const Eigen::Vector3d& d : {Eigen::Vector3d(step, 0, 0), Eigen::Vector3d(-step, 0, 0), Eigen::Vector3d(0, 0, step),
                                      Eigen::Vector3d(0, 0, -step)}) {
        const Eigen::Vector3d o = best + d;
        if (o.cwiseAbs().maxCoeff() > 1.0) continue;
        const double co = cost(o);
        if (co < c) {
          c = co;
          best = o;
          moved = true;
        }
      }
    }
  }
  return best;
}

namespace {
/// One scan of an importer: points in the sensor frame and the sensor pose.
struct Scan {
  std::vector<Eigen::Vector3d> pts;
  std::vector<float> amp;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::string source;
  std::size_t width = 0, height = 1;  ///< organized clouds: rows are lines
};

void add_scan(ImportedScans& out, Scan s, const ImportOptions& opt) {
  const std::size_t k = out.passes.size();
  // Move the points to the nod axis origin; the pose takes the offset (T_M_V = T_scan * offset).
  const Eigen::Vector3d o = opt.auto_nod_origin ? estimate_nod_origin(s.pts) : opt.nod_origin;
  if (!o.isZero()) {
    for (auto& p : s.pts) p -= o;
    s.T = s.T * Eigen::Translation3d(o);
  }
  std::vector<std::vector<Eigen::Vector3d>> lines;
  std::vector<std::vector<float>> amps;
  const bool rows = s.height > 1;
  if (rows) {
    for (std::size_t r = 0; r < s.height; ++r) {
      lines.emplace_back(s.pts.begin() + static_cast<long>(r * s.width), s.pts.begin() + static_cast<long>((r + 1) * s.width));
      if (!s.amp.empty()) amps.emplace_back(s.amp.begin() + static_cast<long>(r * s.width), s.amp.begin() + static_cast<long>((r + 1) * s.width));
    }
  } else {
    std::vector<Eigen::Vector3d> finite;
    std::vector<float> famp;
    for (std::size_t i = 0; i < s.pts.size(); ++i)
      if (s.pts[i].allFinite() && s.pts[i].norm() > 0) {
        finite.push_back(s.pts[i]);
        if (!s.amp.empty()) famp.push_back(s.amp[i]);
      }
    std::vector<std::size_t> starts;
    lines = split_lines(finite, &starts);
    if (!famp.empty())
      for (std::size_t l = 0; l < starts.size(); ++l)
        amps.emplace_back(famp.begin() + static_cast<long>(starts[l]),
                          famp.begin() + static_cast<long>(l + 1 < starts.size() ? starts[l + 1] : famp.size()));
  }
  LineRecovery rec;
  Pass p = sensor_lines_to_pass(lines, amps, k, s.source, opt.max_residual, rows, rec);
  rec.nod_origin = o;
  constant_pose(out.poses, s.T, 1e5 * static_cast<double>(k), static_cast<double>(p.line_count()) * kLinePeriod);
  out.passes.push_back(std::move(p));
  out.recovery.push_back(rec);
}

Eigen::Matrix3d rpy_matrix(double roll, double pitch, double yaw) {  // octomath Quaternion(roll, pitch, yaw)
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void read_scan_ascii(const std::string& path, std::vector<Scan>& scans) {
  require_regular_file(path, "scan file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open the scan file");
  std::string line;
  std::size_t lineno = 0;
  scans.emplace_back();
  scans.back().source = path;
  bool any_node = false;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    std::istringstream is(line);
    if (line.rfind("NODE", 0) == 0) {
      std::string tag;
      double v[6];
      is >> tag;
      for (double& x : v)
        if (!(is >> x)) throw InputError(path + ":" + std::to_string(lineno) + ": expected NODE x y z roll pitch yaw");
      if (any_node || !scans.back().pts.empty()) {
        scans.emplace_back();
        scans.back().source = path + " node " + std::to_string(scans.size() - 1);
      }
      any_node = true;
      scans.back().T.linear() = rpy_matrix(v[3], v[4], v[5]);
      scans.back().T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
      continue;
    }
    double x, y, z;
    if (!(is >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
      throw InputError(path + ":" + std::to_string(lineno) + ": expected x y z (m) or a NODE line");
    scans.back().pts.push_back({x, y, z});
  }
  if (scans.back().pts.empty() && scans.size() == 1) throw InputError(path + ": no points");
}

/// Binary ScanGraph (octomap ScanGraph::readBinary, little-endian).
void read_graph(const std::string& path, std::vector<Scan>& scans) {
  require_regular_file(path, "scan graph");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the scan graph");
  const std::string data((std::istreambuf_iterator<char>(in)), {});
  std::size_t at = 0;
  const auto need = [&](std::size_t n, const char* what) {
    if (data.size() - at < n)
      throw InputError(path + ": byte " + std::to_string(at) + ": the file ends inside " + what);
  };
  const auto u32 = [&](const char* what) {
    need(4, what);
    std::uint32_t v;
    std::memcpy(&v, data.data() + at, 4);
    at += 4;
    return v;
  };
  const auto f64 = [&](const char* what) {
    need(8, what);
    double v;
    std::memcpy(&v, data.data() + at, 8);
    at += 8;
    return v;
  };
  const auto vec = [&](std::uint32_t expect, const char* what) {
    const std::size_t off = at;
    const std::uint32_t n = u32(what);
    if (n != expect)
      throw InputError(path + ": byte " + std::to_string(off) + ": " + what + " has " + std::to_string(n) +
                       " components, expected " + std::to_string(expect));
  };
  const std::uint32_t nodes = u32("the node count");
  if (nodes > 100000) throw InputError(path + ": " + std::to_string(nodes) + " nodes: not a ScanGraph file");
  for (std::uint32_t k = 0; k < nodes; ++k) {
    Scan s;
    const std::uint32_t n = u32("a point count");
    need(static_cast<std::size_t>(n) * 28, "the points");
    s.pts.reserve(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      vec(3, "a point");
      const double x = f64("a point"), y = f64("a point"), z = f64("a point");
      s.pts.push_back({x, y, z});
    }
    vec(3, "a pose translation");
    Eigen::Vector3d t;
    for (int a = 0; a < 3; ++a) t[a] = f64("a pose");
    vec(4, "a pose rotation");
    double q[4];
    for (double& v : q) v = f64("a pose");
    const std::uint32_t id = u32("a node id");
    s.T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    s.T.translation() = t;
    s.source = path + " node " + std::to_string(id);
    scans.push_back(std::move(s));
  }
  // Edges (constraints between nodes) are not needed to import the scans; check they parse.
  const std::uint32_t edges = u32("the edge count");
  for (std::uint32_t e = 0; e < edges; ++e) {
    u32("an edge");
    u32("an edge");
    vec(3, "an edge translation");
    for (int a = 0; a < 3; ++a) f64("an edge");
    vec(4, "an edge rotation");
    for (int a = 0; a < 4; ++a) f64("an edge");
    f64("an edge weight");
  }
  if (at != data.size())
    throw InputError(path + ": byte " + std::to_string(at) + ": " + std::to_string(data.size() - at) +
                     " bytes after the last edge");
}
}  // namespace

ImportedScans import_octomap(const std::vector<std::string>& files, const ImportOptions& opt) {
  ImportedScans out;
  for (const auto& f : files) {
    std::vector<Scan> scans;
    const bool graph = f.size() >= 6 && f.compare(f.size() - 6, 6, ".graph") == 0;
    if (graph) read_graph(f, scans);
    else read_scan_ascii(f, scans);
    for (auto& s : scans) add_scan(out, std::move(s), opt);
  }
  return out;
}

void read_ply(const std::string& path, std::vector<Eigen::Vector3d>& xyz, std::vector<float>& intensity) {
  require_regular_file(path, "PLY file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the PLY file");
  std::string line, format;
  std::size_t lineno = 0, vertices = 0;
  bool in_vertex = false, seen_vertex = false;
  struct Prop {
    std::string name, type;
  };
  std::vector<Prop> props;
  std::getline(in, line);
  ++lineno;
  if (line.rfind("ply", 0) != 0) throw InputError(path + ":1: not a PLY file (no 'ply' magic)");
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream is(line);
    std::string kw;
    is >> kw;
    if (kw == "format") {
      is >> format;
      if (format != "ascii" && format != "binary_little_endian")
        throw InputError(path + ":" + std::to_string(lineno) + ": PLY format '" + format +
                         "' is not supported (ascii, binary_little_endian)");
    } else if (kw == "element") {
      std::string name;
      std::size_t n = 0;
      is >> name >> n;
      if (seen_vertex && !in_vertex) continue;
      in_vertex = name == "vertex";
      if (in_vertex) {
        vertices = n;
        seen_vertex = true;
      } else if (!seen_vertex) {
        throw InputError(path + ":" + std::to_string(lineno) + ": element '" + name +
                         "' before 'vertex' is not supported (vertex must come first)");
      }
    } else if (kw == "property" && in_vertex) {
      Prop p;
      is >> p.type;
      if (p.type == "list") throw InputError(path + ":" + std::to_string(lineno) + ": list properties of vertex are not supported");
      is >> p.name;
      props.push_back(p);
    } else if (kw == "end_header") {
      break;
    }
  }
  if (!seen_vertex) throw InputError(path + ": no 'element vertex' in the header");
  int ix = -1, iy = -1, iz = -1, ii = -1;
  for (std::size_t i = 0; i < props.size(); ++i) {
    if (props[i].name == "x") ix = static_cast<int>(i);
    if (props[i].name == "y") iy = static_cast<int>(i);
    if (props[i].name == "z") iz = static_cast<int>(i);
    if (props[i].name == "intensity") ii = static_cast<int>(i);
  }
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(path + ": the vertex element has no x, y and z properties");
  const std::map<std::string, int> size = {{"char", 1},   {"uchar", 1},   {"int8", 1},    {"uint8", 1},  {"short", 2},
                                           {"ushort", 2}, {"int16", 2},   {"uint16", 2},  {"int", 4},    {"uint", 4},
                                           {"int32", 4},  {"uint32", 4},  {"float", 4},   {"float32", 4}, {"double", 8},
                                           {"float64", 8}};
  for (const auto& p : props)
    if (!size.count(p.type)) throw InputError(path + ": vertex property '" + p.name + "' has unknown type '" + p.type + "'");
  xyz.assign(vertices, Eigen::Vector3d::Zero());
  intensity.assign(ii >= 0 ? vertices : 0, 0.0f);
  std::vector<double> v(props.size());
  for (std::size_t n = 0; n < vertices; ++n) {
    if (format == "ascii") {
      if (!std::getline(in, line)) throw InputError(path + ": the file ends after " + std::to_string(n) + " of " + std::to_string(vertices) + " vertices");
      ++lineno;
      std::istringstream is(line);
      for (auto& x : v)
        if (!(is >> x)) throw InputError(path + ":" + std::to_string(lineno) + ": expected " + std::to_string(props.size()) + " numbers");
    } else {
      for (std::size_t i = 0; i < props.size(); ++i) {
        const std::string& t = props[i].type;
        unsigned char b[8];
        const int sz = size.at(t);
        if (!in.read(reinterpret_cast<char*>(b), sz))
          throw InputError(path + ": the file ends inside vertex " + std::to_string(n) + " of " + std::to_string(vertices));
        if (t == "float" || t == "float32") { float f; std::memcpy(&f, b, 4); v[i] = f; }
        else if (t == "double" || t == "float64") { double d; std::memcpy(&d, b, 8); v[i] = d; }
        else if (t == "char" || t == "int8") v[i] = static_cast<std::int8_t>(b[0]);
        else if (t == "uchar" || t == "uint8") v[i] = b[0];
        else if (t == "short" || t == "int16") { std::int16_t s; std::memcpy(&s, b, 2); v[i] = s; }
        else if (t == "ushort" || t == "uint16") { std::uint16_t s; std::memcpy(&s, b, 2); v[i] = s; }
        else if (t == "int" || t == "int32") { std::int32_t s; std::memcpy(&s, b, 4); v[i] = s; }
        else { std::uint32_t s; std::memcpy(&s, b, 4); v[i] = s; }
      }
    }
    xyz[n] = {v[static_cast<std::size_t>(ix)], v[static_cast<std::size_t>(iy)], v[static_cast<std::size_t>(iz)]};
    if (ii >= 0) intensity[n] = static_cast<float>(v[static_cast<std::size_t>(ii)]);
  }
}

namespace {
std::string fmt_num(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

/// Refuses a viewpoint farther than max_range from more than half of the points (see the header).
void check_viewpoint(const std::string& path, const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& vp,
                     const std::string& source, double max_range) {
  std::size_t finite = 0, far = 0;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& p : pts) {
    if (!p.allFinite()) continue;
    ++finite;
    if ((p - vp).norm() > max_range) ++far;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (finite == 0 || 2 * far <= finite) return;
  const Eigen::Vector3d top((lo.x() + hi.x()) / 2, (lo.y() + hi.y()) / 2, hi.z());
  const double reach = (Eigen::Vector3d(hi.x(), hi.y(), lo.z()) - top).norm();
  std::string msg = path + ": the viewpoint " + fmt_num(vp.x()) + "," + fmt_num(vp.y()) + "," + fmt_num(vp.z()) + " (" +
                    source + ") is farther than the maximum range " +
                    fmt_num(max_range) + " m from " + std::to_string(far) + " of the " + std::to_string(finite) +
                    " points: a sensor there could not have measured them (the rule: at least half of the points within " +
                    "--max-range of the viewpoint). The cloud spans x " + fmt_num(lo.x()) + ".." + fmt_num(hi.x()) + ", y " +
                    fmt_num(lo.y()) + ".." + fmt_num(hi.y()) + ", z " + fmt_num(lo.z()) + ".." + fmt_num(hi.z()) +
                    "; pass --viewpoint X,Y,Z where the sensor was (a map-frame or airborne cloud: e.g. above the centre, " +
                    fmt_num(top.x()) + "," + fmt_num(top.y()) + "," + fmt_num(top.z()) + ")";
  if (reach > max_range) msg += ", and --max-range of at least " + fmt_num(std::ceil(reach)) + " m to reach its corners from there";
  throw ConfigError(msg);
}

bool ends_with_ci(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  for (std::size_t i = 0; i < suffix.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i]) return false;
  return true;
}
}  // namespace

ImportedScans import_cloud(const std::vector<std::string>& files, const Eigen::Vector3d* viewpoint, const ImportOptions& opt) {
  ImportedScans out;
  for (const auto& f : files) {
    Scan s;
    s.source = f;
    std::vector<Eigen::Vector3d> pts;
    const bool ply = ends_with_ci(f, ".ply");
    if (ends_with_ci(f, ".laz"))
      throw InputError(f + ": LAZ (compressed LAS) is not supported: decompress it to LAS first "
                           "(e.g. `laszip -i IN.laz -o OUT.las` or `pdal translate IN.laz OUT.las`)");
    const bool las = ends_with_ci(f, ".las") || has_las_signature(f), las_or_ply = las || ply;
    if (las) {
      LasCloud c = read_las(f);
      const LasHeader& h = c.header;
      double m = opt.unit_scale;
      std::string note = f + ": LAS " + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) + ", point format " +
                         std::to_string(h.point_format) + ", " + std::to_string(h.points) + " points; ";
      if (h.unit_to_metre > 0)
        note += "units: " + h.unit_name + " (" + h.unit_source + ", " + std::to_string(h.unit_to_metre) + " m)";
      else
        note += "units: not declared (no GeoKey or WKT VLR)";
      if (m == 0.0) {
        m = h.unit_to_metre > 0 ? h.unit_to_metre : 1.0;
        note += h.unit_to_metre > 0 ? "; coordinates scaled to metres (x " + std::to_string(m) + ")"
                                    : "; taken as metres: pass --unit-scale 0.3048 if they are feet";
      } else {
        note += "; coordinates scaled by --unit-scale " + std::to_string(m);
      }
      out.notes.push_back(note);
      for (auto& p : c.xyz) p *= m;
      pts = std::move(c.xyz);
      s.amp = std::move(c.intensity);
    } else if (ply) {
      read_ply(f, pts, s.amp);
    } else {
      const PcdTable t = read_pcd(f);
      const int ix = t.header.field_index("x"), iy = t.header.field_index("y"), iz = t.header.field_index("z");
      if (ix < 0 || iy < 0 || iz < 0) throw InputError(f + ": field 'x', 'y' or 'z' is missing (a Cartesian cloud is expected)");
      const auto x = column_values(t, static_cast<std::size_t>(ix)), y = column_values(t, static_cast<std::size_t>(iy)),
                 z = column_values(t, static_cast<std::size_t>(iz));
      for (std::size_t i = 0; i < x.size(); ++i) pts.push_back({x[i], y[i], z[i]});
      const int ii = amplitude_field(t.header);  // intensity, else amplitude (our clouds up to 0.1.0)
      if (ii >= 0)
        for (const double a : column_values(t, static_cast<std::size_t>(ii))) s.amp.push_back(static_cast<float>(a));
      if (t.header.height > 1) {
        s.width = t.header.width;
        s.height = t.header.height;
      }
      const double* vp = t.header.viewpoint;
      s.T.translation() = Eigen::Vector3d(vp[0], vp[1], vp[2]);
      s.T.linear() = Eigen::Quaterniond(vp[3], vp[4], vp[5], vp[6]).normalized().toRotationMatrix();
      // A cloud of a georeferenced run (pcd_pipeline's cloud.pcd, "# map_origin X Y Z") stores its
      // points, and its VIEWPOINT, relative to that origin: back to map coordinates, so that the
      // passes, the poses and a --viewpoint are all in the map frame.
      const Eigen::Vector3d origin(t.header.map_origin[0], t.header.map_origin[1], t.header.map_origin[2]);
      if (!origin.isZero()) {
        for (auto& p : pts) p += origin;
        s.T.translation() += origin;
        out.notes.push_back(f + ": map_origin " + fmt_num(origin.x()) + "," + fmt_num(origin.y()) + "," + fmt_num(origin.z()) +
                            " added back: the points are in map coordinates");
      }
    }
    if (viewpoint) s.T = Eigen::Translation3d(*viewpoint) * Eigen::Isometry3d::Identity();
    check_viewpoint(f, pts, s.T.translation(),
                    viewpoint ? "--viewpoint" : las_or_ply ? "none given: PLY and LAS carry no viewpoint" : "the PCD VIEWPOINT",
                    opt.max_range);
    // Points into the sensor frame: p_s = R^T (p - t).
    for (auto& p : pts)
      if (p.allFinite()) p = s.T.inverse() * p;
    s.pts = std::move(pts);
    add_scan(out, std::move(s), opt);
  }
  return out;
}

}  // namespace pcdp::io
