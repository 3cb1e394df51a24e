// 2.5-D elevation grid fused from many passes, with exact, order-free merging.
//
// Each cell keeps the information-form sums (sum of 1/var and of z/var) of the points in its two
// highest height bands (bands `band` metres tall, fixed in the map frame), plus count, passes, min
// and max of all its points. The elevation is the information-weighted mean of those two bands;
// its variance 1 / sum(1/var).
//
// The gate, and why it is a band: the map keeps the *top surface*. A point far above the cell's
// points starts a new top band and the lower ones drop out of the estimate (a vertical face keeps
// its top surface); a point far below the top bands is counted (min, count) but not fused (a lower
// point under an overhang does not pull the surface down). "Far" is more than one band below the
// top band: with band = 0.05 m that is 5 to 10 cm, about 8 to 16 sigma of a SICK return, so the
// band is a Mahalanobis gate at a fixed scale. Unlike a gate on the running estimate (which
// depends on the order the points arrive in), the top band of a union is the maximum of the top
// bands: merging grids fused from disjoint sets of passes gives exactly the grid fused from all
// of them, in any grouping and order.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

namespace pcdp {

struct ElevationCell {
  std::int32_t top = std::numeric_limits<std::int32_t>::min();  ///< index of the top band
  double w_top = 0, wz_top = 0;    ///< sums of 1/var and z/var in the top band
  double w_next = 0, wz_next = 0;  ///< the same in the band below it
  std::uint32_t count = 0;         ///< all points
  std::uint32_t passes = 0;        ///< passes that saw the cell
  std::int32_t last_pass = -1;     ///< while fusing: the pass counted last
  float zmin = std::numeric_limits<float>::infinity(), zmax = -std::numeric_limits<float>::infinity();

  bool empty() const { return count == 0; }
  double weight() const { return w_top + w_next; }
  double elevation() const { return (wz_top + wz_next) / weight(); }
  double variance() const { return 1.0 / weight(); }
};

class ElevationGrid {
 public:
  ElevationGrid(double resolution, double band) : res_(resolution), band_(band) {}

  double resolution() const { return res_; }
  double band() const { return band_; }

  /// Fuses one point (map frame, vertical variance var_z > 0) seen in pass `pass` (passes are
  /// added in increasing order).
  void add(double x, double y, double z, double var_z, std::int32_t pass);

  /// Merges another grid (same resolution and band; extents may differ): exact and order-free.
  void merge(const ElevationGrid& other);

  /// Sets a cell's state directly (reading a grid back from a GeoTIFF).
  void set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c);

  /// Cell index of a coordinate, and the cell's centre.
  std::int64_t cell_index(double v) const { return static_cast<std::int64_t>(std::floor(v / res_)); }
  double cell_center(std::int64_t i) const { return (static_cast<double>(i) + 0.5) * res_; }

  const ElevationCell* find(std::int64_t ix, std::int64_t iy) const;
  std::size_t size() const { return cells_.size(); }
  /// Inclusive index bounds of the occupied cells; false when empty.
  bool bounds(std::int64_t& ix0, std::int64_t& iy0, std::int64_t& ix1, std::int64_t& iy1) const;
  template <typename F>
  void for_each(F f) const {
    for (const auto& [k, c] : cells_) f(unkey_x(k), unkey_y(k), c);
  }

 private:
  static std::uint64_t key(std::int64_t ix, std::int64_t iy) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(ix)) << 32) | static_cast<std::uint32_t>(iy);
  }
  static std::int64_t unkey_x(std::uint64_t k) { return static_cast<std::int32_t>(k >> 32); }
  static std::int64_t unkey_y(std::uint64_t k) { return static_cast<std::int32_t>(k & 0xffffffffu); }
  static void absorb(ElevationCell& into, std::int32_t band, double w, double wz);

  double res_, band_;
  std::unordered_map<std::uint64_t, ElevationCell> cells_;
};

}  // namespace pcdp
