// Batched OctoMap insertion with a sensor origin per return (the laser position at its line).
//
// Per pass: every kept return casts a ray from its own origin (OctoMap's computeRayKeys, the same
// keys insertPointCloud uses); the free keys of all its rays and the occupied keys of all its
// endpoints are collected for the whole pass, and occupied wins over free in the same batch before
// one update. Inserting line by line instead lets the free rays of later lines erase the
// endpoints of earlier ones (a ground return seen at grazing incidence lies on the next line's
// rays). Rays longer than max_range are cut there and mark only free space, as insertPointCloud
// does. This header includes OctoMap; the rest of the library does not need it.
#pragma once

#include <set>
#include <string>
#include <tuple>

#include <octomap/OcTree.h>

#include "pcdp/flat_map.hpp"

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

/// Casts the kept returns of a registered pass (the costly part; reads only the tree's key
/// geometry, so it can run while another thread updates a tree of the same resolution).
PassRays cast_pass(const octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p);

/// Applies one pass's cells to the tree: free first, then occupied, then the inner nodes.
void apply_rays(octomap::OcTree& tree, const PassRays& rays);

/// The leaves' log-odds of a run, accumulated pass by pass in a flat map with OctoMap's own
/// clamped update (OccupancyOcTreeBase::updateNode / updateNodeLogOdds: the same float
/// arithmetic, the same early abort at the thresholds), and put into a tree once at the end.
/// Equivalent to apply_rays on every pass, leaf for leaf and byte for byte in map.bt (tested), but
/// each pass costs a flat-map update per cell instead of a descent of the tree.
class OccupancyAccumulator {
 public:
  explicit OccupancyAccumulator(const OctoMapParams& p);
  void add(const PassRays& rays);  ///< in pass order
  /// Sets every accumulated leaf of `tree` (same resolution and sensor model), then its inner nodes.
  void build(octomap::OcTree& tree) const;
  std::size_t cells() const { return logodds_.size(); }

  /// The map in OctoMap's compact binary format (.bt), with the tree's node count (root, inner
  /// nodes and leaves, as OcTree::size() counts them) and its occupied leaves.
  struct BinaryMap {
    std::string bytes;
    std::size_t nodes = 0, occupied_leaves = 0;
  };
  /// The .bt file of the accumulated leaves, byte for byte what build() and
  /// OcTree::writeBinaryConst give (tested), without building the tree: the leaves are sorted in
  /// Morton order (x, y, z bits interleaved, the octree's child order), and the tree is walked
  /// depth first over that list. Each node is two bytes, two bits per child in child order
  /// (00 absent, 01 free leaf, 10 occupied leaf, 11 inner node, low bit first), then its inner
  /// children in order.
  BinaryMap encode_binary() const;

 private:
  static std::uint64_t pack(const octomap::OcTreeKey& k) {
    return (static_cast<std::uint64_t>(k[0]) << 32) | (static_cast<std::uint64_t>(k[1]) << 16) | k[2];
  }
  void update(const octomap::OcTreeKey& k, float delta);
  float hit_ = 0, miss_ = 0, min_ = 0, max_ = 0, occupied_ = 0;
  double resolution_ = 0.1;
  FlatMap<float> logodds_;
};

/// cast_pass + apply_rays. Returns the number of rays cast.
std::uint64_t insert_pass(octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p);

/// The occupied cells of a tree as finest-resolution keys (pruned leaves expanded to the keys they
/// cover), for comparing two maps cell by cell.
std::set<std::tuple<int, int, int>> occupied_keys(const octomap::OcTree& tree);

}  // namespace pcdp
