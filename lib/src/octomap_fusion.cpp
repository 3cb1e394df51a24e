#include "pcdp/octomap_fusion.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "pcdp/pass.hpp"

namespace pcdp {

octomap::OcTree make_octree(const OctoMapParams& p) {
  octomap::OcTree tree(p.resolution);
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_min);
  tree.setClampingThresMax(p.clamping_max);
  tree.setOccupancyThres(p.occupancy_threshold);
  return tree;
}

PassRays cast_pass(const octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p) {
  PassRays out;
  // Each cell once per pass, in flat sets (1 free, 2 occupied: occupied wins); a small
  // direct-mapped cache drops most repeats first (neighbouring rays cross the same cells).
  FlatMap<char> cells(0x5bd1e995u);  // another salt than OccupancyAccumulator's map, which it feeds
  std::vector<std::uint64_t> cache(4096, ~0ull);
  const auto pack = [](const octomap::OcTreeKey& k) {
    return (static_cast<std::uint64_t>(k[0]) << 32) | (static_cast<std::uint64_t>(k[1]) << 16) | k[2];
  };
  const auto mark_free = [&](const octomap::OcTreeKey& key) {
    const std::uint64_t k = pack(key);
    std::uint64_t& c = cache[(k * 0x9E3779B97F4A7C15ull) >> 52];
    if (c == k) return;
    c = k;
    char& v = cells[k];
    if (v == 0) v = 1;
  };
  octomap::KeyRay ray;
  std::uint64_t& rays = out.rays;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
    const octomap::point3d o(static_cast<float>(pass.ox[i]), static_cast<float>(pass.oy[i]), static_cast<float>(pass.oz[i]));
    octomap::point3d e(static_cast<float>(pass.x[i]), static_cast<float>(pass.y[i]), static_cast<float>(pass.z[i]));
    bool hit = true;
    if (p.max_range > 0 && (e - o).norm() > p.max_range) {
      e = o + (e - o).normalized() * static_cast<float>(p.max_range);
      hit = false;
    }
    ++rays;
    if (tree.computeRayKeys(o, e, ray))
      for (const auto& k : ray) mark_free(k);
    octomap::OcTreeKey k;
    if (tree.coordToKeyChecked(e, k)) {
      if (hit)
        cells[pack(k)] = 2;
      else
        mark_free(k);  // a cut end is free
    }
  }
  cells.for_each([&](std::uint64_t k, char v) {
    const octomap::OcTreeKey key(static_cast<octomap::key_type>(k >> 32), static_cast<octomap::key_type>((k >> 16) & 0xffff),
                                 static_cast<octomap::key_type>(k & 0xffff));
    (v == 2 ? out.occupied_list : out.free_list).push_back(key);
  });
  return out;
}

void apply_rays(octomap::OcTree& tree, const PassRays& r) {
  // The tree is updated lazily (leaves only) and its inner nodes once at the end of the pass.
  for (const auto& k : r.free_list) tree.updateNode(k, false, true);
  for (const auto& k : r.occupied_list) tree.updateNode(k, true, true);
  tree.updateInnerOccupancy();
}

OccupancyAccumulator::OccupancyAccumulator(const OctoMapParams& p) {
  const octomap::OcTree model = make_octree(p);  // the tree's own float log-odds and thresholds
  hit_ = model.getProbHitLog();
  miss_ = model.getProbMissLog();
  min_ = model.getClampingThresMinLog();
  max_ = model.getClampingThresMaxLog();
}

void OccupancyAccumulator::update(const octomap::OcTreeKey& k, float delta) {
  float& v = logodds_[pack(k)];  // a new leaf starts at 0 (OcTreeNode's log-odds)
  // updateNode's early abort: a leaf at the threshold in the update's direction does not change.
  if ((delta >= 0 && v >= max_) || (delta <= 0 && v <= min_)) return;
  v += delta;  // updateNodeLogOdds
  if (v < min_) {
    v = min_;
    return;
  }
  if (v > max_) v = max_;
}

void OccupancyAccumulator::add(const PassRays& r) {
  for (const auto& k : r.free_list) update(k, miss_);
  for (const auto& k : r.occupied_list) update(k, hit_);
}

void OccupancyAccumulator::build(octomap::OcTree& tree) const {
  logodds_.for_each([&](std::uint64_t key, float v) {
    const octomap::OcTreeKey k(static_cast<octomap::key_type>(key >> 32), static_cast<octomap::key_type>((key >> 16) & 0xffff),
                               static_cast<octomap::key_type>(key & 0xffff));
    tree.setNodeValue(k, v, true);
  });
  tree.updateInnerOccupancy();
}

std::uint64_t insert_pass(octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p) {
  const PassRays r = cast_pass(tree, pass, p);
  apply_rays(tree, r);
  return r.rays;
}

std::set<std::tuple<int, int, int>> occupied_keys(const octomap::OcTree& tree) {
  std::set<std::tuple<int, int, int>> s;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const int size = static_cast<int>(std::lround(it.getSize() / tree.getResolution()));
    const octomap::OcTreeKey k = it.getKey();
    const int half = size / 2;
    for (int dx = 0; dx < size; ++dx)
      for (int dy = 0; dy < size; ++dy)
        for (int dz = 0; dz < size; ++dz) s.insert({k[0] - half + dx, k[1] - half + dy, k[2] - half + dz});
  }
  return s;
}

}  // namespace pcdp
