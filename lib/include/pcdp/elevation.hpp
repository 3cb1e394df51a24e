// 2.5-D elevation grid fused from many passes, with exact, order-free merging.
//
// Each cell keeps its kBands highest non-empty height bands (bands `band` metres tall, fixed in
// the map frame), each with the information-form sums of its points (sum of 1/var, of z/var) and
// their count, plus count, passes, min and max of all its points. The surface is the highest band
// holding at least `min_support` points (a lone stray point above the ground does not become the
// surface), fused with the band just below it if that is kept: the information-weighted mean, and
// variance 1 / sum(1/var).
//
// The gate, and why it is a band: the map keeps the *top surface*. Points in bands below the
// surface's (more than one band below: with band = 0.05 m, 5 to 10 cm, about 8 to 16 sigma of a
// SICK return) are counted (min, count) but not fused: a vertical face keeps its top surface, and
// a lower point under an overhang does not pull the surface down. It is a Mahalanobis gate at a
// fixed scale. Unlike a gate on the running estimate (which depends on the order the points arrive
// in), the highest bands of a union are the highest of the highest bands of its parts: merging
// grids fused from disjoint sets of passes gives exactly the grid fused from all of them, in any
// grouping and order.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

namespace pcdp {

struct HeightBand {
  std::int32_t index = std::numeric_limits<std::int32_t>::min();
  double w = 0, wz = 0;  ///< sums of 1/var and z/var
  std::uint32_t count = 0;
  bool empty() const { return count == 0; }
};

struct ElevationCell {
  static constexpr int kBands = 4;
  std::array<HeightBand, kBands> bands{};  ///< highest first
  std::uint32_t count = 0;                 ///< all points
  std::uint32_t passes = 0;                ///< passes that saw the cell
  std::int32_t last_pass = -1;             ///< while fusing: the pass counted last
  float zmin = std::numeric_limits<float>::infinity(), zmax = -std::numeric_limits<float>::infinity();

  bool empty() const { return count == 0; }
  /// Adds a band's sums (same index: summed; else inserted in order, the lowest dropped).
  void absorb(const HeightBand& b);
  /// The surface's sums (the highest band with enough support, and the one just below it);
  /// weight 0 when no band has the support.
  void surface(std::uint32_t min_support, double& w, double& wz) const;
};

class ElevationGrid {
 public:
  ElevationGrid(double resolution, double band, std::uint32_t min_support = 2)
      : res_(resolution), band_(band), min_support_(min_support) {}

  double resolution() const { return res_; }
  double band() const { return band_; }
  std::uint32_t min_support() const { return min_support_; }

  /// Fuses one point (map frame, vertical variance var_z > 0) seen in pass `pass` (passes are
  /// added in increasing order).
  void add(double x, double y, double z, double var_z, std::int32_t pass);
  /// Merges another grid (same resolution and band; extents may differ): exact and order-free.
  void merge(const ElevationGrid& other);
  /// Sets a cell's state directly (reading a grid back from a GeoTIFF).
  void set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c);

  /// The surface of a cell: false when it has none (no band with enough support).
  bool surface(const ElevationCell& c, double& elevation, double& variance) const;

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

  double res_, band_;
  std::uint32_t min_support_;
  std::unordered_map<std::uint64_t, ElevationCell> cells_;
};

}  // namespace pcdp
