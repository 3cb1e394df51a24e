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
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "pcdp/fusion/detail/flat_map.hpp"

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

/// One point ready to fuse: its cell key, height band and information-form sums (computed off
/// the grid, e.g. on a worker thread, so that adding it is a lookup and a few additions).
struct ElevationSample {
  std::uint64_t key = 0;
  std::int32_t band = 0, pass = 0;
  double w = 0, wz = 0;  ///< 1/var and z/var
  float z = 0;
};

class ElevationGrid {
 public:
  ElevationGrid(double resolution, double band, std::uint32_t min_support = 2)
      : res_(resolution), band_(band), min_support_(min_support) {
    set_limits();
  }

  double resolution() const { return res_; }
  double band() const { return band_; }
  std::uint32_t min_support() const { return min_support_; }

  /// Fuses one point (map frame, vertical variance var_z > 0) seen in pass `pass` (passes are
  /// added in increasing order).
  void add(double x, double y, double z, double var_z, std::int32_t pass) {
    const ElevationSample s = sample(x, y, z, var_z, pass);
    add(&s, 1);
  }
  /// The sample add() fuses for this point (pure: any thread).
  ElevationSample sample(double x, double y, double z, double var_z, std::int32_t pass) const;
  /// Fuses samples in order (the same as add() on each point, with fewer lookups: consecutive
  /// samples of a scan line often share a cell).
  void add(const ElevationSample* s, std::size_t n);
  /// Merges another grid (same resolution and band; extents may differ): exact and order-free.
  void merge(const ElevationGrid& other);
  /// Merges one cell of another grid of the same resolution and band (what merge() does for each).
  void merge_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c) { merge_cell_at(checked_key(ix, iy), c); }
  /// Sets a cell's state directly (reading a grid back from a GeoTIFF).
  void set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c);

  /// The surface of a cell: false when it has none (no band with enough support).
  bool surface(const ElevationCell& c, double& elevation, double& variance) const;

  /// Cell indices are absolute (cell (ix, iy) spans [ix, ix + 1) * resolution in map metres); the
  /// grid holds the cells within kKeyReach of its key origin, cell (0, 0) unless set here. Set it
  /// before the first cell is added (a georeferenced run puts it at its map origin's cell).
  void set_key_origin(std::int64_t ix, std::int64_t iy);
  std::int64_t key_origin_x() const { return kx0_; }
  std::int64_t key_origin_y() const { return ky0_; }
  /// Cells on either side of the key origin a grid holds, per axis (2^30: +-107,000 km at 0.1 m,
  /// +-1,070 km at 1 mm).
  static constexpr std::int64_t kKeyReach = std::int64_t{1} << 30;
  /// Whether the grid can hold cell (ix, iy) (adding a cell it cannot hold throws std::out_of_range).
  bool holds(std::int64_t ix, std::int64_t iy) const {
    return ix - kx0_ >= -kKeyReach && ix - kx0_ < kKeyReach && iy - ky0_ >= -kKeyReach && iy - ky0_ < kKeyReach;
  }
  /// Whether the grid can hold the cell of map point (x, y) and the height band of z (false for
  /// NaN). Two cells (bands) short of the limits, so that no rounding at the edge lets a point
  /// through whose cell holds() refuses; a few comparisons, for every point fused.
  bool holds_point(double x, double y, double z) const {
    return x > lim_[0] && x < lim_[1] && y > lim_[2] && y < lim_[3] && std::fabs(z) < lim_[4];
  }

  std::int64_t cell_index(double v) const { return static_cast<std::int64_t>(std::floor(v / res_)); }
  double cell_center(std::int64_t i) const { return (static_cast<double>(i) + 0.5) * res_; }
  const ElevationCell* find(std::int64_t ix, std::int64_t iy) const;
  std::size_t size() const { return size_; }  ///< cells that hold points
  /// Inclusive index bounds of the occupied cells; false when empty.
  bool bounds(std::int64_t& ix0, std::int64_t& iy0, std::int64_t& ix1, std::int64_t& iy1) const;
  /// f(ix, iy, cell) for every cell, in the order the cells were first touched.
  template <typename F>
  void for_each(F f) const {
    for (std::size_t i = 0; i < size_; ++i) {
      const Chunk& ch = chunks_[i / kChunk];
      const std::uint64_t k = ch.keys[i % kChunk];
      f(unkey_x(k), unkey_y(k), ch.cells[i % kChunk]);
    }
  }

 private:
  // Cell indices relative to the key origin are kept to 31 bits each (+-kKeyReach cells), so that
  // a key is a 62-bit number (FlatMap's keys must not be ~0); a cell beyond is refused (holds()),
  // never wrapped onto another.
  static constexpr std::int64_t kOffset = kKeyReach;
  static constexpr std::uint64_t kMask = (std::uint64_t{1} << 31) - 1;
  std::uint64_t key(std::int64_t ix, std::int64_t iy) const {
    return ((static_cast<std::uint64_t>(ix - kx0_ + kOffset) & kMask) << 31) |
           (static_cast<std::uint64_t>(iy - ky0_ + kOffset) & kMask);
  }
  /// key(), after checking that the grid holds the cell (std::out_of_range otherwise).
  std::uint64_t checked_key(std::int64_t ix, std::int64_t iy) const;
  std::int64_t unkey_x(std::uint64_t k) const { return static_cast<std::int64_t>(k >> 31) - kOffset + kx0_; }
  std::int64_t unkey_y(std::uint64_t k) const { return static_cast<std::int64_t>(k & kMask) - kOffset + ky0_; }
  /// The cell of `k`, appended empty if absent.
  ElevationCell& touch(std::uint64_t k);
  void merge_cell_at(std::uint64_t k, const ElevationCell& c);
  ElevationCell& cell(std::size_t i) { return chunks_[i / kChunk].cells[i % kChunk]; }
  const ElevationCell& cell(std::size_t i) const { return chunks_[i / kChunk].cells[i % kChunk]; }

  double res_, band_;
  std::uint32_t min_support_;
  std::int64_t kx0_ = 0, ky0_ = 0;  ///< the key origin (set_key_origin)
  double lim_[5] = {0, 0, 0, 0, 0};  ///< holds_point's bounds: x, y (map metres), |z|
  void set_limits();
  // The cells in the order they were first touched, in chunks of kChunk (about 40 kB; growth
  // never moves a cell, and a visit of every cell reads memory in order), with a hash from key to
  // place: a lookup probes 8-byte keys. Against one heap node per cell (std::unordered_map): 2x
  // faster fusion and GeoTIFF writing in a run of several passes, but slower for one pass into a
  // new grid, whose fresh chunks are page faults (docs/performance.md).
  static constexpr std::size_t kChunk = 256;
  struct Chunk {
    std::array<ElevationCell, kChunk> cells;
    std::array<std::uint64_t, kChunk> keys;
  };
  std::deque<Chunk> chunks_;
  std::size_t size_ = 0;
  FlatMap<std::uint32_t> index_{0x2545f491u};
};

}  // namespace pcdp
