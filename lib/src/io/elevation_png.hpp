// Internal: the picture of an elevation grid (elevation.png), written by write_elevation_png
// (declared in pcdp/io/geotiff.hpp). Kept apart from the GeoTIFF reader and writer.
#pragma once

#include <cstdint>

namespace pcdp::io {

constexpr std::int64_t kPngMaxSide = 4096;   // grids up to this many cells across: a pixel per cell (or more)
constexpr std::int64_t kPngDownSide = 2048;  // larger ones: downsampled to at most this many pixels across

}  // namespace pcdp::io
