// Stage `fuse_elevation`: the kept points of every pass into one 2.5-D elevation grid
// (elevation.hpp), each point weighted by its vertical variance (cov_zz from `register`; the
// sensor's range_sigma^2 when the covariance is off). Writes elevation.tif (GeoTIFF, the bands of
// DESIGN.md plus the merge state) and elevation.png (colour, hillshade, colour bar, scale bar).
#pragma once

#include "pcdp/elevation.hpp"
#include "pcdp/stage.hpp"

namespace pcdp {

struct Pass;

struct FuseElevationParams {
  double resolution = 0.1;  ///< m
  double band = 0.05;       ///< m, the height band of the top-surface gate
  std::uint32_t min_support = 2;  ///< points in the highest band that make it the surface
  bool has_extent = false;  ///< otherwise the grid grows with the data
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  double z_max = 1e9;       ///< m, points above are not fused
  bool png = true;
  int deflate_level = 1;    ///< of elevation.tif, 1 .. 12
};

const OptionSchema& fuse_elevation_schema();

/// Adds the kept points of a registered pass to `grid`.
void fuse_pass(ElevationGrid& grid, const Pass& pass, const FuseElevationParams& p, double fallback_var);

StageInfo fuse_elevation_stage_info();

}  // namespace pcdp
