// A writer of float32 GeoTIFFs as GDAL writes them (planar, DEFLATE strips or sparse tiles, GDAL's
// metadata and nodata tags, GeoKeys), through libtiff (the directory, BigTIFF, the file) and
// libgeotiff (the GeoKey directory). The strips and tiles are compressed with libdeflate as tasks a
// RunTasks may spread over threads, and handed to libtiff already compressed
// (TIFFWriteRawStrip/TIFFWriteRawTile): libtiff's own codec compresses each block as it is
// written, on the writing thread (docs/performance.md has the comparison and the command).
// GDAL reads these files (gdalinfo, QGIS); `merge` reads them with tiff_reader.hpp.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/core/tasks.hpp"
#include "tiff_format.hpp"

namespace pcdp::io::detail {

struct FloatTiff {
  int width = 0, height = 0, bands = 1;
  int rows_per_strip = 1;
  int tile = 0;  ///< > 0: tiles of tile x tile pixels (a multiple of 16), written by write_float_tiff_blocks
  double pixel_scale[3] = {1, 1, 0};    ///< ModelPixelScaleTag (33550)
  double tiepoint[6] = {0, 0, 0, 0, 0, 0};  ///< ModelTiepointTag (33922): raster (i, j, k) -> model (x, y, z)
  std::string gdal_metadata;            ///< GDAL_METADATA (42112) XML, empty: none
  std::string gdal_nodata;              ///< GDAL_NODATA (42113), e.g. "nan"; empty: none
  bool bigtiff = false;                 ///< force BigTIFF (it is chosen anyway past 4 GiB)
  /// Bands filled together, in band order (sizes summing to `bands`); empty: one band a group.
  /// A source whose cells hold several bands' values is then read once per group, not per band.
  std::vector<int> groups;
  /// The GeoKeys (tiff_writer.hpp's caller decides them: geotiff_crs.hpp); model 0: none written.
  GeoKeys geokeys;
  /// Compress with libtiff's own DEFLATE codec at `level` as the blocks are written (one thread),
  /// not with libdeflate in the tasks handed to RunTasks: only for the comparison in docs/performance.md.
  bool libtiff_codec = false;
};

/// Fills the planes of bands first .. first + planes.size() - 1 (one group): width * height
/// floats each, row 0 first (north-up rasters: the north row).
using PlaneFill = std::function<void(int first, std::vector<std::vector<float>>& planes)>;

/// Writes the raster to `path` (the caller renames it into place). One task per group of bands:
/// fill its planes, DEFLATE their strips at `level` (1 .. 12, libdeflate's levels). At most one
/// group's planes per running task are in memory, plus the compressed strips. The bytes do not
/// depend on which thread ran which task. Throws OutputError (libtiff's message) or std::runtime_error naming the path.
void write_float_tiff(const std::string& path, const FloatTiff& t, int level, const PlaneFill& fill,
                      const RunTasks& share);

/// A block of the raster: a strip (the raster's width, rows_per_strip rows, the last cut to the
/// rows left) or a tile (tile x tile pixels, stored whole: the pixels past the raster's right or
/// bottom edge are padding).
struct Block {
  std::size_t index = 0;  ///< row-major among the blocks of a band
  int x0 = 0, y0 = 0;     ///< its top-left pixel in the raster
  int width = 0, height = 0;
};
/// Fills the planes of bands first .. first + planes.size() - 1 (one group) for `block`: width *
/// height floats each, its top row first. Returns false when it holds no data (every value
/// nodata): a tile is then not stored (TileOffsets and TileByteCounts 0, a sparse file that GDAL
/// and tiff_reader.hpp read as nodata); a strip is stored anyway, as filled.
using BlockFill = std::function<bool(int first, const Block& block, std::vector<std::vector<float>>& planes)>;

/// As write_float_tiff, but each task fills and compresses one block of its group at a time:
/// memory is a block of each running group, plus the compressed blocks (none for an empty tile),
/// whatever the raster's size. Strips (t.tile == 0) are the same bytes write_float_tiff writes for
/// the same values.
void write_float_tiff_blocks(const std::string& path, const FloatTiff& t, int level, const BlockFill& fill,
                             const RunTasks& share);

/// The GDAL_METADATA XML for dataset items (name, value) and band descriptions (band 1 first;
/// empty ones left out), as GDAL writes it: values are escaped twice, because GDAL escapes a
/// value before its XML writer escapes the text again, and its reader undoes both.
std::string gdal_metadata(const std::vector<std::pair<std::string, std::string>>& items,
                          const std::vector<std::string>& band_descriptions);

}  // namespace pcdp::io::detail
