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
/// A pose held constant over a scan's span, sampled every 0.25 s (register interpolates).
void constant_pose(std::vector<PoseSample>& out, const Eigen::Isometry3d& T, double t0, double span) {
  const Eigen::Quaterniond q(T.linear());
  for (double t = t0 - 0.25; t <= t0 + span + 0.25; t += 0.25) out.push_back({t, T.translation(), q});
}

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
  constant_pose(out.poses, s.T, 1e5 * static_cast<double>(k), static_cast<double>(p.line_count()) * kScanLinePeriod);
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
/// Any magnitude, 7 significant digits (1e-30 and 1e160 print as such).
std::string fmt_g(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.7g", v);
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
      double norm = 0;
      const auto rot = unit_quaternion(vp[3], vp[4], vp[5], vp[6], &norm);
      if (!viewpoint && !rot)  // not a rotation: normalizing would silently make it the identity
        throw InputError(f + ": VIEWPOINT's rotation (qw qx qy qz = " + fmt_g(vp[3]) + " " + fmt_g(vp[4]) + " " + fmt_g(vp[5]) +
                         " " + fmt_g(vp[6]) + ", norm " + fmt_g(norm) +
                         ") is not a rotation (a norm of zero, below 1e-9 or not finite gives no direction): it must be the "
                         "sensor's orientation in the cloud's frame (1 0 0 0 for the same), or pass --viewpoint X,Y,Z (the "
                         "identity rotation)");
      s.T.translation() = Eigen::Vector3d(vp[0], vp[1], vp[2]);
      s.T.linear() = rot.value_or(Eigen::Quaterniond::Identity()).toRotationMatrix();
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
