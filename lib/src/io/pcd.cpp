#include "pcdp/io/pcd.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

namespace {

constexpr std::size_t kMaxHeaderBytes = 1 << 20;
constexpr std::uint64_t kMaxPoints = 1ull << 33;  // far above any pass; guards absurd headers
constexpr double kLzfMaxRatio = 90.0;             // a 3-byte LZF token expands to at most 264 bytes

[[noreturn]] void fail(const std::string& path, const std::string& msg) {
  throw InputError(path + ": " + msg);
}

std::vector<std::string> split_ws(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream is(s);
  for (std::string t; is >> t;) out.push_back(t);
  return out;
}

bool parse_u64(const std::string& s, std::uint64_t& v) {
  if (s.empty() || s[0] == '-') return false;
  errno = 0;
  char* end = nullptr;
  v = std::strtoull(s.c_str(), &end, 10);
  return *end == '\0' && errno == 0;
}

std::uint64_t file_size(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail(path, std::string("cannot open: ") + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) fail(path, "is a directory, not a PCD file");
  return static_cast<std::uint64_t>(st.st_size);
}

std::string read_prefix(const std::string& path, std::size_t max_bytes) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::string buf(max_bytes, '\0');
  const std::size_t n = std::fread(buf.data(), 1, max_bytes, f);
  std::fclose(f);
  buf.resize(n);
  return buf;
}

std::vector<std::uint8_t> read_range(const std::string& path, std::uint64_t offset, std::uint64_t n) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<std::uint8_t> buf(n);
  if (std::fseek(f, static_cast<long>(offset), SEEK_SET) != 0 || std::fread(buf.data(), 1, n, f) != n) {
    std::fclose(f);
    fail(path, "read error in the data section");
  }
  std::fclose(f);
  return buf;
}

bool store_ascii(const PcdField& f, const char* tok, std::uint8_t* dst) {
  char* end = nullptr;
  errno = 0;
  if (f.type == 'F') {
    const double v = std::strtod(tok, &end);
    if (*end != '\0') return false;
    // A finite number too large for the field is refused, not stored as inf ("inf" itself is kept).
    if (errno == ERANGE && std::isinf(v)) return false;
    if (f.size == 4 && std::isfinite(v) && std::fabs(v) >= 0x1.ffffffp+127) return false;  // rounds to inf as float
    if (f.size == 4) {
      const float x = static_cast<float>(v);
      std::memcpy(dst, &x, 4);
    } else {
      std::memcpy(dst, &v, 8);
    }
    return true;
  }
  if (f.type == 'U') {
    if (tok[0] == '-') return false;
    const unsigned long long v = std::strtoull(tok, &end, 10);
    if (*end != '\0' || errno == ERANGE) return false;
    const unsigned long long maxv = f.size == 8 ? std::numeric_limits<unsigned long long>::max()
                                                : (1ull << (8 * f.size)) - 1;
    if (v > maxv) return false;
    std::memcpy(dst, &v, static_cast<std::size_t>(f.size));  // little-endian
    return true;
  }
  const long long v = std::strtoll(tok, &end, 10);
  if (*end != '\0' || errno == ERANGE) return false;
  if (f.size < 8) {
    const long long lim = 1ll << (8 * f.size - 1);
    if (v < -lim || v >= lim) return false;
  }
  std::memcpy(dst, &v, static_cast<std::size_t>(f.size));
  return true;
}

}  // namespace

std::size_t PcdHeader::point_bytes() const {
  std::size_t n = 0;
  for (const auto& f : fields) n += f.bytes();
  return n;
}

int PcdHeader::field_index(const std::string& name) const {
  for (std::size_t i = 0; i < fields.size(); ++i)
    if (fields[i].name == name) return static_cast<int>(i);
  return -1;
}

double field_value(const PcdField& f, const std::uint8_t* p) {
  switch (f.type) {
    case 'F':
      if (f.size == 4) { float v; std::memcpy(&v, p, 4); return v; }
      { double v; std::memcpy(&v, p, 8); return v; }
    case 'U':
      switch (f.size) {
        case 1: return *p;
        case 2: { std::uint16_t v; std::memcpy(&v, p, 2); return v; }
        case 4: { std::uint32_t v; std::memcpy(&v, p, 4); return v; }
        default: { std::uint64_t v; std::memcpy(&v, p, 8); return static_cast<double>(v); }
      }
    default:
      switch (f.size) {
        case 1: return static_cast<std::int8_t>(*p);
        case 2: { std::int16_t v; std::memcpy(&v, p, 2); return v; }
        case 4: { std::int32_t v; std::memcpy(&v, p, 4); return v; }
        default: { std::int64_t v; std::memcpy(&v, p, 8); return static_cast<double>(v); }
      }
  }
}

namespace {

constexpr std::size_t kMaxFields = 10000;  // far above any sensor's; bounds the header's work

bool checked_mul(std::uint64_t a, std::uint64_t b, std::uint64_t& r) { return !__builtin_mul_overflow(a, b, &r); }
bool checked_add(std::uint64_t a, std::uint64_t b, std::uint64_t& r) { return !__builtin_add_overflow(a, b, &r); }

std::string header_at(int line, const char* key) {
  return "header line " + std::to_string(line) + " (" + key + ")";
}

}  // namespace

PcdHeader read_pcd_header(const std::string& path) {
  require_regular_file(path, "PCD file");
  const std::uint64_t fsize = file_size(path);
  if (fsize == 0) fail(path, "the file is empty (expected a PCD header)");
  const std::string buf = read_prefix(path, static_cast<std::size_t>(std::min<std::uint64_t>(fsize, kMaxHeaderBytes)));

  PcdHeader h;
  bool have_fields = false, have_size = false, have_type = false, have_count = false;
  bool have_width = false, have_height = false, have_points = false, have_data = false;
  int fields_line = 0, size_line = 0, type_line = 0, count_line = 0, width_line = 0, height_line = 0, points_line = 0;
  std::map<std::string, int> key_line;  // the line of each key seen: a key may appear once
  std::vector<std::string> sizes, types, counts;
  std::size_t pos = 0;
  int lineno = 0;
  while (pos < buf.size() && !have_data) {
    std::size_t eol = buf.find('\n', pos);
    if (eol == std::string::npos) {
      if (buf.size() < fsize) fail(path, "the header is longer than 1 MiB or not a PCD header");
      eol = buf.size();
    }
    std::string line = buf.substr(pos, eol - pos);
    pos = eol + 1;
    ++lineno;
    if (line.find('\0') != std::string::npos)
      fail(path, "header line " + std::to_string(lineno) + ": holds a NUL byte (binary data in the header, or not a PCD file)");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto tok = split_ws(line);
    if (!tok.empty() && tok[0] == "#" && tok.size() > 1 && tok[1] == "map_origin") {
      // pcd_pipeline's products relative to a map origin state it in this comment (other readers,
      // PCL's among them, skip comment lines): "# map_origin X Y Z".
      const std::string where = "header line " + std::to_string(lineno) + " (# map_origin)";
      if (tok.size() != 5) fail(path, where + ": expected 3 numbers (x y z of the map origin, m)");
      for (int i = 0; i < 3; ++i) {
        char* end = nullptr;
        h.map_origin[i] = std::strtod(tok[static_cast<std::size_t>(i) + 2].c_str(), &end);
        if (*end != '\0' || !std::isfinite(h.map_origin[i]))
          fail(path, where + ": '" + tok[static_cast<std::size_t>(i) + 2] + "' is not a finite number");
      }
      continue;
    }
    if (tok.empty() || tok[0][0] == '#') continue;
    const std::string& key = tok[0];
    const std::string where = "header line " + std::to_string(lineno) + " (" + key + ")";
    {
      const std::string canon = key == "COLUMNS" ? "FIELDS" : key;  // an old synonym
      const auto seen = key_line.emplace(canon, lineno);
      if (!seen.second)
        fail(path, where + ": a second " + canon + " line (the first is header line " + std::to_string(seen.first->second) +
                       "); each header key appears once");
    }
    std::vector<std::string> args(tok.begin() + 1, tok.end());
    if (key == "VERSION") {
      continue;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      if (args.empty()) fail(path, where + ": no field names");
      if (args.size() > kMaxFields)
        fail(path, where + ": " + std::to_string(args.size()) + " fields; at most " + std::to_string(kMaxFields) + " are supported");
      h.fields.clear();
      for (const auto& a : args) h.fields.push_back({a, 'F', 4, 1});
      have_fields = true;
      fields_line = lineno;
    } else if (key == "SIZE") {
      sizes = args;
      have_size = true;
      size_line = lineno;
    } else if (key == "TYPE") {
      types = args;
      have_type = true;
      type_line = lineno;
    } else if (key == "COUNT") {
      counts = args;
      have_count = true;
      count_line = lineno;
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      std::uint64_t v = 0;
      if (args.size() != 1 || !parse_u64(args[0], v)) fail(path, where + ": expected one non-negative integer");
      if (v > kMaxPoints) fail(path, where + ": " + args[0] + " is not a plausible point count (limit " + std::to_string(kMaxPoints) + ")");
      if (key == "WIDTH") { h.width = v; have_width = true; width_line = lineno; }
      else if (key == "HEIGHT") { h.height = v; have_height = true; height_line = lineno; }
      else { h.points = v; have_points = true; points_line = lineno; }
    } else if (key == "VIEWPOINT") {
      if (args.size() != 7) fail(path, where + ": expected 7 numbers (tx ty tz qw qx qy qz)");
      for (int i = 0; i < 7; ++i) {
        char* end = nullptr;
        h.viewpoint[i] = std::strtod(args[static_cast<std::size_t>(i)].c_str(), &end);
        if (*end != '\0' || !std::isfinite(h.viewpoint[i])) fail(path, where + ": '" + args[static_cast<std::size_t>(i)] + "' is not a finite number");
      }
    } else if (key == "DATA") {
      if (args.size() != 1) fail(path, where + ": expected ascii, binary or binary_compressed");
      if (args[0] == "ascii") h.data = PcdData::kAscii;
      else if (args[0] == "binary") h.data = PcdData::kBinary;
      else if (args[0] == "binary_compressed") h.data = PcdData::kBinaryCompressed;
      else fail(path, where + ": unknown data format '" + args[0] + "' (expected ascii, binary or binary_compressed)");
      have_data = true;
      // A DATA line that ends the file without a newline leaves pos one past the end; clamp it so the
      // "bytes available" arithmetic in read_pcd cannot wrap around (found by fuzz_pcd).
      h.data_offset = std::min<std::size_t>(pos, buf.size());
    } else {
      fail(path, where + ": unknown header key '" + key + "' (is this a PCD v0.7 file?)");
    }
  }
  if (!have_data) fail(path, "the header has no DATA line (truncated file, or not a PCD file)");
  if (!have_fields) fail(path, "the header has no FIELDS line");
  if (!have_size || !have_type) fail(path, "the header needs SIZE and TYPE lines");
  if (!have_width) fail(path, "the header has no WIDTH line");
  const std::size_t nf = h.fields.size();
  if (sizes.size() != nf)
    fail(path, header_at(size_line, "SIZE") + ": SIZE has " + std::to_string(sizes.size()) + " entries but FIELDS has " + std::to_string(nf));
  if (types.size() != nf)
    fail(path, header_at(type_line, "TYPE") + ": TYPE has " + std::to_string(types.size()) + " entries but FIELDS has " + std::to_string(nf));
  if (have_count && counts.size() != nf)
    fail(path, header_at(count_line, "COUNT") + ": COUNT has " + std::to_string(counts.size()) + " entries but FIELDS has " + std::to_string(nf));
  std::uint64_t point_bytes = 0;
  for (std::size_t i = 0; i < nf; ++i) {
    PcdField& f = h.fields[i];
    std::uint64_t sz = 0, cnt = 1;
    if (!parse_u64(sizes[i], sz) || (sz != 1 && sz != 2 && sz != 4 && sz != 8))
      fail(path, header_at(size_line, "SIZE") + ": field '" + f.name + "': SIZE '" + sizes[i] + "' must be 1, 2, 4 or 8");
    if (types[i].size() != 1 || std::string("FUI").find(types[i][0]) == std::string::npos)
      fail(path, header_at(type_line, "TYPE") + ": field '" + f.name + "': TYPE '" + types[i] + "' must be F, U or I");
    if (have_count && (!parse_u64(counts[i], cnt) || cnt == 0 || cnt > 1000000))
      fail(path, header_at(count_line, "COUNT") + ": field '" + f.name + "': COUNT '" + counts[i] + "' must be an integer from 1 to 1000000");
    f.type = types[i][0];
    f.size = static_cast<int>(sz);
    f.count = static_cast<int>(cnt);
    if (f.type == 'F' && f.size != 4 && f.size != 8)
      fail(path, header_at(size_line, "SIZE") + ": field '" + f.name + "': a float field must have SIZE 4 or 8, not " + sizes[i]);
    if (!checked_add(point_bytes, f.bytes(), point_bytes))
      fail(path, header_at(count_line, "COUNT") + ": the bytes of one point overflow 64-bit arithmetic");
  }
  {  // A name may appear once ('_' is padding and may repeat): sorted, so O(n log n) in the fields.
    std::vector<std::size_t> order;
    order.reserve(nf);
    for (std::size_t i = 0; i < nf; ++i)
      if (h.fields[i].name != "_") order.push_back(i);
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const int c = h.fields[a].name.compare(h.fields[b].name);
      return c != 0 ? c < 0 : a < b;
    });
    std::size_t dup = nf;  // the first field (in file order) that repeats an earlier name
    for (std::size_t k = 1; k < order.size(); ++k)
      if (h.fields[order[k]].name == h.fields[order[k - 1]].name) dup = std::min(dup, order[k]);
    if (dup < nf) fail(path, header_at(fields_line, "FIELDS") + ": field '" + h.fields[dup].name + "' appears twice in FIELDS");
  }
  if (!have_height) h.height = 1;
  const int wh_line = have_height ? height_line : width_line;
  const char* wh_key = have_height ? "HEIGHT" : "WIDTH";
  if (h.height == 0 && h.width != 0)
    fail(path, header_at(height_line, "HEIGHT") + ": HEIGHT 0 with WIDTH " + std::to_string(h.width) +
                   " (HEIGHT is the number of rows, at least 1; an empty file has WIDTH 0)");
  std::uint64_t wh = 0;
  if (!checked_mul(h.width, h.height, wh) || wh > kMaxPoints)
    fail(path, header_at(wh_line, wh_key) + ": WIDTH x HEIGHT = " + std::to_string(h.width) + " x " + std::to_string(h.height) +
                   " is not a plausible point count (limit " + std::to_string(kMaxPoints) + ")");
  if (!have_points) h.points = wh;
  if (h.points != wh)
    fail(path, header_at(points_line, "POINTS") + ": POINTS " + std::to_string(h.points) + " disagrees with WIDTH x HEIGHT = " +
                   std::to_string(h.width) + " x " + std::to_string(h.height));
  // Every size the reader derives from the header is checked here, before anything is allocated.
  std::uint64_t data_bytes = 0;
  const int n_line = have_points ? points_line : wh_line;
  const char* n_key = have_points ? "POINTS" : wh_key;
  if (!checked_mul(h.points, point_bytes, data_bytes))
    fail(path, header_at(n_line, n_key) + ": " + std::to_string(h.points) + " points of " + std::to_string(point_bytes) +
                   " bytes (the sum of SIZE x COUNT over FIELDS) overflow 64-bit arithmetic");
  // No encoding stores a point in less than 1/kLzfMaxRatio of its bytes: a claim beyond that is
  // refused here, whatever the encoding (the readers below check each encoding exactly).
  const std::uint64_t avail = fsize - h.data_offset;
  if (static_cast<double>(data_bytes) > kLzfMaxRatio * static_cast<double>(avail) + 64.0)
    fail(path, header_at(n_line, n_key) + ": truncated: the header claims " + std::to_string(h.points) + " points (" +
                   std::to_string(data_bytes) + " bytes) but the file holds " + std::to_string(avail) +
                   " bytes of data, too few for any PCD encoding");
  return h;
}

namespace {

PcdTable read_pcd_unguarded(const std::string& path) {
  PcdTable t;
  t.header = read_pcd_header(path);
  const PcdHeader& h = t.header;
  const std::uint64_t fsize = file_size(path);
  const std::uint64_t avail = fsize - h.data_offset;
  const std::size_t pb = h.point_bytes();
  std::uint64_t need = 0;
  if (!checked_mul(h.points, pb, need)) fail(path, "the header's point count times point size overflows");  // checked above
  const std::size_t nf = h.fields.size();
  const auto claims = [&] {
    return "the header claims " + std::to_string(h.points) + " points (" + std::to_string(need) + " bytes)";
  };

  t.columns.resize(nf);
  if (h.data == PcdData::kBinary) {
    if (avail < need)
      fail(path, "truncated: " + claims() + " but the file holds " + std::to_string(avail) + " bytes of data (" +
                     std::to_string(avail / (pb ? pb : 1)) + " whole points)");
    if (avail > need)
      fail(path, "the file holds " + std::to_string(avail - need) + " bytes after the last of the " +
                     std::to_string(h.points) + " points the header declares (header and data disagree)");
    const auto data = read_range(path, h.data_offset, need);
    std::size_t off = 0;
    for (std::size_t i = 0; i < nf; ++i) {
      const std::size_t fb = h.fields[i].bytes();
      auto& col = t.columns[i];
      col.resize(h.points * fb);
      for (std::uint64_t p = 0; p < h.points; ++p) std::memcpy(col.data() + p * fb, data.data() + p * pb + off, fb);
      off += fb;
    }
  } else if (h.data == PcdData::kBinaryCompressed) {
    if (avail < 8) fail(path, "truncated: binary_compressed data needs an 8-byte size prefix, the file holds " + std::to_string(avail) + " bytes");
    const auto sizes = read_range(path, h.data_offset, 8);
    std::uint32_t csize = 0, usize = 0;
    std::memcpy(&csize, sizes.data(), 4);
    std::memcpy(&usize, sizes.data() + 4, 4);
    if (usize != need)
      fail(path, "binary_compressed: the uncompressed size " + std::to_string(usize) + " disagrees with " + claims());
    if (csize > avail - 8)
      fail(path, "truncated: binary_compressed declares " + std::to_string(csize) + " compressed bytes but " +
                     std::to_string(avail - 8) + " follow");
    // PCL 1.7's writer sized binary_compressed files for the worst case and left zeros after the
    // data (the ISPRS clouds of PointCloudLibrary/data): zero padding is accepted, anything else not.
    bool zero_tail = csize < avail - 8;
    for (std::uint64_t at = h.data_offset + 8 + csize; zero_tail && at < fsize;) {
      const std::uint64_t len = std::min<std::uint64_t>(fsize - at, 1 << 20);
      const auto tail = read_range(path, at, static_cast<std::size_t>(len));
      zero_tail = std::all_of(tail.begin(), tail.end(), [](std::uint8_t b) { return b == 0; });
      at += len;
    }
    if (csize < avail - 8 && !zero_tail)
      fail(path, "binary_compressed: the file holds " + std::to_string(avail - 8 - csize) + " bytes after the " +
                     std::to_string(csize) + " compressed bytes the data declares, not all zero (header and data disagree)");
    if (static_cast<double>(usize) > kLzfMaxRatio * static_cast<double>(csize) + 64.0)
      fail(path, "binary_compressed: " + std::to_string(csize) + " compressed bytes cannot hold " + claims());
    std::vector<std::uint8_t> raw(need);
    if (need > 0) {
      const auto comp = read_range(path, h.data_offset + 8, csize);
      if (!lzf_decompress(comp.data(), comp.size(), raw.data(), raw.size()))
        fail(path, "binary_compressed: corrupt LZF data (does not decode to " + std::to_string(need) + " bytes)");
    }
    std::size_t off = 0;  // column-major: all of field 0, then all of field 1, ...
    for (std::size_t i = 0; i < nf; ++i) {
      const std::size_t n = h.points * h.fields[i].bytes();
      t.columns[i].assign(raw.begin() + static_cast<long>(off), raw.begin() + static_cast<long>(off + n));
      off += n;
    }
  } else {
    // Each point takes at least two bytes per value ("0 "), so a header claiming more than the
    // file could hold is rejected before anything is read. The columns grow with the points read,
    // never by the header's claim.
    std::uint64_t values = 0, min_bytes = 0;
    for (const auto& f : h.fields) checked_add(values, static_cast<std::uint64_t>(f.count), values);  // <= 1e10
    if (!checked_mul(h.points, values, min_bytes) || !checked_mul(min_bytes, 2, min_bytes) || min_bytes > avail + 1)
      fail(path, "truncated: " + claims() + " but the " + std::to_string(avail) +
                     " bytes of ascii data cannot hold them");
    const auto data = read_range(path, h.data_offset, avail);
    if (const void* nul = data.empty() ? nullptr : std::memchr(data.data(), '\0', data.size())) {
      const auto at = static_cast<std::size_t>(static_cast<const std::uint8_t*>(nul) - data.data());
      const auto line = 1 + std::count(data.begin(), data.begin() + static_cast<long>(at), '\n');
      fail(path, "data line " + std::to_string(line) + ": holds a NUL byte (binary data in an ascii PCD?)");
    }
    std::size_t pos = 0;
    std::uint64_t p = 0;
    std::uint64_t lineno = 0;
    std::vector<char> line;
    while (pos < data.size()) {
      std::size_t eol = pos;
      while (eol < data.size() && data[eol] != '\n') ++eol;
      line.assign(data.begin() + static_cast<long>(pos), data.begin() + static_cast<long>(eol));
      line.push_back('\0');
      pos = eol + 1;
      ++lineno;
      char* save = nullptr;
      char* tok = strtok_r(line.data(), " \t\r", &save);
      if (!tok) continue;  // blank line
      if (p >= h.points) fail(path, "data line " + std::to_string(lineno) + ": more points than the " + std::to_string(h.points) + " the header declares");
      for (std::size_t i = 0; i < nf; ++i) {
        const PcdField& f = h.fields[i];
        t.columns[i].resize((p + 1) * f.bytes());
        for (int c = 0; c < f.count; ++c) {
          if (!tok)
            fail(path, "data line " + std::to_string(lineno) + " (point " + std::to_string(p) + "): too few values (field '" + f.name + "' missing)");
          std::uint8_t* dst = t.columns[i].data() + p * f.bytes() + static_cast<std::size_t>(c) * static_cast<std::size_t>(f.size);
          if (!store_ascii(f, tok, dst))
            fail(path, "data line " + std::to_string(lineno) + " (point " + std::to_string(p) + "): field '" + f.name + "': '" +
                           tok + "' is not a valid " + std::string(1, f.type) + std::to_string(f.size) + " value");
          tok = strtok_r(nullptr, " \t\r", &save);
        }
      }
      if (tok) fail(path, "data line " + std::to_string(lineno) + " (point " + std::to_string(p) + "): more values than the fields declare");
      ++p;
    }
    if (p != h.points)
      fail(path, "truncated: " + claims() + " but the file holds " + std::to_string(p) + " points");
  }
  return t;
}

}  // namespace

PcdTable read_pcd(const std::string& path) {
  try {
    return read_pcd_unguarded(path);
  } catch (const std::bad_alloc&) {
    struct stat st {};
    const std::string size = ::stat(path.c_str(), &st) == 0 ? " of " + std::to_string(st.st_size) + " bytes" : "";
    fail(path, "out of memory while reading this PCD file" + size + " (free memory, or split the pass)");
  }
}

// ---- writer --------------------------------------------------------------------------------

PcdWriter::PcdWriter(std::string path, std::vector<PcdField> fields)
    : path_(std::move(path)), body_path_(path_ + ".body"), fields_(std::move(fields)) {
  for (const auto& f : fields_) point_bytes_ += f.bytes();
  body_ = std::fopen(body_path_.c_str(), "wb");
  if (!body_) throw OutputError(body_path_ + ": cannot create (" + std::strerror(errno) + ")");
}

PcdWriter::~PcdWriter() {
  if (body_) {
    std::fclose(body_);
    std::remove(body_path_.c_str());
  }
}

void PcdWriter::append(const std::uint8_t* rows, std::size_t n) {
  if (n == 0) return;
  if (std::fwrite(rows, point_bytes_, n, body_) != n)
    throw OutputError(body_path_ + ": write failed (" + std::strerror(errno) + ")");
  points_ += n;
}

void PcdWriter::close(std::uint64_t height) {
  if (!body_) return;
  if (std::fflush(body_) != 0) throw OutputError(body_path_ + ": write failed (" + std::strerror(errno) + ")");
  std::fclose(body_);
  body_ = nullptr;
  if (height == 0 || points_ % height != 0) height = 1;
  std::ostringstream hs;
  hs << "# .PCD v0.7 - Point Cloud Data file format (written by pcd_pipeline)\n";
  if (map_origin_[0] != 0.0 || map_origin_[1] != 0.0 || map_origin_[2] != 0.0) {
    char o[112];  // %.17g: a round origin stays "500000"
    std::snprintf(o, sizeof o, "# map_origin %.17g %.17g %.17g\n", map_origin_[0], map_origin_[1], map_origin_[2]);
    hs << o;
  }
  hs << "VERSION 0.7\nFIELDS";
  for (const auto& f : fields_) hs << ' ' << f.name;
  hs << "\nSIZE";
  for (const auto& f : fields_) hs << ' ' << f.size;
  hs << "\nTYPE";
  for (const auto& f : fields_) hs << ' ' << f.type;
  hs << "\nCOUNT";
  for (const auto& f : fields_) hs << ' ' << f.count;
  hs << "\nWIDTH " << points_ / height << "\nHEIGHT " << height << "\nVIEWPOINT";
  for (const double v : viewpoint_) {
    char b[32];  // %.17g: round trips, and the default stays "0 0 0 1 0 0 0"
    std::snprintf(b, sizeof b, " %.17g", v);
    hs << b;
  }
  hs << "\nPOINTS " << points_ << "\nDATA binary\n";
  const std::string header = hs.str();

  std::FILE* out = std::fopen(path_.c_str(), "wb");
  std::FILE* in = std::fopen(body_path_.c_str(), "rb");
  bool ok = out && in && std::fwrite(header.data(), 1, header.size(), out) == header.size();
  std::vector<char> buf(1 << 20);
  while (ok) {
    const std::size_t n = std::fread(buf.data(), 1, buf.size(), in);
    if (n == 0) break;
    ok = std::fwrite(buf.data(), 1, n, out) == n;
  }
  if (in) std::fclose(in);
  if (out && std::fclose(out) != 0) ok = false;
  std::remove(body_path_.c_str());
  if (!ok) throw OutputError(path_ + ": write failed (" + std::strerror(errno) + ")");
}

std::vector<double> column_values(const PcdTable& t, std::size_t k) {
  const PcdField& f = t.header.fields[k];
  const std::vector<std::uint8_t>& c = t.columns[k];
  std::vector<double> v(t.header.points);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = field_value(f, c.data() + i * f.bytes());
  return v;
}

}  // namespace pcdp::io
