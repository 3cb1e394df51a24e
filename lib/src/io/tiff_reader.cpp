#include "tiff_reader.hpp"

#include <libdeflate.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>

#include "pcdp/errors.hpp"
#include "tiff_format.hpp"
#include "xml_escape.hpp"

namespace pcdp::io::detail {

namespace {

std::uint64_t le(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = v << 8 | p[i];
  return v;
}

struct DecompressorFree {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

class Reader {
 public:
  Reader(std::string path, std::vector<std::uint8_t> bytes) : path_(std::move(path)), b_(std::move(bytes)) {}

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path_ + ": " + what); }

  /// `n` bytes at `at`, or an error naming `what`.
  const std::uint8_t* at(std::uint64_t off, std::uint64_t n, const std::string& what) const {
    if (off > b_.size() || n > b_.size() - off)
      fail(what + " lies beyond the end of the file (" + std::to_string(b_.size()) + " bytes)");
    return b_.data() + off;
  }
  std::size_t size() const { return b_.size(); }

  struct Entry {
    std::uint16_t type = 0;
    std::uint64_t count = 0;
    const std::uint8_t* value = nullptr;
  };

  /// The first image file directory, tag -> entry.
  std::map<std::uint16_t, Entry> directory() {
    const std::uint8_t* h = at(0, 8, "the TIFF header");
    if (h[0] == 'M' && h[1] == 'M') fail("a big-endian (\"MM\") TIFF; only little-endian (\"II\") files are read");
    if (h[0] != 'I' || h[1] != 'I') fail("not a TIFF file (it does not start with \"II\" or \"MM\")");
    const std::uint64_t magic = le(h + 2, 2);
    if (magic == 43) {
      big_ = true;
      const std::uint8_t* bh = at(0, 16, "the BigTIFF header");
      if (le(bh + 4, 2) != 8 || le(bh + 6, 2) != 0) fail("a BigTIFF header with an offset size other than 8");
    } else if (magic != 42) {
      fail("not a TIFF file (version " + std::to_string(magic) + ", not 42 or 43)");
    }
    const int field = big_ ? 8 : 4, count_bytes = big_ ? 8 : 2, entry_bytes = big_ ? 20 : 12;
    const std::uint64_t ifd = le(at(big_ ? 8 : 4, static_cast<std::uint64_t>(field), "the first directory's offset"), field);
    const std::uint64_t n = le(at(ifd, static_cast<std::uint64_t>(count_bytes), "the first directory"), count_bytes);
    if (n > b_.size() / static_cast<std::uint64_t>(entry_bytes)) fail("the first directory lies beyond the end of the file");
    const std::uint8_t* e = at(ifd + count_bytes, n * entry_bytes, "the first directory");
    std::map<std::uint16_t, Entry> dir;
    for (std::uint64_t k = 0; k < n; ++k, e += entry_bytes) {
      Entry en;
      const auto tag = static_cast<std::uint16_t>(le(e, 2));
      en.type = static_cast<std::uint16_t>(le(e + 2, 2));
      en.count = le(e + 4, field);
      const int unit = tiff_type_bytes(en.type);
      if (en.count > b_.size()) fail("tag " + std::to_string(tag) + " counts more values than the file has bytes");
      const std::uint64_t bytes = en.count * static_cast<std::uint64_t>(unit);
      const std::uint8_t* field_at = e + 4 + field;
      en.value = bytes <= static_cast<std::uint64_t>(field)
                     ? field_at
                     : at(le(field_at, field), bytes, "the values of tag " + std::to_string(tag));
      dir[tag] = en;
    }
    return dir;
  }

  /// The integers of an entry (SHORT, LONG or LONG8).
  std::vector<std::uint64_t> ints(std::uint16_t tag, const Entry& e) const {
    const int unit = e.type == kTiffShort ? 2 : e.type == kTiffLong ? 4 : e.type == kTiffLong8 ? 8 : 0;
    if (unit == 0) fail("tag " + std::to_string(tag) + " has field type " + std::to_string(e.type) + ", not an integer type");
    std::vector<std::uint64_t> v(e.count);
    for (std::uint64_t i = 0; i < e.count; ++i) v[i] = le(e.value + i * unit, unit);
    return v;
  }

 private:
  std::string path_;
  std::vector<std::uint8_t> b_;
  bool big_ = false;
};

const char* tag_name(std::uint16_t tag) {
  switch (tag) {
    case 256: return "ImageWidth";
    case 257: return "ImageLength";
    case 258: return "BitsPerSample";
    case 259: return "Compression";
    case 273: return "StripOffsets";
    case 277: return "SamplesPerPixel";
    case 278: return "RowsPerStrip";
    case 279: return "StripByteCounts";
    case 284: return "PlanarConfiguration";
    case 317: return "Predictor";
    case 339: return "SampleFormat";
    default: return "a tag";
  }
}
}  // namespace

FloatTiffData read_float_tiff(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path + ": cannot open");
  const std::streamoff end = in.tellg();
  if (end < 0) throw InputError(path + ": cannot read");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(end));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(bytes.data()), end)) throw InputError(path + ": cannot read");
  Reader r(path, std::move(bytes));
  const auto dir = r.directory();

  const auto values = [&](std::uint16_t tag) -> std::vector<std::uint64_t> {
    const auto it = dir.find(tag);
    if (it == dir.end()) return {};
    return r.ints(tag, it->second);
  };
  const auto one = [&](std::uint16_t tag, std::uint64_t fallback, bool required) {
    const std::vector<std::uint64_t> v = values(tag);
    if (v.empty()) {
      if (required) r.fail(std::string("tag ") + std::to_string(tag) + " (" + tag_name(tag) + ") is missing");
      return fallback;
    }
    return v[0];
  };
  const auto all_equal = [&](std::uint16_t tag, std::uint64_t want, const std::string& rule) {
    for (std::uint64_t v : values(tag))
      if (v != want)
        r.fail(std::string("tag ") + std::to_string(tag) + " (" + tag_name(tag) + ") = " + std::to_string(v) + ": " + rule);
  };
  if (dir.count(322) || dir.count(324)) r.fail("a tiled TIFF; only strips are read");
  const std::uint64_t w = one(256, 0, true), h = one(257, 0, true), spp = one(277, 1, false);
  if (w < 1 || h < 1 || spp < 1 || w > std::numeric_limits<int>::max() || h > std::numeric_limits<int>::max() ||
      spp > 65535)
    r.fail("a raster of " + std::to_string(w) + " x " + std::to_string(h) + " x " + std::to_string(spp) +
           " samples; each must be at least 1 (and fit an int)");
  if (values(258).empty()) r.fail("tag 258 (BitsPerSample) is missing");
  all_equal(258, 32, "only 32-bit samples are read");
  if (values(339).empty()) r.fail("tag 339 (SampleFormat) is missing: only IEEE float (3) samples are read");
  all_equal(339, 3, "only IEEE float (3) samples are read");
  const std::uint64_t compression = one(259, 1, false);
  if (compression != 1 && compression != 8 && compression != 32946)
    r.fail("tag 259 (Compression) = " + std::to_string(compression) + ": only none (1) and DEFLATE (8, 32946) are read");
  const std::uint64_t predictor = one(317, 1, false);
  if (predictor != 1) r.fail("tag 317 (Predictor) = " + std::to_string(predictor) + ": only no predictor (1) is read");
  const std::uint64_t planar = one(284, 1, false);
  if (planar != 1 && planar != 2) r.fail("tag 284 (PlanarConfiguration) = " + std::to_string(planar) + ": must be 1 or 2");
  const std::uint64_t rps = std::min(one(278, h, false), h);
  if (rps < 1) r.fail("tag 278 (RowsPerStrip) = 0");

  // A raster's samples cannot outgrow what its strips can hold: DEFLATE expands at most 1032 to
  // 1; uncompressed strips hold their bytes. Checked before anything is allocated.
  const std::uint64_t cells = w * h;  // < 2^62: both below 2^31
  if (spp > (std::uint64_t{1} << 62) / 4 / cells || cells * spp * 4 > r.size() * 1032 + 4096)
    r.fail("a raster of " + std::to_string(w) + " x " + std::to_string(h) + " x " + std::to_string(spp) +
           " floats is larger than its " + std::to_string(r.size()) + " bytes can hold");

  const std::uint64_t strips_down = (h + rps - 1) / rps;
  const std::uint64_t strips = planar == 2 ? strips_down * spp : strips_down;
  const std::vector<std::uint64_t> offsets = values(273), counts = values(279);
  if (offsets.size() != strips || counts.size() != strips)
    r.fail("tags 273 and 279 (StripOffsets, StripByteCounts) hold " + std::to_string(offsets.size()) + " and " +
           std::to_string(counts.size()) + " strips; the raster has " + std::to_string(strips));

  FloatTiffData t;
  t.width = static_cast<int>(w);
  t.height = static_cast<int>(h);
  t.bands = static_cast<int>(spp);
  t.planes.assign(spp, std::vector<float>(cells));
  const std::uint64_t per_pixel = planar == 2 ? 1 : spp;  // samples of a pixel in one strip
  std::vector<float> buf(rps * w * per_pixel);
  std::unique_ptr<libdeflate_decompressor, DecompressorFree> d(libdeflate_alloc_decompressor());
  if (!d) throw std::runtime_error(path + ": cannot set up DEFLATE");
  for (std::uint64_t s = 0; s < strips; ++s) {
    const std::uint64_t down = s % strips_down, band = planar == 2 ? s / strips_down : 0;
    const std::uint64_t rows = std::min(rps, h - down * rps);
    const std::uint64_t need = rows * w * per_pixel * 4;
    const std::string what = "strip " + std::to_string(s);
    const std::uint8_t* src = r.at(offsets[s], counts[s], what);
    if (compression == 1) {
      if (counts[s] < need) r.fail(what + " holds " + std::to_string(counts[s]) + " bytes, not " + std::to_string(need));
      std::memcpy(buf.data(), src, need);
    } else {
      // A last strip may be stored full height (libtiff) or cut to the rows left (GDAL): both do.
      std::size_t got = 0;
      const libdeflate_result res =
          libdeflate_zlib_decompress(d.get(), src, counts[s], buf.data(), buf.size() * sizeof(float), &got);
      if (res != LIBDEFLATE_SUCCESS || got < need) r.fail(what + " is not a whole DEFLATE (zlib) stream of its rows");
    }
    for (std::uint64_t row = 0; row < rows; ++row) {
      const std::uint64_t y = down * rps + row;
      if (planar == 2) {
        std::memcpy(t.planes[band].data() + y * w, buf.data() + row * w, w * sizeof(float));
      } else {
        const float* px = buf.data() + row * w * spp;
        for (std::uint64_t x = 0; x < w; ++x)
          for (std::uint64_t b = 0; b < spp; ++b) t.planes[b][y * w + x] = px[x * spp + b];
      }
    }
  }

  const auto doubles = [&](std::uint16_t tag, double* out, std::uint64_t n) {
    const auto it = dir.find(tag);
    if (it == dir.end()) return false;
    if (it->second.type != kTiffDouble || it->second.count < n)
      r.fail("tag " + std::to_string(tag) + " must hold at least " + std::to_string(n) + " doubles");
    for (std::uint64_t i = 0; i < n; ++i) {
      const std::uint64_t u = le(it->second.value + 8 * i, 8);
      std::memcpy(&out[i], &u, sizeof u);
    }
    return true;
  };
  const bool scale = doubles(33550, t.pixel_scale, 3), tie = doubles(33922, t.tiepoint, 6);
  t.georeferenced = scale && tie;
  const auto md = dir.find(42112);
  if (md != dir.end()) {
    if (md->second.type != kTiffAscii) r.fail("tag 42112 (GDAL_METADATA) is not ASCII");
    const char* c = reinterpret_cast<const char*>(md->second.value);
    t.gdal_metadata.assign(c, std::find(c, c + md->second.count, '\0'));
  }
  return t;
}

std::vector<std::pair<std::string, std::string>> gdal_metadata_items(const std::string& xml) {
  std::vector<std::pair<std::string, std::string>> items;
  for (std::size_t at = xml.find("<Item "); at != std::string::npos; at = xml.find("<Item ", at + 1)) {
    const std::size_t close = xml.find('>', at), end = xml.find("</Item>", at);
    if (close == std::string::npos || end == std::string::npos || end < close) break;
    const std::string attrs = xml.substr(at + 6, close - at - 6);
    if (attrs.find("sample=") != std::string::npos || attrs.find("role=") != std::string::npos) continue;
    const std::size_t n0 = attrs.find("name=\"");
    if (n0 == std::string::npos) continue;
    const std::size_t n1 = attrs.find('"', n0 + 6);
    if (n1 == std::string::npos) continue;
    items.emplace_back(xml_unescape(attrs.substr(n0 + 6, n1 - n0 - 6)),
                       xml_unescape(xml_unescape(xml.substr(close + 1, end - close - 1))));
  }
  return items;
}

}  // namespace pcdp::io::detail
