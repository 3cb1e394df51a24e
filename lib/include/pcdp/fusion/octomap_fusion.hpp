// Batched OctoMap insertion with a sensor origin per return (the laser position at its line).
//
// Per pass: every kept return casts a ray from its own origin (walk_ray_keys: the keys of OctoMap's
// computeRayKeys, which insertPointCloud uses); the free keys of all its rays and the occupied keys of all its
// endpoints are collected for the whole pass, and occupied wins over free in the same batch before
// one update. Inserting line by line instead lets the free rays of later lines erase the
// endpoints of earlier ones (a ground return seen at grazing incidence lies on the next line's
// rays). Rays longer than max_range are cut there and mark only free space, as insertPointCloud
// does. This header includes OctoMap; the rest of the library does not need it.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <tuple>

#include <octomap/OcTree.h>

#include "pcdp/fusion/detail/voxel_blocks.hpp"
#include "pcdp/pipeline/work_share.hpp"

#include <cstdint>

namespace pcdp {

struct Pass;

struct OctoMapParams {
  double resolution = 0.1;  ///< m
  double max_range = -1.0;  ///< m; < 0: unlimited (OctoMap's default)
  // OctoMap's defaults.
  double prob_hit = 0.7, prob_miss = 0.4;
  double clamping_min = 0.1192, clamping_max = 0.971;
  double occupancy_threshold = 0.5;
};

/// A tree with the sensor model of `p`.
octomap::OcTree make_octree(const OctoMapParams& p);

/// The cells one pass's rays update: free (traversed) and occupied (end points), occupied winning.
struct PassRays {
  std::uint64_t rays = 0;
  /// Each cell once: the free cells that are not occupied, and the occupied ones (prepared by
  /// cast_pass, on the worker thread, so the in-order part only updates).
  std::vector<octomap::OcTreeKey> free_list, occupied_list;
};

/// The free cells of the ray o -> e, exactly those OctoMap's `computeRayKeys` gives and in its
/// order (tested key for key), passed to f(x, y, z) as they are found instead of stored in a
/// KeyRay. The same walk (Amanatides & Woo) with the same arithmetic: the direction and length
/// in float as point3d computes them, the cell boundaries in double; it stops at the end point's
/// cell or once the next boundary lies beyond the ray's length, whichever comes first, and neither
/// end's cell is passed unless the walk starts in it (the origin's cell is passed first when the
/// ends differ). Returns false, passing nothing, when either end is outside the tree.
template <class F>
bool walk_ray_keys(const octomap::OcTree& tree, const octomap::point3d& o, const octomap::point3d& e, F&& f) {
  octomap::OcTreeKey ko, ke;
  if (!tree.coordToKeyChecked(o, ko) || !tree.coordToKeyChecked(e, ke)) return false;
  if (ko == ke) return true;
  octomap::point3d dir = e - o;
  const float length = static_cast<float>(dir.norm());
  dir /= length;
  const double res = tree.getResolution();
  int step[3];
  double tmax[3], tdelta[3];
  for (int a = 0; a < 3; ++a) {
    step[a] = dir(a) > 0.0f ? 1 : (dir(a) < 0.0f ? -1 : 0);
    if (step[a] == 0) {
      tmax[a] = tdelta[a] = std::numeric_limits<double>::max();
      continue;
    }
    // The boundary of the origin's cell in the ray's direction: centre plus half a cell (the half
    // cell rounded to float, as OctoMap does).
    const double boundary = tree.keyToCoord(ko[a]) + static_cast<float>(step[a] * res * 0.5);
    tmax[a] = (boundary - o(a)) / dir(a);
    tdelta[a] = res / std::fabs(dir(a));
  }
  // The walk in scalars (kept in arrays indexed by the stepping axis, every step waits on a store).
  std::uint32_t x = ko[0], y = ko[1], z = ko[2];
  const std::uint32_t ex = ke[0], ey = ke[1], ez = ke[2];
  double tx = tmax[0], ty = tmax[1], tz = tmax[2];
  const std::uint32_t sx = static_cast<std::uint32_t>(step[0]), sy = static_cast<std::uint32_t>(step[1]),
                      sz = static_cast<std::uint32_t>(step[2]);  // -1 wraps: keys are unsigned 16-bit
  f(x, y, z);
  for (;;) {
    if (tx < ty && tx < tz) {
      x = (x + sx) & 0xffffu;
      tx += tdelta[0];
    } else if (!(tx < ty) && ty < tz) {
      y = (y + sy) & 0xffffu;
      ty += tdelta[1];
    } else {
      z = (z + sz) & 0xffffu;
      tz += tdelta[2];
    }
    if (x == ex && y == ey && z == ez) return true;
    // The next boundary beyond the ray's length: rounding walked past the end's cell; stop here.
    if (std::min(std::min(tx, ty), tz) > length) return true;
    f(x, y, z);
  }
}

/// Casts the kept returns of a registered pass (the costly part; reads only the tree's key
/// geometry, so it can run while another thread updates a tree of the same resolution). The
/// returns are cast in ranges handed to `share` (idle threads may take some); the result is the
/// same whoever casts them.
PassRays cast_pass(const octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p,
                   WorkShare& share = WorkShare::serial());

/// Applies one pass's cells to the tree: free first, then occupied, then the inner nodes.
void apply_rays(octomap::OcTree& tree, const PassRays& rays);

/// The leaves' log-odds of a run, accumulated pass by pass with OctoMap's own clamped update
/// (OccupancyOcTreeBase::updateNode / updateNodeLogOdds: the same float arithmetic, the same early
/// abort at the thresholds), and put into a tree once at the end. Equivalent to apply_rays on
/// every pass, leaf for leaf and byte for byte in map.bt (tested), but each pass costs an update
/// per cell in a flat block instead of a descent of the tree. The leaves are kept in 8^3 blocks
/// (voxel_blocks.hpp), which are the octree's subtrees three levels above the leaves: the blocks
/// in Morton order, each block's cells in Morton order, are the tree's depth-first leaf order.
class OccupancyAccumulator {
 public:
  explicit OccupancyAccumulator(const OctoMapParams& p);
  void add(const PassRays& rays);  ///< in pass order
  /// Sets every accumulated leaf of `tree` (same resolution and sensor model), then its inner nodes.
  void build(octomap::OcTree& tree) const;
  std::size_t cells() const { return cells_; }

  /// The map in OctoMap's compact binary format (.bt), with the tree's node count (root, inner
  /// nodes and leaves, as OcTree::size() counts them) and its occupied leaves.
  struct BinaryMap {
    std::string bytes;
    std::size_t nodes = 0, occupied_leaves = 0;
  };
  /// The .bt file of the accumulated leaves, byte for byte what build() and
  /// OcTree::writeBinaryConst give (tested), without building the tree: the leaves are listed in
  /// Morton order (x, y, z bits interleaved, the octree's child order), and the tree is walked
  /// depth first over that list. Each node is two bytes, two bits per child in child order
  /// (00 absent, 01 free leaf, 10 occupied leaf, 11 inner node, low bit first), then its inner
  /// children in order.
  BinaryMap encode_binary() const;

 private:
  struct LeafBlock {
    float logodds[512] = {};     // a new leaf starts at 0 (OcTreeNode's log-odds)
    std::uint64_t present[8] = {};  // which cells are leaves
  };
  template <class F>
  void for_each_leaf(F&& f) const;  // f(key, log-odds), blocks in the order first touched
  float hit_ = 0, miss_ = 0, min_ = 0, max_ = 0, occupied_ = 0;
  double resolution_ = 0.1;
  std::size_t cells_ = 0;
  BlockGrid<LeafBlock> leaves_;
};

/// cast_pass + apply_rays. Returns the number of rays cast.
std::uint64_t insert_pass(octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p);

/// The occupied cells of a tree as finest-resolution keys (pruned leaves expanded to the keys they
/// cover), for comparing two maps cell by cell.
std::set<std::tuple<int, int, int>> occupied_keys(const octomap::OcTree& tree);

}  // namespace pcdp
