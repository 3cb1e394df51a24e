// The elevation grid on disk: two GeoTIFFs of the same raster, written through libtiff and
// libgeotiff (GDAL's tags; read by GDAL and by `merge` through libtiff).
// - elevation.tif, the user's bands of docs/data_contract.md: 1 elevation m, 2 variance m^2,
//   3 count, 4 min m, 5 max m, 6 passes; float32, NaN = unobserved, north-up geotransform in map
//   metres (map x = east, map y = north), the pipeline's `crs` as GeoKeys.
// - elevation.state.tif beside it (elevation_state_path()), the exact merge state: 1 count,
//   2 min, 3 max, 4 passes, then for each of the cell's four highest height bands its index, sum
//   of 1/var, mean height and count (bands 5-20). GeoTIFF bands share one type, so these are
//   float32 too: merged elevations agree to float32 precision.
// Metadata records resolution, band height and min_support. Written to temporary names, then
// renamed. DEFLATE-compressed at `deflate_level` (1 .. 12, libdeflate's levels, as GDAL's
// ZLEVEL): 1 compresses the 8-pass bench grid 2.3x faster than 6, GDAL's default, for a file
// 2.4 % larger (docs/performance.md). A raster of at most 2^22 cells is written in strips of at
// least 64 KiB of a band; a larger one in 256 x 256 tiles, those without an observed cell not
// stored (a sparse GeoTIFF: GDAL reads them as nodata), so that the files and their writing cost
// what the grid observed (docs/fusion.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/fusion/elevation.hpp"
#include "pcdp/core/tasks.hpp"

namespace pcdp::io {

/// Each group of bands is filled and compressed a strip or tile at a time as a task handed to
/// `run` (the pipeline's threads with nothing else to do help); the file's bytes do not depend on
/// who ran them.
/// Returns the number of cells with a surface (the pixels of band 1 that are not nodata). Throws
/// InputError naming elevation.tif and the size when the raster spans more than 65,536 tiles of
/// 256 x 256 cells (4,294,967,296 cells), before anything is allocated.
/// `crs`: "" (no GeoKeys) or as normalize_crs() returns it. `state_path`: where the merge state
/// goes; empty: elevation_state_path(path).
std::size_t write_elevation_geotiff(const ElevationGrid& grid, const std::string& path, int deflate_level = 1,
                                   const RunTasks& run = run_in_order, const std::string& crs = "",
                                   const std::string& state_path = "");

/// The merge state's file of the grid `path`: "X.tif" -> "X.state.tif" (else path + ".state.tif").
std::string elevation_state_path(const std::string& path);

/// The pipeline key `crs`, checked against PROJ's database: "EPSG:N" (any case of EPSG) naming a
/// projected CRS in metres, or WKT (1 or 2) of one that PROJ identifies with an EPSG code with
/// full confidence. Returns "EPSG:N"; "" for "". elevation.tif states its CRS as that code in its
/// GeoKeys (libgeotiff writes GeoKeys from codes; a WKT without a code would read back in GDAL as
/// an unknown CRS, so it is refused). Throws std::invalid_argument stating the rule (the caller
/// names the key).
std::string normalize_crs(const std::string& text);

/// The CRS of a grid (read from its merge state, or from the grid of an earlier version): "EPSG:N",
/// a user-defined CRS's WKT, or "" when it has none. Throws InputError as read_elevation_geotiff.
std::string elevation_geotiff_crs(const std::string& path);
/// InputError naming `product` and the size unless a raster of cells ix0 .. ix1 x iy0 .. iy1
/// spans at most 65,536 tiles of 256 x 256 cells: what write_elevation_geotiff can write (its
/// tile directory grows with the raster's area, whatever it holds).
void check_elevation_extent(std::int64_t ix0, std::int64_t iy0, std::int64_t ix1, std::int64_t iy1, double res,
                            const std::string& product = "elevation.tif");

/// The grid an elevation.tif's GDAL metadata records: PCDP_RESOLUTION and PCDP_BAND (numbers
/// > 0) and PCDP_MIN_SUPPORT (a whole number in 1 .. 1000000), each exactly once, each value a
/// number and nothing else. Throws InputError naming `path` and the item.
struct GridMetadata {
  double resolution = 0, band = 0;
  std::uint32_t min_support = 0;
};
GridMetadata parse_grid_metadata(const std::string& gdal_metadata_xml, const std::string& path);

/// InputError unless the files are distinct grids: the same file twice (by any path) or two
/// files of identical bytes would count the same passes twice in a merge.
void check_distinct_grids(const std::vector<std::string>& paths);

/// Reads the grid `path` from its merge state (elevation_state_path(path); a grid of version 0.1.0
/// holds it itself, 22 bands). Throws InputError naming the file read when it is
/// missing, not a GeoTIFF of pcd_pipeline, or lacks the merge bands.
ElevationGrid read_elevation_geotiff(const std::string& path);
/// Merges the grid in `path` into `grid`: the same as grid.merge(read_elevation_geotiff(path)),
/// but read a row of a strip or tile at a time into `grid`, so it takes no second grid's memory.
/// Every cell's state is checked as it is read (docs/fusion.md). Throws InputError as
/// read_elevation_geotiff does, when a merged count would pass 2^32 - 1, or when the file's
/// resolution, band or min_support differ from `grid`'s (checked before any cell is read; the
/// message calls `grid` `grid_name`).
/// A damaged file found mid-way leaves the cells read so far merged: discard `grid` then.
void merge_elevation_geotiff(ElevationGrid& grid, const std::string& path,
                             const std::string& grid_name = "the grid");

/// The picture a person reads (lib/src/io/elevation_png.cpp, docs/fusion.md): elevation in colour
/// (perceptual ramp, 2nd-98th percentile) with hillshade, eastings and northings in map metres on
/// the axes, a colour bar that shows the clipping (the true min/max beyond triangles), "flat" or
/// "no data" where there is no range, unseen and too-few-returns cells in colours of their own
/// with a legend, and a scale bar. 8-bit RGB PNG through libpng's
/// simplified writer (no row filters, zlib level 3: a preview). Written to a temporary name, then
/// renamed; throws std::runtime_error naming the path. A grid more than 4,096 cells across is
/// drawn downsampled, at most 2,048 pixels across: each pixel the mean surface of f x f cells, f
/// the smallest that fits, noted on the picture ("1 px = f x f cells"). Returns f (1: a pixel per
/// cell).
int write_elevation_png(const ElevationGrid& grid, const std::string& path);

}  // namespace pcdp::io
