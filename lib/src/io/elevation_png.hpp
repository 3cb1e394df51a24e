// Internal: the picture of an elevation grid (elevation.png), written by write_elevation_png
// (declared in pcdp/io/geotiff.hpp). Kept apart from the GeoTIFF reader and writer.
//
// What it shows (docs/fusion.md): the surface in a perceptual ramp with hillshade, clipped to the
// 2nd-98th percentile; cells without returns ("unseen") and cells whose returns are too few for a
// surface (no height band with min_support points) in two colours of their own, named in a
// legend; eastings and northings of the grid (absolute map metres, as the GeoTIFF) on the axes;
// a colour bar whose ends say what they are (the percentile, or the true min/max) and, where
// the colours are clipped, a triangle with the true extreme beyond it; "flat: z = ..." or
// "no data" instead of a bar where there is no range to show; a scale bar.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/fusion/elevation.hpp"

namespace pcdp::io {

constexpr std::int64_t kPngMaxSide = 4096;   // grids up to this many cells across: a pixel per cell (or more)
constexpr std::int64_t kPngDownSide = 2048;  // larger ones: downsampled to at most this many pixels across

namespace detail {

/// The two colours that are not heights (8-bit RGB).
struct Rgb8 {
  std::uint8_t r, g, b;
};
inline constexpr Rgb8 kUnseenColour{225, 225, 225};       ///< no return in the cell
inline constexpr Rgb8 kFewReturnsColour{244, 190, 208};   ///< returns, but no surface (under min_support)

/// A label drawn on the picture: its text and where (the pixel its text is centred on, along
/// the axis it labels: x for eastings, y for northings and the colour bar).
struct PictureLabel {
  std::string text;
  int at = 0;
};

/// The picture and where its parts lie (for the tests, which decode the PNG and look there).
struct ElevationPicture {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< 8-bit RGB, row by row
  int cells_per_pixel = 1;        ///< f: each map pixel is the mean of f x f cells
  int scale = 1;                  ///< each map pixel drawn as scale x scale picture pixels
  int map_left = 0, map_top = 0, map_width = 0, map_height = 0;  ///< the map inside its frame
  std::int64_t ix0 = 0, iy1 = 0;  ///< the cell at the map's north-west corner
  int bar_left = 0, bar_top = 0, bar_width = 0, bar_height = 0;  ///< the colour bar (inside its frame)
  enum class Bar { kRamp, kFlat, kNoData } bar = Bar::kNoData;
  double lo = 0, hi = 0;      ///< the heights at the bar's ends (the clipped range)
  double zmin = 0, zmax = 0;  ///< the true range of the surface
  bool clipped_low = false, clipped_high = false;
  std::vector<PictureLabel> eastings, northings, bar_labels;
  std::vector<std::string> legend;  ///< the legend's lines, top to bottom
  /// The picture pixel at the centre of cell (ix, iy) (valid for a cell inside the map).
  int cell_x(std::int64_t ix) const {
    return map_left + static_cast<int>((ix - ix0) / cells_per_pixel) * scale + scale / 2;
  }
  int cell_y(std::int64_t iy) const {
    return map_top + static_cast<int>((iy1 - iy) / cells_per_pixel) * scale + scale / 2;
  }
};

/// Draws the picture (what write_elevation_png encodes).
ElevationPicture render_elevation(const ElevationGrid& grid);

}  // namespace detail
}  // namespace pcdp::io
