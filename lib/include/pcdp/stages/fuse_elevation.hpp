// Stage `fuse_elevation`: the kept points of every pass into one 2.5-D elevation grid
// (elevation.hpp), each point weighted by its vertical variance (cov_zz from `register`; the
// sensor's range_sigma^2 when the covariance is off). Writes elevation.tif (GeoTIFF, the bands of
// docs/data_contract.md plus the merge state) and elevation.png (colour, hillshade, colour bar, scale bar).
#pragma once

#include <string>

#include "pcdp/fusion/elevation.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

struct Pass;

struct FuseElevationParams {
  double resolution = 0.1;  ///< m
  double band = 0.05;       ///< m, the height band of the top-surface gate
  std::uint32_t min_support = 2;  ///< points in the highest band that make it the surface
  std::string extent;       ///< "xmin,ymin,xmax,ymax" as given; empty: the grid grows with the data
  bool has_extent = false;  ///< `extent` read into xmin .. ymax; otherwise the grid grows with the data
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  double z_max = 1e9;       ///< m, points above are not fused
  bool png = true;
  int deflate_level = 1;    ///< of elevation.tif, 1 .. 12
  /// The map origin the passes' coordinates are relative to (RunContext::map_origin): the grid,
  /// extent and z_max are in map metres, so each point is fused at pass coordinates + origin.
  double origin_x = 0, origin_y = 0, origin_z = 0;
  std::string stage = "fuse_elevation";  ///< how messages name the stage
};

/// A grid for these parameters: its key origin at the map origin's cell, so that the grid holds
/// the cells within ElevationGrid::kKeyReach of it (UTM coordinates at 1 mm included).
ElevationGrid make_elevation_grid(const FuseElevationParams& p);

/// The options of `fuse_elevation`, bound to FuseElevationParams.
const Options<FuseElevationParams>& fuse_elevation_options();
const OptionSchema& fuse_elevation_schema();

/// Adds the kept points of a registered pass to `grid`. Throws InputError naming the stage, the
/// pass and the point when a point to fuse lies beyond what the grid can hold (never wrapped).
void fuse_pass(ElevationGrid& grid, const Pass& pass, const FuseElevationParams& p, double fallback_var);

StageInfo fuse_elevation_stage_info();

}  // namespace pcdp
