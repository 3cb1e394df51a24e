#include "tiff_writer.hpp"

#include <libdeflate.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include "pcdp/errors.hpp"
#include "tiff_format.hpp"
#include "xml_escape.hpp"

namespace pcdp::io::detail {

namespace {

// Little-endian bytes, whatever the host.
void put(std::vector<std::uint8_t>& b, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_double(std::vector<std::uint8_t>& b, double d) {
  std::uint64_t u;
  static_assert(sizeof u == sizeof d, "IEEE double");
  std::memcpy(&u, &d, sizeof u);
  put(b, u, 8);
}

// One image file directory: entries collected in tag order, laid out by bytes(). Values that fit
// in an entry's value field sit there; the others follow the directory, word-aligned.
class Ifd {
 public:
  explicit Ifd(bool big) : big_(big) {}
  void ints(std::uint16_t tag, std::uint16_t type, const std::vector<std::uint64_t>& v) {
    const int bytes = tiff_type_bytes(type);
    std::vector<std::uint8_t> b;
    for (std::uint64_t x : v) put(b, x, bytes);
    entries_.push_back({tag, type, v.size(), std::move(b)});
  }
  void doubles(std::uint16_t tag, const double* v, std::size_t n) {
    std::vector<std::uint8_t> b;
    for (std::size_t i = 0; i < n; ++i) put_double(b, v[i]);
    entries_.push_back({tag, kTiffDouble, n, std::move(b)});
  }
  void ascii(std::uint16_t tag, const std::string& s) {
    std::vector<std::uint8_t> b(s.begin(), s.end());
    b.push_back(0);
    const std::size_t n = b.size();
    entries_.push_back({tag, kTiffAscii, n, std::move(b)});
  }
  /// The directory at file offset `at` (entry count, entries, no next directory), then the
  /// values that did not fit in their entries.
  std::vector<std::uint8_t> bytes(std::uint64_t at) const {
    const int count_bytes = big_ ? 8 : 2, field = big_ ? 8 : 4;
    const std::uint64_t dir_size = count_bytes + (big_ ? 20 : 12) * entries_.size() + field;
    std::vector<std::uint8_t> dir, ext;
    put(dir, entries_.size(), count_bytes);
    for (const Entry& e : entries_) {
      put(dir, e.tag, 2);
      put(dir, e.type, 2);
      put(dir, e.count, field);
      if (e.value.size() <= static_cast<std::size_t>(field)) {
        dir.insert(dir.end(), e.value.begin(), e.value.end());
        for (std::size_t i = e.value.size(); i < static_cast<std::size_t>(field); ++i) dir.push_back(0);
      } else {
        while (ext.size() % 8) ext.push_back(0);  // TIFF 6.0 asks for even offsets
        put(dir, at + dir_size + ext.size(), field);
        ext.insert(ext.end(), e.value.begin(), e.value.end());
      }
    }
    put(dir, 0, field);
    dir.insert(dir.end(), ext.begin(), ext.end());
    return dir;
  }

 private:
  struct Entry {
    std::uint16_t tag, type;
    std::uint64_t count;
    std::vector<std::uint8_t> value;
  };
  bool big_;
  std::vector<Entry> entries_;
};

struct CompressorFree {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

}  // namespace

std::string gdal_metadata(const std::vector<std::pair<std::string, std::string>>& items,
                          const std::vector<std::string>& band_descriptions) {
  std::string xml = "<GDALMetadata>\n";
  for (const auto& [name, value] : items)
    xml += "  <Item name=\"" + xml_escape(name) + "\">" + xml_escape(xml_escape(value)) + "</Item>\n";
  for (std::size_t b = 0; b < band_descriptions.size(); ++b)
    if (!band_descriptions[b].empty())
      xml += "  <Item name=\"DESCRIPTION\" sample=\"" + std::to_string(b) + "\" role=\"description\">" +
             xml_escape(xml_escape(band_descriptions[b])) + "</Item>\n";
  return xml + "</GDALMetadata>\n";
}

namespace {
/// The layout write_float_tiff*() share: strips (t.tile == 0: the raster's width, rows_per_strip
/// rows, the last cut to the rows left) or tiles (t.tile x t.tile, stored whole, padded at the right
/// and bottom edges), band after band (PlanarConfiguration 2).
struct Layout {
  std::size_t w, h, bw, bh, across, down, blocks, nb;
  bool tiled;
  std::vector<int> first;  ///< first band of each group, then the end
  Layout(const std::string& path, const FloatTiff& t) {
    if (t.width < 1 || t.height < 1 || t.bands < 1 || t.rows_per_strip < 1)
      throw std::invalid_argument(path + ": a TIFF needs at least one row, column, band and row per strip");
    if (t.tile != 0 && (t.tile < 16 || t.tile % 16 != 0))
      throw std::invalid_argument(path + ": TIFF tiles are a multiple of 16 wide and long");
    tiled = t.tile != 0;
    w = static_cast<std::size_t>(t.width);
    h = static_cast<std::size_t>(t.height);
    bw = t.tile ? static_cast<std::size_t>(t.tile) : w;
    bh = t.tile ? static_cast<std::size_t>(t.tile) : static_cast<std::size_t>(t.rows_per_strip);
    across = (w + bw - 1) / bw;
    down = (h + bh - 1) / bh;
    blocks = across * down;
    nb = static_cast<std::size_t>(t.bands);
    first.assign(1, 0);
    for (int g : t.groups.empty() ? std::vector<int>(nb, 1) : t.groups) {
      if (g < 1) throw std::invalid_argument(path + ": an empty group of bands");
      first.push_back(first.back() + g);
    }
    if (first.back() != t.bands) throw std::invalid_argument(path + ": the groups do not add up to the bands");
  }
  /// Rows block `s` is stored with: a tile's whole length; a strip's rows, the last one cut.
  std::size_t rows(std::size_t s) const { return tiled ? bh : std::min(bh, h - (s / across) * bh); }
};

/// Compresses blocks into `out` (one vector per band and block, band after band); an empty
/// vector is a block not stored (sparse).
class Compressor {
 public:
  Compressor(const std::string& path, int level) : path_(path), c_(libdeflate_alloc_compressor(level)) {
    if (!c_) throw std::runtime_error(path + ": cannot set up DEFLATE at level " + std::to_string(level));
  }
  void operator()(const float* data, std::size_t n, std::vector<std::uint8_t>& z) {
    const std::size_t in = n * sizeof(float);
    z.resize(libdeflate_zlib_compress_bound(c_.get(), in));
    // TIFF stores little-endian floats in an "II" file: the plane's own bytes on this host.
    static_assert(std::numeric_limits<float>::is_iec559, "IEEE float");
    const std::size_t got = libdeflate_zlib_compress(c_.get(), data, in, z.data(), z.size());
    if (got == 0) throw std::runtime_error(path_ + ": DEFLATE failed");
    z.resize(got);
    z.shrink_to_fit();
  }

 private:
  const std::string& path_;
  std::unique_ptr<libdeflate_compressor, CompressorFree> c_;
};

void write_file(const std::string& path, const FloatTiff& t, const Layout& L,
                const std::vector<std::vector<std::uint8_t>>& out);
}  // namespace

void write_float_tiff(const std::string& path, const FloatTiff& t, int level, const PlaneFill& fill,
                      WorkShare& share) {
  if (t.tile != 0) throw std::invalid_argument(path + ": whole planes are written as strips; tiles take a BlockFill");
  const Layout L(path, t);
  // Compressed strips, band after band (PlanarConfiguration 2 orders them so).
  std::vector<std::vector<std::uint8_t>> out(L.nb * L.blocks);
  share.run(L.first.size() - 1, [&](std::size_t g) {
    Compressor compress(path, level);
    std::vector<std::vector<float>> planes(static_cast<std::size_t>(L.first[g + 1] - L.first[g]), std::vector<float>(L.w * L.h));
    fill(L.first[g], planes);
    for (std::size_t j = 0; j < planes.size(); ++j) {
      const std::size_t b = static_cast<std::size_t>(L.first[g]) + j;
      for (std::size_t s = 0; s < L.blocks; ++s)
        compress(planes[j].data() + s * L.bh * L.w, L.rows(s) * L.w, out[b * L.blocks + s]);
    }
  });
  write_file(path, t, L, out);
}

void write_float_tiff_blocks(const std::string& path, const FloatTiff& t, int level, const BlockFill& fill,
                             WorkShare& share) {
  const Layout L(path, t);
  std::vector<std::vector<std::uint8_t>> out(L.nb * L.blocks);
  share.run(L.first.size() - 1, [&](std::size_t g) {
    Compressor compress(path, level);
    std::vector<std::vector<float>> planes(static_cast<std::size_t>(L.first[g + 1] - L.first[g]));
    for (std::size_t s = 0; s < L.blocks; ++s) {
      Block blk;
      blk.index = s;
      blk.x0 = static_cast<int>((s % L.across) * L.bw);
      blk.y0 = static_cast<int>((s / L.across) * L.bh);
      blk.width = static_cast<int>(L.bw);
      blk.height = static_cast<int>(L.rows(s));
      for (auto& p : planes) p.resize(L.bw * L.rows(s));
      // A tile with nothing in it is not stored (TileOffsets and TileByteCounts 0: a sparse
      // file, read as nodata); a strip always is, as GDAL writes strips.
      if (!fill(L.first[g], blk, planes) && t.tile != 0) continue;
      for (std::size_t j = 0; j < planes.size(); ++j)
        compress(planes[j].data(), planes[j].size(), out[(static_cast<std::size_t>(L.first[g]) + j) * L.blocks + s]);
    }
  });
  write_file(path, t, L, out);
}

namespace {
void write_file(const std::string& path, const FloatTiff& t, const Layout& L,
                const std::vector<std::vector<std::uint8_t>>& out) {
  const std::size_t w = L.w, h = L.h, nb = L.nb;
  std::uint64_t data_bytes = 0;
  for (const auto& z : out) data_bytes += z.size();
  // Past 4 GiB of offsets a classic TIFF cannot point: BigTIFF then (GDAL's BIGTIFF=IF_NEEDED).
  const bool big = t.bigtiff || data_bytes + (std::uint64_t{1} << 24) > std::numeric_limits<std::uint32_t>::max();
  const std::uint64_t header = big ? 16 : 8;
  const std::uint64_t ifd_at = (header + data_bytes + 7) / 8 * 8;
  Ifd ifd(big);
  const std::uint16_t off_type = big ? kTiffLong8 : kTiffLong;
  std::vector<std::uint64_t> offsets, counts;
  std::uint64_t at = header;
  for (const auto& z : out) {
    offsets.push_back(z.empty() ? 0 : at);  // an empty block: not stored
    counts.push_back(z.size());
    at += z.size();
  }
  // Entries in ascending tag order.
  ifd.ints(256, kTiffLong, {w});                                // ImageWidth
  ifd.ints(257, kTiffLong, {h});                                // ImageLength
  ifd.ints(258, kTiffShort, std::vector<std::uint64_t>(nb, 32));  // BitsPerSample
  ifd.ints(259, kTiffShort, {8});                               // Compression: Deflate (zlib stream)
  ifd.ints(262, kTiffShort, {1});                               // PhotometricInterpretation: BlackIsZero
  if (!t.tile) ifd.ints(273, off_type, offsets);            // StripOffsets
  ifd.ints(277, kTiffShort, {nb});                              // SamplesPerPixel
  if (!t.tile) ifd.ints(278, kTiffLong, {L.bh});                // RowsPerStrip
  if (!t.tile) ifd.ints(279, off_type, counts);             // StripByteCounts
  ifd.ints(284, kTiffShort, {2});                               // PlanarConfiguration: separate planes
  ifd.ints(317, kTiffShort, {1});                               // Predictor: none
  if (t.tile) {
    ifd.ints(322, kTiffLong, {L.bw});     // TileWidth
    ifd.ints(323, kTiffLong, {L.bh});     // TileLength
    ifd.ints(324, off_type, offsets);  // TileOffsets (0: not stored)
    ifd.ints(325, off_type, counts);   // TileByteCounts (0: not stored)
  }
  if (nb > 1) ifd.ints(338, kTiffShort, std::vector<std::uint64_t>(nb - 1, 0));  // ExtraSamples: unspecified
  ifd.ints(339, kTiffShort, std::vector<std::uint64_t>(nb, 3));  // SampleFormat: IEEE float
  ifd.doubles(33550, t.pixel_scale, 3);
  ifd.doubles(33922, t.tiepoint, 6);
  if (!t.gdal_metadata.empty()) ifd.ascii(42112, t.gdal_metadata);
  if (!t.gdal_nodata.empty()) ifd.ascii(42113, t.gdal_nodata);

  std::vector<std::uint8_t> head;
  head.push_back('I');
  head.push_back('I');
  if (big) {
    put(head, 43, 2);
    put(head, 8, 2);  // bytes per offset
    put(head, 0, 2);
    put(head, ifd_at, 8);
  } else {
    put(head, 42, 2);
    put(head, ifd_at, 4);
  }
  const std::vector<std::uint8_t> tail = ifd.bytes(ifd_at);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw OutputError(path + ": cannot create (" + std::string(std::strerror(errno)) + ")");
  bool ok = std::fwrite(head.data(), 1, head.size(), f) == head.size();
  for (const auto& z : out) ok = ok && std::fwrite(z.data(), 1, z.size(), f) == z.size();
  static const std::uint8_t zeros[8] = {};
  const std::size_t pad = static_cast<std::size_t>(ifd_at - header - data_bytes);
  ok = ok && std::fwrite(zeros, 1, pad, f) == pad;
  ok = ok && std::fwrite(tail.data(), 1, tail.size(), f) == tail.size();
  ok = std::fclose(f) == 0 && ok;
  if (!ok) {
    const int e = errno;
    std::remove(path.c_str());
    throw OutputError(path + ": cannot write (" + std::string(std::strerror(e)) + ")");
  }
}
}  // namespace

}  // namespace pcdp::io::detail
