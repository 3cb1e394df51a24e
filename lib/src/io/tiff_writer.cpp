#include "tiff_writer.hpp"

#include <libdeflate.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include <geotiff/geokeys.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>

#include "pcdp/core/errors.hpp"
#include "tiff_format.hpp"
#include "xml_escape.hpp"

namespace pcdp::io::detail {

namespace {
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
/// vector is a block not stored (sparse). `raw`: copies them, for libtiff's codec to compress.
class Compressor {
 public:
  Compressor(const std::string& path, int level, bool raw)
      : path_(path), raw_(raw), c_(libdeflate_alloc_compressor(level)) {
    if (!c_ || level > 12) throw std::runtime_error(path + ": cannot set up DEFLATE at level " + std::to_string(level));
  }
  void operator()(const float* data, std::size_t n, std::vector<std::uint8_t>& z) {
    const std::size_t in = n * sizeof(float);
    if (raw_) {
      z.resize(in);
      std::memcpy(z.data(), data, in);
      return;
    }
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
  bool raw_;
  std::unique_ptr<libdeflate_compressor, CompressorFree> c_;
};

void write_file(const std::string& path, const FloatTiff& t, const Layout& L, int level,
                const std::vector<std::vector<std::uint8_t>>& out);
}  // namespace

void write_float_tiff(const std::string& path, const FloatTiff& t, int level, const PlaneFill& fill,
                      const RunTasks& share) {
  if (t.tile != 0) throw std::invalid_argument(path + ": whole planes are written as strips; tiles take a BlockFill");
  const Layout L(path, t);
  // Compressed strips, band after band (PlanarConfiguration 2 orders them so).
  std::vector<std::vector<std::uint8_t>> out(L.nb * L.blocks);
  share(L.first.size() - 1, [&](std::size_t g) {
    Compressor compress(path, level, t.libtiff_codec);
    std::vector<std::vector<float>> planes(static_cast<std::size_t>(L.first[g + 1] - L.first[g]), std::vector<float>(L.w * L.h));
    fill(L.first[g], planes);
    for (std::size_t j = 0; j < planes.size(); ++j) {
      const std::size_t b = static_cast<std::size_t>(L.first[g]) + j;
      for (std::size_t s = 0; s < L.blocks; ++s)
        compress(planes[j].data() + s * L.bh * L.w, L.rows(s) * L.w, out[b * L.blocks + s]);
    }
  });
  write_file(path, t, L, level, out);
}

void write_float_tiff_blocks(const std::string& path, const FloatTiff& t, int level, const BlockFill& fill,
                             const RunTasks& share) {
  const Layout L(path, t);
  std::vector<std::vector<std::uint8_t>> out(L.nb * L.blocks);
  share(L.first.size() - 1, [&](std::size_t g) {
    Compressor compress(path, level, t.libtiff_codec);
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
  write_file(path, t, L, level, out);
}
namespace {
/// The first error libtiff or libgeotiff reported, or `what`.
[[noreturn]] void fail_write(const std::string& path, const TiffMessages& m, const std::string& what) {
  std::remove(path.c_str());
  throw OutputError(path + ": cannot write the GeoTIFF (" + (m.error.empty() ? what : m.error) + ")");
}

void write_geokeys(TIFF* tif, const std::string& path, const GeoKeys& k, TiffMessages& m) {
  if (k.model == 0) return;
  GTIF* g = GTIFNew(tif);
  if (!g) fail_write(path, m, "libgeotiff cannot set up its keys");
  GTIFKeySet(g, GTModelTypeGeoKey, TYPE_SHORT, 1, k.model);
  GTIFKeySet(g, GTRasterTypeGeoKey, TYPE_SHORT, 1, RasterPixelIsArea);
  if (!k.citation.empty()) GTIFKeySet(g, GTCitationGeoKey, TYPE_ASCII, 0, k.citation.c_str());
  if (k.model == ModelTypeProjected && k.epsg > 0) GTIFKeySet(g, ProjectedCSTypeGeoKey, TYPE_SHORT, 1, k.epsg);
  if (k.model == ModelTypeGeographic && k.epsg > 0) GTIFKeySet(g, GeographicTypeGeoKey, TYPE_SHORT, 1, k.epsg);
  const int ok = GTIFWriteKeys(g);
  GTIFFree(g);
  if (!ok) fail_write(path, m, "libgeotiff cannot write its keys");
}

void write_file(const std::string& path, const FloatTiff& t, const Layout& L, int level,
                const std::vector<std::vector<std::uint8_t>>& out) {
  std::uint64_t data_bytes = 0;
  for (const auto& z : out) data_bytes += z.size();
  // Past 4 GiB of offsets a classic TIFF cannot point: BigTIFF then (GDAL's BIGTIFF=IF_NEEDED).
  const bool big = t.bigtiff || data_bytes + (std::uint64_t{1} << 24) > std::numeric_limits<std::uint32_t>::max();
  TiffMessages m;
  TiffPtr tp = open_tiff(path, big ? "w8" : "w", m);
  if (!tp) {
    std::remove(path.c_str());
    throw OutputError(path + ": cannot create (" + m.error + ")");
  }
  TIFF* tif = tp.get();
  const auto nb = static_cast<std::uint16_t>(L.nb);
  bool ok = TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(L.w)) &&
            TIFFSetField(tif, TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(L.h)) &&
            TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 32) && TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, nb) &&
            TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP) &&
            TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE) &&
            TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK) &&
            TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_SEPARATE);
  if (ok && t.libtiff_codec) ok = TIFFSetField(tif, TIFFTAG_ZIPQUALITY, level);
  if (ok && L.nb > 1) {
    const std::vector<std::uint16_t> extra(L.nb - 1, EXTRASAMPLE_UNSPECIFIED);
    ok = TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, static_cast<std::uint16_t>(extra.size()), extra.data());
  }
  if (ok && L.tiled)
    ok = TIFFSetField(tif, TIFFTAG_TILEWIDTH, static_cast<std::uint32_t>(L.bw)) &&
         TIFFSetField(tif, TIFFTAG_TILELENGTH, static_cast<std::uint32_t>(L.bh));
  else if (ok)
    ok = TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, static_cast<std::uint32_t>(L.bh));
  if (ok)
    ok = TIFFSetField(tif, TIFFTAG_GEOPIXELSCALE, 3, t.pixel_scale) && TIFFSetField(tif, TIFFTAG_GEOTIEPOINTS, 6, t.tiepoint);
  if (ok && !t.gdal_metadata.empty()) ok = TIFFSetField(tif, kTagGdalMetadata, t.gdal_metadata.c_str());
  if (ok && !t.gdal_nodata.empty()) ok = TIFFSetField(tif, kTagGdalNodata, t.gdal_nodata.c_str());
  if (!ok) fail_write(path, m, "a tag was refused");
  write_geokeys(tif, path, t.geokeys, m);
  // The blocks in file order (band after band). An empty one is not written: libtiff leaves its
  // offset and byte count 0 (a sparse file).
  for (std::size_t s = 0; s < out.size(); ++s) {
    const auto& z = out[s];
    if (z.empty()) continue;
    const auto n = static_cast<tmsize_t>(z.size());
    auto* data = const_cast<std::uint8_t*>(z.data());
    const auto block = static_cast<std::uint32_t>(s);
    tmsize_t wrote;
    if (t.libtiff_codec)
      wrote = L.tiled ? TIFFWriteEncodedTile(tif, block, data, n) : TIFFWriteEncodedStrip(tif, block, data, n);
    else
      wrote = L.tiled ? TIFFWriteRawTile(tif, block, data, n) : TIFFWriteRawStrip(tif, block, data, n);
    if (wrote < 0 || (!t.libtiff_codec && wrote != n)) fail_write(path, m, std::string(std::strerror(errno)));
  }
  if (!TIFFWriteDirectory(tif)) fail_write(path, m, std::string(std::strerror(errno)));
  // TIFFClose flushes; libtiff reports a failed write through the handler.
  TIFFFlush(tif);
  tp.reset();
  if (!m.error.empty()) fail_write(path, m, "");
}
}  // namespace

}  // namespace pcdp::io::detail
