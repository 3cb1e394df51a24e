#include "pcdp/io/las.hpp"

#include <algorithm>
#include <cerrno>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {

template <typename T>
T get(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // LAS is little-endian, as is every platform this builds on
  return v;
}

std::string fixed_string(const std::uint8_t* p, std::size_t n) {
  std::string s(reinterpret_cast<const char*>(p), n);
  const auto z = s.find('\0');
  if (z != std::string::npos) s.resize(z);
  return s;
}

struct File {
  std::string path;
  std::ifstream in;
  std::uint64_t size = 0;

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path + ": " + what); }

  /// Reads n bytes at `at`; `what` names the part (for the message when the file is too short).
  void read(std::uint64_t at, std::size_t n, std::uint8_t* out, const std::string& what) {
    if (at > size || n > size - at)
      fail(what + " (bytes " + std::to_string(at) + "-" + std::to_string(at + n) + ") lies past the end of the file (" +
           std::to_string(size) + " bytes)");
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n)))
      fail("cannot read " + what + " at byte " + std::to_string(at));
  }
};

File open_las(const std::string& path) {
  require_regular_file(path, "LAS file");
  File f;
  f.path = path;
  f.in.open(path, std::ios::binary | std::ios::ate);
  if (!f.in) f.fail("cannot open the LAS file");
  const auto end = f.in.tellg();
  if (end < 0) f.fail("cannot find the size of the LAS file");
  f.size = static_cast<std::uint64_t>(end);
  return f;
}

/// A GeoTIFF unit code (EPSG linear unit) to its name and metres, or false when not a known one.
bool epsg_linear_unit(unsigned code, std::string& name, double& metres) {
  switch (code) {
    case 9001: name = "metre"; metres = 1.0; return true;
    case 9002: name = "foot"; metres = 0.3048; return true;
    case 9003: name = "US survey foot"; metres = 1200.0 / 3937.0; return true;
    case 9036: name = "kilometre"; metres = 1000.0; return true;
    default: return false;
  }
}

/// The GeoKeyDirectory (an array of uint16: version, revision, minor, key count, then 4 per key).
void unit_from_geokeys(const std::vector<std::uint8_t>& d, LasHeader& h, const std::string& path) {
  if (d.size() < 8) return;
  const std::size_t keys = get<std::uint16_t>(d.data() + 6);
  if (d.size() < 8 + 8 * keys)
    throw InputError(path + ": VLR LASF_Projection 34735 (GeoKeyDirectory): " + std::to_string(keys) +
                     " keys need " + std::to_string(8 + 8 * keys) + " bytes, the record has " + std::to_string(d.size()));
  unsigned proj = 0, vert = 0;
  for (std::size_t k = 0; k < keys; ++k) {
    const std::uint8_t* e = d.data() + 8 + 8 * k;
    const unsigned id = get<std::uint16_t>(e), loc = get<std::uint16_t>(e + 2), value = get<std::uint16_t>(e + 6);
    if (loc != 0) continue;  // the unit keys are SHORT values held in the entry itself
    if (id == 3076) proj = value;
    if (id == 4099) vert = value;
  }
  std::string name;
  double m = 0;
  if (proj && epsg_linear_unit(proj, name, m)) {
    h.unit_source = "GeoKey ProjLinearUnitsGeoKey = " + std::to_string(proj);
  } else if (vert && epsg_linear_unit(vert, name, m)) {
    h.unit_source = "GeoKey VerticalUnitsGeoKey = " + std::to_string(vert);
  } else {
    return;
  }
  h.unit_name = name;
  h.unit_to_metre = m;
}

/// OGC WKT (1 or 2): the last UNIT/LENGTHUNIT whose factor is not an angle's is the projected CRS's.
void unit_from_wkt(const std::string& wkt, LasHeader& h) {
  std::size_t at = 0;
  while ((at = wkt.find("UNIT[", at)) != std::string::npos) {
    const std::size_t q1 = wkt.find('"', at), q2 = q1 == std::string::npos ? q1 : wkt.find('"', q1 + 1);
    at += 5;
    if (q2 == std::string::npos) return;
    const std::size_t comma = wkt.find(',', q2);
    if (comma == std::string::npos) return;
    const std::string name = wkt.substr(q1 + 1, q2 - q1 - 1);
    char* end = nullptr;
    const double f = std::strtod(wkt.c_str() + comma + 1, &end);
    std::string low = name;
    for (auto& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (!(f > 0) || !std::isfinite(f) || low.find("degree") != std::string::npos || low.find("radian") != std::string::npos ||
        low.find("grad") != std::string::npos || low.find("arc") != std::string::npos)
      continue;
    h.unit_name = name;
    h.unit_to_metre = f;
    h.unit_source = "WKT UNIT[\"" + name + "\"," + wkt.substr(comma + 1, static_cast<std::size_t>(end - (wkt.c_str() + comma + 1))) + "]";
  }
}

LasHeader parse_header(File& f) {
  LasHeader h;
  const std::string& path = f.path;
  if (f.size < 4) f.fail("not a LAS file: " + std::to_string(f.size) + " bytes, no \"LASF\" signature");
  std::uint8_t b[375] = {};
  f.read(0, 4, b, "the signature");
  if (std::memcmp(b, "LASF", 4) != 0) f.fail("not a LAS file: it does not start with the signature \"LASF\"");
  if (f.size < 227) f.fail("the file ends inside the LAS header (" + std::to_string(f.size) + " bytes, a header has at least 227)");
  f.read(0, 227, b, "the header");
  h.version_major = b[24];
  h.version_minor = b[25];
  if (h.version_major != 1 || h.version_minor < 2 || h.version_minor > 4)
    f.fail("header field version (byte 24): LAS " + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) +
           " is not supported (1.2, 1.3, 1.4)");
  h.header_size = get<std::uint16_t>(b + 94);
  const std::uint16_t min_header = h.version_minor == 2 ? 227 : h.version_minor == 3 ? 235 : 375;
  if (h.header_size < min_header)
    f.fail("header field header size (byte 94) is " + std::to_string(h.header_size) + "; LAS 1." +
           std::to_string(h.version_minor) + " needs at least " + std::to_string(min_header));
  if (h.header_size > f.size)
    f.fail("header field header size (byte 94) is " + std::to_string(h.header_size) + ", larger than the file (" +
           std::to_string(f.size) + " bytes)");
  if (min_header > 227) f.read(0, min_header, b, "the header");
  h.offset_to_points = get<std::uint32_t>(b + 96);
  h.vlr_count = get<std::uint32_t>(b + 100);
  const unsigned format_byte = b[104];
  if (format_byte & 0xC0)
    f.fail("header field point data format (byte 104) is " + std::to_string(format_byte) +
           ": bits 6-7 mark a compressed (LAZ) file, which is not supported; decompress it to LAS first "
           "(e.g. `laszip -i IN.laz -o OUT.las` or `pdal translate IN.laz OUT.las`)");
  h.point_format = static_cast<int>(format_byte);
  const std::size_t need = las_point_size(h.point_format);
  if (need == 0)
    f.fail("header field point data format (byte 104) is " + std::to_string(format_byte) +
           "; supported: 0, 1, 2, 3, 6, 7, 8 (4, 5, 9, 10 carry waveforms)");
  if (h.point_format >= 6 && h.version_minor < 4)
    f.fail("header field point data format (byte 104) is " + std::to_string(format_byte) + ": formats 6-10 need LAS 1.4, the file is 1." +
           std::to_string(h.version_minor));
  h.record_length = get<std::uint16_t>(b + 105);
  if (h.record_length < need)
    f.fail("header field point data record length (byte 105) is " + std::to_string(h.record_length) + "; point format " +
           std::to_string(h.point_format) + " needs at least " + std::to_string(need) + " bytes");
  const std::uint32_t legacy = get<std::uint32_t>(b + 107);
  h.points = legacy;
  if (h.version_minor == 4) {
    const std::uint64_t count = get<std::uint64_t>(b + 247);
    if (legacy != 0 && legacy != count)
      f.fail("header field legacy number of point records (byte 107) is " + std::to_string(legacy) +
             " but number of point records (byte 247) is " + std::to_string(count) + "; they must agree (or the legacy one be 0)");
    h.points = count;
  }
  static const char* axis = "XYZ";
  for (int a = 0; a < 3; ++a) {
    h.scale[a] = get<double>(b + 131 + 8 * a);
    h.offset[a] = get<double>(b + 155 + 8 * a);
    h.max[a] = get<double>(b + 179 + 16 * a);
    h.min[a] = get<double>(b + 187 + 16 * a);
    if (!std::isfinite(h.scale[a]) || h.scale[a] == 0.0)
      f.fail(std::string("header field ") + axis[a] + " scale factor (byte " + std::to_string(131 + 8 * a) + ") is " +
             std::to_string(h.scale[a]) + "; it must be finite and not 0");
    if (!std::isfinite(h.offset[a]))
      f.fail(std::string("header field ") + axis[a] + " offset (byte " + std::to_string(155 + 8 * a) + ") is not finite");
  }
  if (h.offset_to_points < h.header_size)
    f.fail("header field offset to point data (byte 96) is " + std::to_string(h.offset_to_points) +
           ", inside the header (header size " + std::to_string(h.header_size) + ")");
  if (h.offset_to_points > f.size)
    f.fail("header field offset to point data (byte 96) is " + std::to_string(h.offset_to_points) + ", past the end of the file (" +
           std::to_string(f.size) + " bytes)");
  // VLRs: 54-byte headers and their payloads, between the header and the point data.
  std::uint64_t at = h.header_size;
  for (std::uint32_t v = 0; v < h.vlr_count; ++v) {
    const std::string which = "VLR " + std::to_string(v) + " of " + std::to_string(h.vlr_count);
    if (h.offset_to_points - at < 54)
      f.fail(which + " (byte " + std::to_string(at) + "): its 54-byte header does not fit before the point data (offset to point data " +
             std::to_string(h.offset_to_points) + "; is the header field number of VLRs (byte 100) right?)");
    std::uint8_t vh[54];
    f.read(at, 54, vh, which);
    const std::string user = fixed_string(vh + 2, 16);
    const unsigned id = get<std::uint16_t>(vh + 18);
    const std::uint16_t len = get<std::uint16_t>(vh + 20);
    at += 54;
    if (h.offset_to_points - at < len)
      f.fail(which + " (" + user + " " + std::to_string(id) + ", byte " + std::to_string(at - 54) + "): its " + std::to_string(len) +
             " bytes of data run past the offset to point data (" + std::to_string(h.offset_to_points) + ")");
    if (user == "LASF_Projection" && (id == 34735 || id == 2112) && len > 0) {
      std::vector<std::uint8_t> d(len);
      f.read(at, len, d.data(), which);
      if (id == 34735) unit_from_geokeys(d, h, path);
      else if (h.unit_to_metre == 0.0) unit_from_wkt(fixed_string(d.data(), d.size()), h);
    }
    at += len;
  }
  // The point data: points x record length, checked, must lie inside the file.
  const std::uint64_t avail = f.size - h.offset_to_points;
  if (h.points > avail / h.record_length)
    f.fail("header field number of point records (" + std::string(h.version_minor == 4 ? "byte 247" : "byte 107") + ") is " +
           std::to_string(h.points) + ": " + std::to_string(h.points) + " x " + std::to_string(h.record_length) +
           " bytes do not fit in the " + std::to_string(avail) + " bytes after the offset to point data (" +
           std::to_string(h.offset_to_points) + ")");
  return h;
}

}  // namespace

std::size_t las_point_size(int format) {
  switch (format) {
    case 0: return 20;
    case 1: return 28;
    case 2: return 26;
    case 3: return 34;
    case 6: return 30;
    case 7: return 36;
    case 8: return 38;
    default: return 0;
  }
}

bool has_las_signature(const std::string& path) {
  if (!regular_file_problem(path, "file").empty()) return false;
  std::ifstream in(path, std::ios::binary);
  char m[4] = {};
  return in.read(m, 4) && std::memcmp(m, "LASF", 4) == 0;
}

LasHeader read_las_header(const std::string& path) {
  File f = open_las(path);
  return parse_header(f);
}

LasCloud read_las(const std::string& path) {
  File f = open_las(path);
  LasCloud c;
  c.header = parse_header(f);
  const LasHeader& h = c.header;
  const std::size_t n = static_cast<std::size_t>(h.points);
  c.xyz.resize(n);
  c.intensity.resize(n);
  c.classification.resize(n);
  // Read in blocks of up to 64k points: memory is the output's, not the file's twice.
  const std::size_t block = 65536;
  std::vector<std::uint8_t> buf(std::min<std::size_t>(n, block) * h.record_length);
  const bool new_format = h.point_format >= 6;
  for (std::size_t i0 = 0; i0 < n; i0 += block) {
    const std::size_t m = std::min(block, n - i0);
    f.read(h.offset_to_points + static_cast<std::uint64_t>(i0) * h.record_length, m * h.record_length, buf.data(),
           "points " + std::to_string(i0) + "-" + std::to_string(i0 + m - 1));
    for (std::size_t j = 0; j < m; ++j) {
      const std::uint8_t* p = buf.data() + j * h.record_length;
      const std::size_t i = i0 + j;
      for (int a = 0; a < 3; ++a) c.xyz[i][a] = static_cast<double>(get<std::int32_t>(p + 4 * a)) * h.scale[a] + h.offset[a];
      if (!c.xyz[i].allFinite())
        f.fail("point " + std::to_string(i) + ": X * scale + offset is not finite (scale " + std::to_string(h.scale[0]) + ")");
      c.intensity[i] = static_cast<float>(get<std::uint16_t>(p + 12));
      c.classification[i] = new_format ? p[16] : static_cast<std::uint8_t>(p[15] & 0x1F);
    }
  }
  return c;
}

CloudFormat cloud_format_of(const std::string& path, const std::string& what) {
  const auto slash = path.find_last_of('/');
  const auto dot = path.find_last_of('.');
  std::string ext = dot == std::string::npos || (slash != std::string::npos && dot < slash) ? "" : path.substr(dot);
  std::string low = ext;
  for (auto& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (low == ".pcd") return CloudFormat::kPcd;
  if (low == ".ply") return CloudFormat::kPly;
  if (low == ".las") return CloudFormat::kLas;
  throw ConfigError(what + " '" + path + "': " + (ext.empty() ? "no extension" : "extension '" + ext + "'") +
                    " is not a cloud format this writes; use .pcd, .ply (binary little-endian) or .las (LAS 1.2)" +
                    (low == ".laz" ? " (LAZ, compressed LAS, is not written)" : ""));
}

namespace {
void put_bytes(std::vector<std::uint8_t>& out, const void* p, std::size_t n) {
  const auto* b = static_cast<const std::uint8_t*>(p);
  out.insert(out.end(), b, b + n);
}
template <typename T>
void put(std::vector<std::uint8_t>& out, T v) {
  put_bytes(out, &v, sizeof v);
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& head, const std::vector<std::uint8_t>& body) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> fp(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!fp) throw OutputError(path + ": cannot create the file (" + std::strerror(errno) + ")");
  if (std::fwrite(head.data(), 1, head.size(), fp.get()) != head.size() ||
      (!body.empty() && std::fwrite(body.data(), 1, body.size(), fp.get()) != body.size()) || std::fflush(fp.get()) != 0)
    throw OutputError(path + ": cannot write the file (" + std::strerror(errno) + ")");
  std::FILE* raw = fp.release();
  if (std::fclose(raw) != 0) throw OutputError(path + ": cannot close the file (" + std::strerror(errno) + ")");
}
}  // namespace

std::uint64_t write_las(const std::string& path, const CloudOut& c) {
  const std::size_t n = c.xyz.size();
  if (n > std::numeric_limits<std::uint32_t>::max())
    throw OutputError(path + ": " + std::to_string(n) + " points: LAS 1.2 holds at most 4294967295");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  std::size_t at_lo[3] = {0, 0, 0}, at_hi[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = c.xyz[i];
    if (!p.allFinite()) continue;
    for (int a = 0; a < 3; ++a) {
      if (p[a] < lo[a]) lo[a] = p[a], at_lo[a] = i;
      if (p[a] > hi[a]) hi[a] = p[a], at_hi[a] = i;
    }
  }
  if (!(lo.x() <= hi.x())) lo = hi = Eigen::Vector3d::Zero();
  const double scale = 0.001;
  // Millimetres as int32 about an offset rounded to whole metres: refused before anything is written.
  for (int a = 0; a < 3; ++a)
    if (hi[a] - lo[a] > 2 * 2147483.647 - 1.0) {
      char span[32];
      std::snprintf(span, sizeof span, "%.9g", hi[a] - lo[a]);
      throw LasSpanError(path + ": points " + std::to_string(at_lo[a]) + " and " + std::to_string(at_hi[a]) + " lie " +
                             span + " m apart along " + "xyz"[a] +
                             ": a LAS file (millimetres as 32-bit integers) spans at most 4,294 km",
                         at_lo[a], at_hi[a], hi[a] - lo[a], a);
    }
  const Eigen::Vector3d offset = ((lo + hi) / 2).array().round();
  std::uint32_t written = 0;
  std::vector<std::uint8_t> body;
  body.reserve(n * 28);
  unsigned by_return = 0;
  // The header's bounds are those of the stored (rounded) coordinates, so that every point a
  // reader decodes lies inside them.
  Eigen::Vector3d qlo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), qhi = -qlo;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = c.xyz[i];
    if (!p.allFinite()) continue;  // LAS has no "no point": non-finite points are not written
    for (int a = 0; a < 3; ++a) {
      const double q = std::round((p[a] - offset[a]) / scale);
      if (!(q >= std::numeric_limits<std::int32_t>::min() && q <= std::numeric_limits<std::int32_t>::max()))
        throw OutputError(path + ": point " + std::to_string(i) + " lies " + std::to_string(std::abs(p[a] - offset[a])) +
                          " from the LAS offset: at scale 0.001 a LAS coordinate reaches +-2147483.647");
      put(body, static_cast<std::int32_t>(q));
      qlo[a] = std::min(qlo[a], q);
      qhi[a] = std::max(qhi[a], q);
    }
    float a = i < c.intensity.size() ? c.intensity[i] : 0.0f;
    a = std::isfinite(a) ? std::clamp(a, 0.0f, 65535.0f) : 0.0f;
    put(body, static_cast<std::uint16_t>(std::lround(a)));
    put(body, static_cast<std::uint8_t>(0x09));  // return 1 of 1
    put(body, static_cast<std::uint8_t>(1));     // class 1: unclassified
    put(body, static_cast<std::int8_t>(0));      // scan angle rank
    put(body, static_cast<std::uint8_t>(i < c.label.size() ? c.label[i] : 0));  // user data: the pcd_pipeline label
    put(body, static_cast<std::uint16_t>(0));    // point source id
    put(body, 0.0);                              // GPS time
    ++written;
    ++by_return;
  }
  std::vector<std::uint8_t> h;
  h.reserve(227);
  put_bytes(h, "LASF", 4);
  put(h, static_cast<std::uint16_t>(0));  // file source id
  put(h, static_cast<std::uint16_t>(0));  // global encoding
  for (int i = 0; i < 16; ++i) put(h, static_cast<std::uint8_t>(0));  // GUID
  put(h, static_cast<std::uint8_t>(1));
  put(h, static_cast<std::uint8_t>(2));
  char sys[32] = "pcd_pipeline", gen[32] = "pcd_pipeline";
  put_bytes(h, sys, 32);
  put_bytes(h, gen, 32);
  put(h, static_cast<std::uint16_t>(0));  // creation day
  put(h, static_cast<std::uint16_t>(0));  // creation year
  put(h, static_cast<std::uint16_t>(227));
  put(h, static_cast<std::uint32_t>(227));  // offset to point data: no VLR
  put(h, static_cast<std::uint32_t>(0));
  put(h, static_cast<std::uint8_t>(1));
  put(h, static_cast<std::uint16_t>(28));
  put(h, written);
  put(h, static_cast<std::uint32_t>(by_return));
  for (int r = 1; r < 5; ++r) put(h, static_cast<std::uint32_t>(0));
  for (int a = 0; a < 3; ++a) put(h, scale);
  for (int a = 0; a < 3; ++a) put(h, offset[a]);
  for (int a = 0; a < 3; ++a) {
    put(h, written ? qhi[a] * scale + offset[a] : 0.0);
    put(h, written ? qlo[a] * scale + offset[a] : 0.0);
  }
  write_bytes(path, h, body);
  return written;
}

void write_ply(const std::string& path, const CloudOut& c) {
  const bool amp = !c.intensity.empty(), lab = !c.label.empty();
  std::string head = "ply\nformat binary_little_endian 1.0\ncomment written by pcd_pipeline\nelement vertex " +
                     std::to_string(c.xyz.size()) + "\nproperty double x\nproperty double y\nproperty double z\n";
  if (amp) head += "property float intensity\n";
  if (lab) head += "property uchar label\n";
  head += "end_header\n";
  std::vector<std::uint8_t> h(head.begin(), head.end()), body;
  body.reserve(c.xyz.size() * (24 + (amp ? 4 : 0) + (lab ? 1 : 0)));
  for (std::size_t i = 0; i < c.xyz.size(); ++i) {
    for (int a = 0; a < 3; ++a) put(body, c.xyz[i][a]);
    if (amp) put(body, i < c.intensity.size() ? c.intensity[i] : std::numeric_limits<float>::quiet_NaN());
    if (lab) put(body, i < c.label.size() ? c.label[i] : std::uint8_t{0});
  }
  write_bytes(path, h, body);
}

}  // namespace pcdp::io
