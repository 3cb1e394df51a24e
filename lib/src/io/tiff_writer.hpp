// A small writer of float32 GeoTIFFs as GDAL writes them (planar, DEFLATE strips, GDAL's metadata
// and nodata tags), with the strips compressed as tasks a WorkShare may spread over threads.
//
// Why not GDAL's own writer: it compresses every strip on one thread when the dataset closes, and
// that was the longest single piece at the end of a run (22 of the 44 ms the 8-pass bench spends
// writing products on one thread; docs/performance.md, eleventh round). GDAL reads these files
// (gdalinfo, QGIS); the tests read them back through it. `merge` reads them with tiff_reader.hpp.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/work_share.hpp"

namespace pcdp::io::detail {

struct FloatTiff {
  int width = 0, height = 0, bands = 1;
  int rows_per_strip = 1;
  double pixel_scale[3] = {1, 1, 0};    ///< ModelPixelScaleTag (33550)
  double tiepoint[6] = {0, 0, 0, 0, 0, 0};  ///< ModelTiepointTag (33922): raster (i, j, k) -> model (x, y, z)
  std::string gdal_metadata;            ///< GDAL_METADATA (42112) XML, empty: none
  std::string gdal_nodata;              ///< GDAL_NODATA (42113), e.g. "nan"; empty: none
  bool bigtiff = false;                 ///< force BigTIFF (it is chosen anyway past 4 GiB)
  /// Bands filled together, in band order (sizes summing to `bands`); empty: one band a group.
  /// A source whose cells hold several bands' values is then read once per group, not per band.
  std::vector<int> groups;
};

/// Fills the planes of bands first .. first + planes.size() - 1 (one group): width * height
/// floats each, row 0 first (north-up rasters: the north row).
using PlaneFill = std::function<void(int first, std::vector<std::vector<float>>& planes)>;

/// Writes the raster to `path` (the caller renames it into place). One task per group of bands:
/// fill its planes, DEFLATE their strips at `level` (1 .. 12, libdeflate's levels). At most one
/// group's planes per running task are in memory, plus the compressed strips. The bytes do not
/// depend on which thread ran which task. Throws std::runtime_error naming the path.
void write_float_tiff(const std::string& path, const FloatTiff& t, int level, const PlaneFill& fill,
                      WorkShare& share);

/// The GDAL_METADATA XML for dataset items (name, value) and band descriptions (band 1 first;
/// empty ones left out), as GDAL writes it: values are escaped twice, because GDAL escapes a
/// value before its XML writer escapes the text again, and its reader undoes both.
std::string gdal_metadata(const std::vector<std::pair<std::string, std::string>>& items,
                          const std::vector<std::string>& band_descriptions);

}  // namespace pcdp::io::detail
