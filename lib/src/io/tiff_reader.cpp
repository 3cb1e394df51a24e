#include "tiff_reader.hpp"

#include <geotiff/geokeys.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>

#include <algorithm>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <stdexcept>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "tiff_format.hpp"
#include "xml_escape.hpp"

namespace pcdp::io::detail {

namespace {
/// libgeotiff's messages (a damaged GeoKey directory): kept with libtiff's, not printed.
void geotiff_error(GTIF* g, int level, const char* fmt, ...) {
  if (level != LIBGEOTIFF_ERROR) return;
  auto* m = static_cast<TiffMessages*>(GTIFGetUserData(g));
  if (!m || !m->error.empty()) return;
  char buf[512];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  m->error = buf;
}

/// One libtiff handle and its messages (which libtiff's handlers write to: not moved).
struct Handle {
  TiffMessages msgs;
  TiffPtr tif;
};
}  // namespace

struct FloatTiffRows::Impl {
  std::string path;
  std::uint64_t size = 0;  ///< of the file, bytes
  FloatTiffInfo info;
  // The raster is stored in blocks: strips (the raster's width, rps rows) or tiles (bw x rps,
  // `across` of them side by side, padded at the right and bottom edges). A strip is one block
  // across; `strips_down` counts the rows of blocks.
  std::uint64_t w = 0, h = 0, spp = 0, rps = 0, planar = 1, compression = 1, strips_down = 0;
  std::uint64_t bw = 0, across = 1;
  bool tiled = false;
  /// handles[0] reads the directory, the tiles and the strips of sample 0; a band-interleaved
  /// stripped file gets a handle per sample, each reading its strips a row at a time in order.
  std::vector<std::unique_ptr<Handle>> handles;
  std::uint64_t next_down = 0;  ///< the next row of blocks
  std::vector<float> row;       ///< one row of a pixel-interleaved block
  std::vector<std::vector<float>> tile;  ///< one tile of each plane

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path + ": " + what); }
  /// `what`, with libtiff's own words for it when it gave some.
  [[noreturn]] void fail_lib(const Handle& hd, const std::string& what) const {
    fail(what + (hd.msgs.error.empty() ? std::string() : " (libtiff: " + hd.msgs.error + ")"));
  }

  std::unique_ptr<Handle> open_handle() {
    auto hd = std::make_unique<Handle>();
    hd->tif = open_tiff(path, "r", hd->msgs);
    if (!hd->tif) fail("not a TIFF file libtiff can read (" + hd->msgs.error + ")");
    return hd;
  }

  void open() {
    require_regular_file(path, "GeoTIFF");
    {
      std::ifstream in(path, std::ios::binary);
      if (!in) throw InputError(path + ": cannot open");
      char magic[4] = {};
      in.read(magic, 4);
      const bool ii = magic[0] == 'I' && magic[1] == 'I' && (magic[2] == 42 || magic[2] == 43) && magic[3] == 0;
      const bool mm = magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 && (magic[3] == 42 || magic[3] == 43);
      if (!in || (!ii && !mm)) fail("not a TIFF file (it starts with neither \"II*\" nor \"MM*\", classic or BigTIFF)");
      std::error_code ec;
      size = std::filesystem::file_size(path, ec);
      if (ec) throw InputError(path + ": cannot read (" + ec.message() + ")");
    }
    handles.push_back(open_handle());
    Handle& hd = *handles[0];
    TIFF* t = hd.tif.get();
    // libtiff reads past some damage with a warning (a tag's values beyond the end of the file,
    // a wrong count: "tag ignored"); a grid read that way would not be the grid written. Its
    // other warnings (a nonstandard tile size, ExtraSamples missing) are about files it reads
    // as written.
    const std::string& warn = hd.msgs.warning;
    if (warn.find("ignored") != std::string::npos || warn.find("IO error") != std::string::npos ||
        warn.find("ncorrect") != std::string::npos)
      fail("its directory is damaged (libtiff: " + warn + ")");
    std::uint32_t w32 = 0, h32 = 0;
    if (!TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w32)) fail("tag 256 (ImageWidth) is missing");
    if (!TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h32)) fail("tag 257 (ImageLength) is missing");
    std::uint16_t spp16 = 1, bps = 0, format = 0, comp = 1, pred = 1, pc = 1;
    TIFFGetField(t, TIFFTAG_SAMPLESPERPIXEL, &spp16);
    w = w32;
    h = h32;
    spp = spp16;
    if (w < 1 || h < 1 || spp < 1 || w > std::numeric_limits<int>::max() || h > std::numeric_limits<int>::max())
      fail("a raster of " + std::to_string(w) + " x " + std::to_string(h) + " x " + std::to_string(spp) +
           " samples; each must be at least 1 (and fit an int)");
    if (!TIFFGetField(t, TIFFTAG_BITSPERSAMPLE, &bps)) fail("tag 258 (BitsPerSample) is missing");
    if (bps != 32) fail("tag 258 (BitsPerSample) = " + std::to_string(bps) + ": only 32-bit samples are read");
    if (!TIFFGetField(t, TIFFTAG_SAMPLEFORMAT, &format))
      fail("tag 339 (SampleFormat) is missing: only IEEE float (3) samples are read");
    if (format != SAMPLEFORMAT_IEEEFP)
      fail("tag 339 (SampleFormat) = " + std::to_string(format) + ": only IEEE float (3) samples are read");
    TIFFGetField(t, TIFFTAG_COMPRESSION, &comp);
    compression = comp;
    if (comp != COMPRESSION_NONE && comp != COMPRESSION_ADOBE_DEFLATE && comp != COMPRESSION_DEFLATE)
      fail("tag 259 (Compression) = " + std::to_string(comp) + ": only none (1) and DEFLATE (8, 32946) are read");
    TIFFGetField(t, TIFFTAG_PREDICTOR, &pred);
    if (pred != PREDICTOR_NONE) fail("tag 317 (Predictor) = " + std::to_string(pred) + ": only no predictor (1) is read");
    TIFFGetField(t, TIFFTAG_PLANARCONFIG, &pc);
    planar = pc;
    if (planar != 1 && planar != 2) fail("tag 284 (PlanarConfiguration) = " + std::to_string(planar) + ": must be 1 or 2");
    const std::uint64_t per_pixel = planar == 2 ? 1 : spp;  // samples of a pixel in one block
    tiled = TIFFIsTiled(t) != 0;
    if (tiled) {
      std::uint32_t tw = 0, tl = 0;
      TIFFGetField(t, TIFFTAG_TILEWIDTH, &tw);
      TIFFGetField(t, TIFFTAG_TILELENGTH, &tl);
      bw = tw;
      rps = tl;
      if (bw < 1 || rps < 1)
        fail("tags 322 and 323 (TileWidth, TileLength) = " + std::to_string(bw) + " x " + std::to_string(rps) +
             ": each must be at least 1");
      // A tile is decoded whole, padding included: it cannot outgrow what the file can hold
      // (DEFLATE expands at most 1032 to 1). Checked before a tile's buffer is allocated.
      const std::uint64_t limit = size * 1032 + 4096;
      if (bw > limit / rps / per_pixel / 4)
        fail("tiles of " + std::to_string(bw) + " x " + std::to_string(rps) + " x " + std::to_string(per_pixel) +
             " floats are larger than the file's " + std::to_string(size) + " bytes can hold");
      across = (w + bw - 1) / bw;
    } else {
      std::uint32_t r = 0;
      bw = w;
      rps = TIFFGetField(t, TIFFTAG_ROWSPERSTRIP, &r) ? std::min<std::uint64_t>(r, h) : h;
      if (rps < 1) fail("tag 278 (RowsPerStrip) = 0");
    }
    strips_down = (h + rps - 1) / rps;
    const std::uint64_t blocks = strips_down * across * (planar == 2 ? spp : 1);
    const std::uint64_t have = tiled ? TIFFNumberOfTiles(t) : TIFFNumberOfStrips(t);
    const auto [offsets, counts] = offset_counts(tiled ? 324 : 273, tiled ? 325 : 279);
    if (have != blocks || offsets != blocks || counts != blocks) {
      const std::string tags =
          tiled ? "tags 324 and 325 (TileOffsets, TileByteCounts)" : "tags 273 and 279 (StripOffsets, StripByteCounts)";
      fail(tags + " hold " + std::to_string(offsets) + " and " + std::to_string(counts) + (tiled ? " tiles" : " strips") +
           "; the raster has " + std::to_string(blocks));
    }
    for (std::uint64_t s = 0; s < blocks; ++s) {
      int err = 0;
      const std::uint64_t off = TIFFGetStrileOffsetWithErr(t, static_cast<std::uint32_t>(s), &err);
      const std::uint64_t n = err ? 0 : TIFFGetStrileByteCountWithErr(t, static_cast<std::uint32_t>(s), &err);
      if (err) fail_lib(hd, "the offset or byte count of " + block_name(s) + " cannot be read");
      if (off > size || n > size - off)
        fail(block_name(s) + " lies beyond the end of the file (" + std::to_string(size) + " bytes)");
    }

    info.width = static_cast<int>(w);
    info.height = static_cast<int>(h);
    info.bands = static_cast<int>(spp);
    const auto doubles = [&](ttag_t tag, double* out, std::uint16_t k) {
      std::uint16_t count = 0;
      double* v = nullptr;
      if (!TIFFGetField(t, tag, &count, &v)) return false;
      if (!v || count < k) fail("tag " + std::to_string(tag) + " must hold at least " + std::to_string(k) + " doubles");
      std::copy(v, v + k, out);
      return true;
    };
    const bool scale = doubles(TIFFTAG_GEOPIXELSCALE, info.pixel_scale, 3), tie = doubles(TIFFTAG_GEOTIEPOINTS, info.tiepoint, 6);
    info.georeferenced = scale && tie;
    char* md = nullptr;
    if (TIFFGetField(t, kTagGdalMetadata, &md) && md) info.gdal_metadata = md;
    read_geokeys(hd);
  }

  /// The value counts of two tags in the directory as stored (libtiff pads a short offsets array
  /// with zeros, which would read as blocks not stored): the entries of the directory libtiff
  /// read, at its offset, read here. 0: the tag is absent.
  std::pair<std::uint64_t, std::uint64_t> offset_counts(std::uint16_t a, std::uint16_t b) {
    TIFF* t = handles[0]->tif.get();
    const bool big = TIFFIsBigTIFF(t) != 0, swap = TIFFIsByteSwapped(t) != 0;
    const std::uint64_t at = TIFFCurrentDirOffset(t);
    const int count_bytes = big ? 8 : 2, entry = big ? 20 : 12, field = big ? 8 : 4;
    std::ifstream in(path, std::ios::binary);
    const auto le = [&](const unsigned char* p, int n) {
      std::uint64_t v = 0;
      for (int i = 0; i < n; ++i) v |= std::uint64_t{p[swap ? n - 1 - i : i]} << (8 * i);
      return v;
    };
    unsigned char buf[20];
    if (at > size || size - at < static_cast<std::uint64_t>(count_bytes)) fail("its directory lies beyond the end of the file");
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(reinterpret_cast<char*>(buf), count_bytes)) fail("cannot read its directory");
    const std::uint64_t n = le(buf, count_bytes);
    if (n > (size - at) / static_cast<std::uint64_t>(entry)) fail("its directory lies beyond the end of the file");
    std::uint64_t ca = 0, cb = 0;
    for (std::uint64_t k = 0; k < n; ++k) {
      if (!in.read(reinterpret_cast<char*>(buf), entry)) fail("cannot read its directory");
      const std::uint64_t tag = le(buf, 2);
      if (tag == a) ca = le(buf + 4, field);
      if (tag == b) cb = le(buf + 4, field);
    }
    return {ca, cb};
  }

  void read_geokeys(Handle& hd) {
    hd.msgs.error.clear();
    GTIF* g = GTIFNewEx(hd.tif.get(), geotiff_error, &hd.msgs);
    if (!g) fail_lib(hd, "its GeoKey directory (tag 34735) cannot be read");
    std::unique_ptr<GTIF, void (*)(GTIF*)> guard(g, GTIFFree);
    if (!hd.msgs.error.empty()) fail("its GeoKey directory (tag 34735) is damaged (libgeotiff: " + hd.msgs.error + ")");
    GeoKeys& k = info.geokeys;
    unsigned short v = 0;
    if (GTIFKeyGetSHORT(g, GTModelTypeGeoKey, &v, 0, 1) == 1) k.model = v;
    if (GTIFKeyGetSHORT(g, ProjectedCSTypeGeoKey, &v, 0, 1) == 1 && k.model == ModelTypeProjected) k.epsg = v;
    if (GTIFKeyGetSHORT(g, GeographicTypeGeoKey, &v, 0, 1) == 1 && k.model == ModelTypeGeographic) k.epsg = v;
    if (k.epsg == KvUserDefined) k.epsg = 0;
    char cit[4096] = {};
    if (GTIFKeyGetASCII(g, GTCitationGeoKey, cit, sizeof cit) > 0) k.citation = cit;
  }

  std::string block_name(std::uint64_t s) const { return (tiled ? "tile " : "strip ") + std::to_string(s); }

  bool sparse(std::uint64_t s) const {
    TIFF* t = handles[0]->tif.get();
    return TIFFGetStrileOffset(t, static_cast<std::uint32_t>(s)) == 0 &&
           TIFFGetStrileByteCount(t, static_cast<std::uint32_t>(s)) == 0;
  }

  /// Checked before block `s` is decoded (its `rows` rows of bw pixels and `per_pixel` samples a
  /// pixel): its bytes can hold those rows (DEFLATE expands at most 1032 to 1; uncompressed,
  /// they are the bytes).
  void check_block(std::uint64_t s, std::uint64_t rows, std::uint64_t per_pixel) const {
    const std::uint64_t count = TIFFGetStrileByteCount(handles[0]->tif.get(), static_cast<std::uint32_t>(s));
    const std::uint64_t need = rows * bw * per_pixel * 4;  // < 2^62: each factor is checked
    if (compression == 1 ? count < need : need > count * 1032 + 1024)
      fail(block_name(s) + " holds " + std::to_string(count) + " bytes, too few for " + std::to_string(rows) +
           " rows of " + std::to_string(bw) + " x " + std::to_string(per_pixel) + " floats");
  }

  /// f(piece) for each row of the blocks in row `down` of blocks, block after block (left to
  /// right), every band's samples of the row's part in that block. Blocks of which no plane is
  /// stored are skipped when `skip_sparse`; a plane not stored reads as NaN.
  template <typename F>
  void block_row(std::uint64_t down, bool skip_sparse, FloatTiffPiece& piece, F&& f) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const std::uint64_t n = std::min(rps, h - down * rps);
    const std::uint64_t per_pixel = planar == 2 ? 1 : spp;
    const std::uint64_t planes = planar == 2 ? spp : 1, per_plane = strips_down * across;
    piece.bands.resize(spp);
    if (!tiled && planar == 2)
      while (handles.size() < spp) handles.push_back(open_handle());  // a handle per plane, reading in order
    for (std::uint64_t j = 0; j < across; ++j) {
      std::vector<char> stored(planes);
      bool any = false;
      for (std::uint64_t p = 0; p < planes; ++p) {
        const std::uint64_t s = p * per_plane + down * across + j;
        stored[p] = !sparse(s);
        if (stored[p]) check_block(s, tiled ? rps : n, per_pixel);
        any = any || stored[p];
      }
      if (!any && skip_sparse) continue;
      const std::uint64_t x0 = j * bw, cols = std::min(bw, w - x0);
      piece.col0 = static_cast<int>(x0);
      piece.cols = static_cast<int>(cols);
      if (tiled) {  // each plane's tile decoded whole (its size checked against the file's above)
        tile.resize(planes);
        for (std::uint64_t p = 0; p < planes; ++p) {
          const std::uint64_t s = p * per_plane + down * across + j;
          tile[p].assign(stored[p] ? bw * rps * per_pixel : 0, 0.0f);
          if (!stored[p]) continue;
          const auto bytes = static_cast<tmsize_t>(tile[p].size() * sizeof(float));
          if (TIFFReadEncodedTile(handles[0]->tif.get(), static_cast<std::uint32_t>(s), tile[p].data(), bytes) != bytes)
            fail_lib(*handles[0], block_name(s) + " cannot be decoded");
        }
      }
      for (std::uint64_t r = 0; r < n; ++r) {
        const std::uint64_t y = down * rps + r;
        if (planar == 2) {
          for (std::uint64_t p = 0; p < planes; ++p) {
            std::vector<float>& out = piece.bands[p];
            const std::uint64_t s = p * per_plane + down * across + j;
            if (!stored[p]) {
              out.assign(cols, nan);
            } else if (tiled) {
              out.assign(tile[p].begin() + static_cast<std::ptrdiff_t>(r * bw), tile[p].begin() + static_cast<std::ptrdiff_t>(r * bw + cols));
            } else {
              out.resize(w);
              Handle& hd = *handles[p];
              if (TIFFReadScanline(hd.tif.get(), out.data(), static_cast<std::uint32_t>(y), static_cast<std::uint16_t>(p)) < 0)
                fail_lib(hd, block_name(s) + " cannot be decoded (row " + std::to_string(y) + ")");
            }
          }
        } else {
          const std::uint64_t s = down * across + j;
          if (!stored[0]) {
            for (std::uint64_t b = 0; b < spp; ++b) piece.bands[b].assign(cols, nan);
          } else {
            const float* src = nullptr;
            if (tiled) {
              src = tile[0].data() + r * bw * spp;
            } else {
              row.resize(w * spp);
              if (TIFFReadScanline(handles[0]->tif.get(), row.data(), static_cast<std::uint32_t>(y), 0) < 0)
                fail_lib(*handles[0], block_name(s) + " cannot be decoded (row " + std::to_string(y) + ")");
              src = row.data();
            }
            for (std::uint64_t b = 0; b < spp; ++b) {
              piece.bands[b].resize(cols);
              for (std::uint64_t c = 0; c < cols; ++c) piece.bands[b][c] = src[c * spp + b];
            }
          }
        }
        piece.row = static_cast<int>(y);
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
