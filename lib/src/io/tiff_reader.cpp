#include "tiff_reader.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>

#include "pcdp/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "tiff_format.hpp"
#include "xml_escape.hpp"

namespace pcdp::io::detail {

namespace {
std::uint64_t le(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = v << 8 | p[i];
  return v;
}

constexpr std::uint64_t kChunkFloats = 256 * 1024;  // a row's buffer grows by at most this as data arrives
constexpr std::uint64_t kInBytes = 64 * 1024;       // compressed bytes read at a time

/// One stored block (strip or tile) of one plane, decoded a row at a time as its bytes are read:
/// the memory it takes is its input buffer and zlib's window, whatever the block's size.
struct BlockStream {
  std::uint64_t off = 0, left = 0;  ///< the stored bytes not read yet
  bool deflate = false, sparse = false, open = false;
  z_stream z{};
  std::vector<std::uint8_t> in;
  BlockStream() = default;
  BlockStream(const BlockStream&) = delete;
  BlockStream& operator=(const BlockStream&) = delete;
  ~BlockStream() {
    if (open) inflateEnd(&z);
  }
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
    case 322: return "TileWidth";
    case 323: return "TileLength";
    case 339: return "SampleFormat";
    default: return "a tag";
  }
}

struct Entry {
  std::uint16_t type = 0;
  std::uint64_t count = 0;
  std::vector<std::uint8_t> value;  ///< count values of the type's size (none for an unknown type)
};
}  // namespace

struct FloatTiffRows::Impl {
  std::string path;
  std::ifstream in;
  std::uint64_t size = 0;  ///< of the file, bytes
  FloatTiffInfo info;
  // The raster is stored in blocks: strips (the raster's width, rps rows) or tiles (bw x rps,
  // `across` of them side by side, padded at the right and bottom edges). A strip is one block
  // across; `strips_down` counts the rows of blocks.
  std::uint64_t w = 0, h = 0, spp = 0, rps = 0, planar = 1, compression = 1, strips_down = 0;
  std::uint64_t bw = 0, across = 1;
  bool tiled = false;
  std::vector<std::uint64_t> offsets, counts;
  std::uint64_t next_down = 0;  ///< the next row of blocks
  std::vector<float> row;       ///< one row of a pixel-interleaved block

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path + ": " + what); }

  /// An error naming `what` unless the file holds `n` bytes at `off`.
  void check_within(std::uint64_t off, std::uint64_t n, const std::string& what) const {
    if (off > size || n > size - off)
      fail(what + " lies beyond the end of the file (" + std::to_string(size) + " bytes)");
  }
  /// `n` bytes at `off` into `out`, or an error naming `what`.
  void read(std::uint64_t off, std::uint64_t n, const std::string& what, std::uint8_t* out) {
    check_within(off, n, what);
    in.seekg(static_cast<std::streamoff>(off));
    if (n && !in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n))) fail("cannot read " + what);
  }
  std::vector<std::uint8_t> read(std::uint64_t off, std::uint64_t n, const std::string& what) {
    check_within(off, n, what);  // before allocating n bytes
    std::vector<std::uint8_t> b(n);
    read(off, n, what, b.data());
    return b;
  }

  /// The first image file directory, tag -> entry.
  std::map<std::uint16_t, Entry> directory() {
    const std::vector<std::uint8_t> h8 = read(0, 8, "the TIFF header");
    if (h8[0] == 'M' && h8[1] == 'M') fail("a big-endian (\"MM\") TIFF; only little-endian (\"II\") files are read");
    if (h8[0] != 'I' || h8[1] != 'I') fail("not a TIFF file (it does not start with \"II\" or \"MM\")");
    const std::uint64_t magic = le(h8.data() + 2, 2);
    bool big = false;
    if (magic == 43) {
      big = true;
      if (le(h8.data() + 4, 2) != 8 || le(h8.data() + 6, 2) != 0) fail("a BigTIFF header with an offset size other than 8");
    } else if (magic != 42) {
      fail("not a TIFF file (version " + std::to_string(magic) + ", not 42 or 43)");
    }
    const int field = big ? 8 : 4, count_bytes = big ? 8 : 2, entry_bytes = big ? 20 : 12;
    const std::uint64_t ifd = le(read(big ? 8 : 4, static_cast<std::uint64_t>(field), "the first directory's offset").data(), field);
    const std::uint64_t n = le(read(ifd, static_cast<std::uint64_t>(count_bytes), "the first directory").data(), count_bytes);
    if (n > size / static_cast<std::uint64_t>(entry_bytes)) fail("the first directory lies beyond the end of the file");
    const std::vector<std::uint8_t> entries = read(ifd + count_bytes, n * entry_bytes, "the first directory");
    std::map<std::uint16_t, Entry> dir;
    for (std::uint64_t k = 0; k < n; ++k) {
      const std::uint8_t* e = entries.data() + k * entry_bytes;
      Entry en;
      const auto tag = static_cast<std::uint16_t>(le(e, 2));
      en.type = static_cast<std::uint16_t>(le(e + 2, 2));
      en.count = le(e + 4, field);
      if (en.count > size) fail("tag " + std::to_string(tag) + " counts more values than the file has bytes");
      const std::uint64_t bytes = en.count * static_cast<std::uint64_t>(tiff_type_bytes(en.type));
      const std::uint8_t* field_at = e + 4 + field;
      if (bytes <= static_cast<std::uint64_t>(field))
        en.value.assign(field_at, field_at + bytes);
      else
        en.value = read(le(field_at, field), bytes, "the values of tag " + std::to_string(tag));
      dir[tag] = std::move(en);
    }
    return dir;
  }

  /// The integers of an entry (SHORT, LONG or LONG8).
  std::vector<std::uint64_t> ints(std::uint16_t tag, const Entry& e) const {
    if (e.type != kTiffShort && e.type != kTiffLong && e.type != kTiffLong8)
      fail("tag " + std::to_string(tag) + " has field type " + std::to_string(e.type) + ", not an integer type");
    const int unit = tiff_type_bytes(e.type);
    std::vector<std::uint64_t> v(e.count);
    for (std::uint64_t i = 0; i < e.count; ++i) v[i] = le(e.value.data() + i * unit, unit);
    return v;
  }

  void open() {
    require_regular_file(path, "GeoTIFF");
    in.open(path, std::ios::binary | std::ios::ate);
    if (!in) throw InputError(path + ": cannot open");
    const std::streamoff end = in.tellg();
    if (end < 0) throw InputError(path + ": cannot read");
    size = static_cast<std::uint64_t>(end);
    const auto dir = directory();

    const auto values = [&](std::uint16_t tag) -> std::vector<std::uint64_t> {
      const auto it = dir.find(tag);
      if (it == dir.end()) return {};
      return ints(tag, it->second);
    };
    const auto one = [&](std::uint16_t tag, std::uint64_t fallback, bool required) {
      const std::vector<std::uint64_t> v = values(tag);
      if (v.empty()) {
        if (required) fail(std::string("tag ") + std::to_string(tag) + " (" + tag_name(tag) + ") is missing");
        return fallback;
      }
      return v[0];
    };
    const auto all_equal = [&](std::uint16_t tag, std::uint64_t want, const std::string& rule) {
      for (std::uint64_t v : values(tag))
        if (v != want)
          fail(std::string("tag ") + std::to_string(tag) + " (" + tag_name(tag) + ") = " + std::to_string(v) + ": " + rule);
    };
    tiled = dir.count(322) || dir.count(323) || dir.count(324) || dir.count(325);
    w = one(256, 0, true);
    h = one(257, 0, true);
    spp = one(277, 1, false);
    if (w < 1 || h < 1 || spp < 1 || w > std::numeric_limits<int>::max() || h > std::numeric_limits<int>::max() ||
        spp > 65535)
      fail("a raster of " + std::to_string(w) + " x " + std::to_string(h) + " x " + std::to_string(spp) +
           " samples; each must be at least 1 (and fit an int)");
    if (values(258).empty()) fail("tag 258 (BitsPerSample) is missing");
    all_equal(258, 32, "only 32-bit samples are read");
    if (values(339).empty()) fail("tag 339 (SampleFormat) is missing: only IEEE float (3) samples are read");
    all_equal(339, 3, "only IEEE float (3) samples are read");
    compression = one(259, 1, false);
    if (compression != 1 && compression != 8 && compression != 32946)
      fail("tag 259 (Compression) = " + std::to_string(compression) + ": only none (1) and DEFLATE (8, 32946) are read");
    const std::uint64_t predictor = one(317, 1, false);
    if (predictor != 1) fail("tag 317 (Predictor) = " + std::to_string(predictor) + ": only no predictor (1) is read");
    planar = one(284, 1, false);
    if (planar != 1 && planar != 2) fail("tag 284 (PlanarConfiguration) = " + std::to_string(planar) + ": must be 1 or 2");
    const std::uint64_t per_pixel = planar == 2 ? 1 : spp;  // samples of a pixel in one block
    if (tiled) {
      bw = one(322, 0, true);
      rps = one(323, 0, true);
      if (bw < 1 || rps < 1)
        fail("tags 322 and 323 (TileWidth, TileLength) = " + std::to_string(bw) + " x " + std::to_string(rps) +
             ": each must be at least 1");
      // A tile is stored whole, padding included: it cannot outgrow what the file can hold
      // (DEFLATE expands at most 1032 to 1). Checked before a tile's buffer is allocated.
      const std::uint64_t limit = size * 1032 + 4096;
      if (bw > limit / rps / per_pixel / 4)
        fail("tiles of " + std::to_string(bw) + " x " + std::to_string(rps) + " x " + std::to_string(per_pixel) +
             " floats are larger than the file's " + std::to_string(size) + " bytes can hold");
      across = (w + bw - 1) / bw;
    } else {
      bw = w;
      rps = std::min(one(278, h, false), h);
      if (rps < 1) fail("tag 278 (RowsPerStrip) = 0");
    }

    strips_down = (h + rps - 1) / rps;
    const std::uint64_t blocks = strips_down * across * (planar == 2 ? spp : 1);
    offsets = values(tiled ? 324 : 273);
    counts = values(tiled ? 325 : 279);
    if (offsets.size() != blocks || counts.size() != blocks) {
      const std::string tags =
          tiled ? "tags 324 and 325 (TileOffsets, TileByteCounts)" : "tags 273 and 279 (StripOffsets, StripByteCounts)";
      fail(tags + " hold " + std::to_string(offsets.size()) + " and " + std::to_string(counts.size()) +
           (tiled ? " tiles" : " strips") + "; the raster has " + std::to_string(blocks));
    }

    info.width = static_cast<int>(w);
    info.height = static_cast<int>(h);
    info.bands = static_cast<int>(spp);
    const auto doubles = [&](std::uint16_t tag, double* out, std::uint64_t k) {
      const auto it = dir.find(tag);
      if (it == dir.end()) return false;
      if (it->second.type != kTiffDouble || it->second.count < k)
        fail("tag " + std::to_string(tag) + " must hold at least " + std::to_string(k) + " doubles");
      for (std::uint64_t i = 0; i < k; ++i) {
        const std::uint64_t u = le(it->second.value.data() + 8 * i, 8);
        std::memcpy(&out[i], &u, sizeof u);
      }
      return true;
    };
    const bool scale = doubles(33550, info.pixel_scale, 3), tie = doubles(33922, info.tiepoint, 6);
    info.georeferenced = scale && tie;
    const auto md = dir.find(42112);
    if (md != dir.end()) {
      if (md->second.type != kTiffAscii) fail("tag 42112 (GDAL_METADATA) is not ASCII");
      const char* c = reinterpret_cast<const char*>(md->second.value.data());
      info.gdal_metadata.assign(c, std::find(c, c + md->second.value.size(), '\0'));
    }
  }

  std::string block_name(std::uint64_t s) const { return (tiled ? "tile " : "strip ") + std::to_string(s); }

  /// Opens block `s`, of which `rows` rows of bw pixels and `per_pixel` samples a pixel will be
  /// read. Checked before anything is allocated: the block lies in the file, and its bytes can
  /// hold those rows (DEFLATE expands at most 1032 to 1; uncompressed, they are the bytes). A
  /// block with offset and byte count 0 is not stored (a sparse file): nodata.
  void open_block(std::uint64_t s, std::uint64_t rows, std::uint64_t per_pixel, BlockStream& b) {
    b.sparse = offsets[s] == 0 && counts[s] == 0;
    if (b.sparse) return;
    const std::string what = block_name(s);
    check_within(offsets[s], counts[s], what);
    const std::uint64_t need = rows * bw * per_pixel * 4;  // < 2^62: each factor is checked
    if (compression == 1 ? counts[s] < need : need > counts[s] * 1032 + 1024)
      fail(what + " holds " + std::to_string(counts[s]) + " bytes, too few for " + std::to_string(rows) + " rows of " +
           std::to_string(bw) + " x " + std::to_string(per_pixel) + " floats");
    b.off = offsets[s];
    b.left = counts[s];
    b.deflate = compression != 1;
    if (b.deflate) {
      if (inflateInit(&b.z) != Z_OK) throw std::runtime_error(path + ": cannot set up DEFLATE");
      b.open = true;
    }
  }

  /// The next row of an open block, n floats, into `out` (grown as the data arrives).
  void read_row(BlockStream& b, std::uint64_t n, std::vector<float>& out, std::uint64_t s) {
    out.clear();
    if (b.sparse) {
      out.assign(n, std::numeric_limits<float>::quiet_NaN());
      return;
    }
    std::uint64_t got = 0;  // floats
    while (got < n) {
      const std::uint64_t want = std::min(n, got + kChunkFloats);
      out.resize(want);
      if (!b.deflate) {
        read(b.off, (want - got) * 4, block_name(s), reinterpret_cast<std::uint8_t*>(out.data() + got));
        b.off += (want - got) * 4;
        got = want;
        continue;
      }
      b.z.next_out = reinterpret_cast<Bytef*>(out.data()) + got * 4;
      b.z.avail_out = static_cast<uInt>((want - got) * 4);
      while (b.z.avail_out > 0) {
        if (b.z.avail_in == 0) {
          if (b.left == 0) fail(block_name(s) + " is not a whole DEFLATE (zlib) stream of its rows");
          const std::uint64_t k = std::min(b.left, kInBytes);
          b.in.resize(k);
          read(b.off, k, block_name(s), b.in.data());
          b.off += k;
          b.left -= k;
          b.z.next_in = b.in.data();
          b.z.avail_in = static_cast<uInt>(k);
        }
        // Damage past the rows wanted (inflate may read ahead) surfaces with the rows after them.
        const int r = inflate(&b.z, Z_NO_FLUSH);
        if (r != Z_OK && b.z.avail_out > 0) fail(block_name(s) + " is not a whole DEFLATE (zlib) stream of its rows");
      }
      got = want;
    }
  }

  /// f(piece) for each row of the blocks in row `down` of blocks, block after block (left to
  /// right), every band's samples of the row's part in that block. Blocks of which no plane is
  /// stored are skipped when `skip_sparse`.
  template <typename F>
  void block_row(std::uint64_t down, bool skip_sparse, FloatTiffPiece& piece, F&& f) {
    const std::uint64_t n = std::min(rps, h - down * rps);
    const std::uint64_t per_pixel = planar == 2 ? 1 : spp;
    const std::uint64_t planes = planar == 2 ? spp : 1, per_plane = strips_down * across;
    piece.bands.resize(spp);
    for (std::uint64_t j = 0; j < across; ++j) {
      std::vector<BlockStream> streams(planes);
      bool any = false;
      for (std::uint64_t p = 0; p < planes; ++p) {
        const std::uint64_t s = p * per_plane + down * across + j;
        open_block(s, n, per_pixel, streams[p]);
        any = any || !streams[p].sparse;
      }
      if (!any && skip_sparse) continue;
      const std::uint64_t x0 = j * bw, cols = std::min(bw, w - x0);
      piece.col0 = static_cast<int>(x0);
      piece.cols = static_cast<int>(cols);
      for (std::uint64_t r = 0; r < n; ++r) {
        if (planar == 2) {
          for (std::uint64_t p = 0; p < planes; ++p) {
            read_row(streams[p], bw, piece.bands[p], p * per_plane + down * across + j);
            piece.bands[p].resize(cols);
          }
        } else {
          read_row(streams[0], bw * spp, this->row, down * across + j);
          for (std::uint64_t b = 0; b < spp; ++b) {
            piece.bands[b].resize(cols);
            for (std::uint64_t c = 0; c < cols; ++c) piece.bands[b][c] = this->row[c * spp + b];
          }
        }
        piece.row = static_cast<int>(down * rps + r);
        f(static_cast<const FloatTiffPiece&>(piece));
      }
    }
  }
};

FloatTiffRows::FloatTiffRows(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->open();
}
FloatTiffRows::~FloatTiffRows() = default;
const FloatTiffInfo& FloatTiffRows::info() const { return impl_->info; }

bool FloatTiffRows::next(int& first, int& count, std::vector<std::vector<float>>& rows) {
  Impl& m = *impl_;
  if (m.next_down >= m.strips_down) return false;
  const std::uint64_t down = m.next_down++;
  const std::uint64_t n = std::min(m.rps, m.h - down * m.rps);
  first = static_cast<int>(down * m.rps);
  count = static_cast<int>(n);
  // The rows' memory, in steps as the blocks' rows arrive: a block not stored costs nothing
  // to read but its nodata here.
  rows.resize(m.spp);
  for (auto& r : rows) r.clear();
  FloatTiffPiece piece;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  m.block_row(down, true, piece, [&](const FloatTiffPiece& p) {
    for (std::uint64_t b = 0; b < m.spp; ++b) {
      const std::size_t at = static_cast<std::size_t>(p.row - first) * m.w + static_cast<std::size_t>(p.col0);
      if (rows[b].size() < at + static_cast<std::size_t>(p.cols)) rows[b].resize(at + static_cast<std::size_t>(p.cols), nan);
      std::memcpy(rows[b].data() + at, p.bands[b].data(), static_cast<std::size_t>(p.cols) * sizeof(float));
    }
  });
  for (auto& r : rows) r.resize(n * m.w, nan);
  return true;
}

void FloatTiffRows::for_each_piece(const std::function<void(const FloatTiffPiece&)>& f) {
  Impl& m = *impl_;
  FloatTiffPiece piece;
  for (; m.next_down < m.strips_down; ++m.next_down) m.block_row(m.next_down, true, piece, f);
}

FloatTiffData read_float_tiff(const std::string& path) {
  FloatTiffRows tiff(path);
  FloatTiffData t;
  static_cast<FloatTiffInfo&>(t) = tiff.info();
  const std::size_t w = static_cast<std::size_t>(t.width);
  t.planes.resize(static_cast<std::size_t>(t.bands));
  std::vector<std::vector<float>> rows;
  int first = 0, count = 0;
  // Grown a row of blocks at a time, as the rows arrive.
  while (tiff.next(first, count, rows))
    for (std::size_t b = 0; b < rows.size(); ++b) t.planes[b].insert(t.planes[b].end(), rows[b].begin(), rows[b].end());
  (void)w;
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
