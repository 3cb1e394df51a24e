// The elevation grid on disk: a GeoTIFF written through GDAL with the bands of DESIGN.md
// (1 elevation m, 2 variance m^2, 3 count, 4 min m, 5 max m; float32, NaN = unobserved, north-up
// geotransform in map metres, map x = east, map y = north), plus the bands that make grids
// mergeable exactly (6 top band index, 7 sum 1/var of the top band, 8 sum z/var of the top band,
// 9 and 10 the same for the band below, 11 passes; float64 so that merges lose nothing). Metadata
// records the resolution and the band height. Written to a temporary name, then renamed.
#pragma once

#include <string>

#include "pcdp/elevation.hpp"

namespace pcdp::io {

void write_elevation_geotiff(const ElevationGrid& grid, const std::string& path);
/// Throws InputError when the file is missing, not a GeoTIFF of pcd_pipeline, or lacks the
/// merge bands.
ElevationGrid read_elevation_geotiff(const std::string& path);

/// The picture a person reads: elevation in colour (perceptual ramp) with hillshade, unobserved
/// cells in light grey, a colour bar with heights and a scale bar. PNG, via GDAL.
void write_elevation_png(const ElevationGrid& grid, const std::string& path);

}  // namespace pcdp::io
