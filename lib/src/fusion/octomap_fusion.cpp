#include "pcdp/fusion/octomap_fusion.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/fusion/detail/voxel_blocks.hpp"

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

namespace {
// The cells of one pass: a bit per cell for free (traversed) and for occupied (an end point).
struct CellBlock {
  std::uint64_t free[8] = {}, occupied[8] = {};
};
// A pass is cast in up to kCastRanges ranges of at least kCastRangeMin returns (fewer for a small
// pass): enough for two threads to share the last pass of a run (1-2 ms a range on the bench's
// passes of 18 k returns), few enough that merging them costs nothing measurable.
constexpr std::size_t kCastRanges = 8, kCastRangeMin = 2048;

// A range's blocks in the order first touched (without the grid's directory, which may be large).
struct RangeCells {
  std::vector<std::uint64_t> keys;
  std::vector<CellBlock> blocks;
};

// The cells the kept rays of returns [begin, end) cross (free) and end in (occupied), a bit each,
// in 8^3 blocks (voxel_blocks.hpp) in the order first touched, found through a dense directory
// over the keys the rays can reach (a ray stays within its ends' keys).
RangeCells cast_range(const octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p, std::size_t begin,
                      std::size_t end, std::uint64_t& rays) {
  // The ray of return i: its origin and end point, the end cut at max_range (then not a hit).
  const auto ray_of = [&](std::size_t i, octomap::point3d& o, octomap::point3d& e) {
    o = octomap::point3d(static_cast<float>(pass.ox[i]), static_cast<float>(pass.oy[i]), static_cast<float>(pass.oz[i]));
    e = octomap::point3d(static_cast<float>(pass.x[i]), static_cast<float>(pass.y[i]), static_cast<float>(pass.z[i]));
    if (p.max_range > 0 && (e - o).norm() > p.max_range) {
      e = o + (e - o).normalized() * static_cast<float>(p.max_range);
      return false;
    }
    return true;
  };
  const auto cast = [&](std::size_t i) { return pass.is_kept(i) && std::isfinite(pass.x[i]) && std::isfinite(pass.ox[i]); };
  VoxelBounds bounds;
  for (std::size_t i = begin; i < end; ++i) {
    if (!cast(i)) continue;
    octomap::point3d o, e;
    ray_of(i, o, e);
    octomap::OcTreeKey ko, ke;
    if (!tree.coordToKeyChecked(o, ko) || !tree.coordToKeyChecked(e, ke)) continue;  // such a ray casts nothing
    bounds.add(ko[0], ko[1], ko[2]);
    bounds.add(ke[0], ke[1], ke[2]);
  }
  BlockGrid<CellBlock> cells(bounds, 0x5bd1e995u);  // another salt than OccupancyAccumulator's map, which it feeds
  BlockCursor<CellBlock> cursor(cells);
  const auto mark = [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, bool occupied) {
    CellBlock& b = cursor.at(x, y, z);
    const unsigned c = cell_of(x, y, z);
    (occupied ? b.occupied : b.free)[c >> 6] |= 1ull << (c & 63);
  };
  for (std::size_t i = begin; i < end; ++i) {
    if (!cast(i)) continue;
    octomap::point3d o, e;
    const bool hit = ray_of(i, o, e);
    ++rays;
    walk_ray_keys(tree, o, e, [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { mark(x, y, z, false); });
    octomap::OcTreeKey k;
    if (tree.coordToKeyChecked(e, k)) mark(k[0], k[1], k[2], hit);  // a cut end is free
  }
  RangeCells out;
  out.keys.reserve(cells.size());
  out.blocks.reserve(cells.size());
  for (std::size_t b = 0; b < cells.size(); ++b) {
    out.keys.push_back(cells.key(b));
    out.blocks.push_back(cells[b]);
  }
  return out;  // the directory is freed here, not held until every range is cast
}
}  // namespace

PassRays cast_pass(const octomap::OcTree& tree, const Pass& pass, const OctoMapParams& p, WorkShare& share) {
  // The returns in consecutive ranges, cast as tasks that idle threads may share (work_share.hpp),
  // then merged. A pass's cells are the union of its ranges' cells, occupied winning over free
  // in the union; and the blocks, taken range by range, each range's in the order it first touched
  // them, come in the order one cast of the whole pass first touches them. So the lists do not
  // depend on the ranges nor on who cast them (tested against one walk over the whole pass).
  const std::size_t n = pass.size();
  const std::size_t ranges = std::max<std::size_t>(1, std::min(kCastRanges, n / kCastRangeMin));
  std::vector<RangeCells> part(ranges);
  std::vector<std::uint64_t> rays(ranges, 0);
  share.run(ranges, [&](std::size_t r) { part[r] = cast_range(tree, pass, p, n * r / ranges, n * (r + 1) / ranges, rays[r]); });
  PassRays out;
  for (std::uint64_t r : rays) out.rays += r;
  // Each block's free-only cells, then its occupied ones, in cell order.
  const auto emit = [&](std::uint64_t key, const CellBlock& blk) {
    std::uint64_t free_only[8];
    for (int w = 0; w < 8; ++w) free_only[w] = blk.free[w] & ~blk.occupied[w];
    const auto push = [&](std::vector<octomap::OcTreeKey>& list, unsigned c) {
      std::uint32_t x, y, z;
      voxel_of({key, c}, x, y, z);
      list.emplace_back(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y), static_cast<octomap::key_type>(z));
    };
    for_each_bit(free_only, [&](unsigned c) { push(out.free_list, c); });
    for_each_bit(blk.occupied, [&](unsigned c) { push(out.occupied_list, c); });
  };
  if (ranges == 1) {
    for (std::size_t b = 0; b < part[0].keys.size(); ++b) emit(part[0].keys[b], part[0].blocks[b]);
    return out;
  }
  VoxelBounds bounds;  // the ranges' blocks span at most these voxels
  for (const RangeCells& rc : part)
    for (const std::uint64_t key : rc.keys) {
      std::uint32_t x, y, z;
      voxel_of({key, 0}, x, y, z);
      bounds.add(x, y, z);
    }
  BlockGrid<CellBlock> merged(bounds, 0x5bd1e995u);
  for (const RangeCells& rc : part)
    for (std::size_t b = 0; b < rc.keys.size(); ++b) {
      CellBlock& into = merged.block(rc.keys[b]);
      for (int w = 0; w < 8; ++w) {
        into.free[w] |= rc.blocks[b].free[w];
        into.occupied[w] |= rc.blocks[b].occupied[w];
      }
    }
  for (std::size_t b = 0; b < merged.size(); ++b) emit(merged.key(b), merged[b]);
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
  occupied_ = model.getOccupancyThresLog();
  resolution_ = model.getResolution();
}

void OccupancyAccumulator::add(const PassRays& r) {
  BlockCursor<LeafBlock> cursor(leaves_);  // the lists come block by block from cast_pass
  const auto update = [&](const octomap::OcTreeKey& k, float delta) {
    LeafBlock& b = cursor.at(k[0], k[1], k[2]);
    const unsigned c = cell_of(k[0], k[1], k[2]);
    std::uint64_t& word = b.present[c >> 6];
    const std::uint64_t bit = 1ull << (c & 63);
    cells_ += (word & bit) == 0;
    word |= bit;
    float& v = b.logodds[c];
    // updateNode's early abort: a leaf at the threshold in the update's direction does not change.
    if ((delta >= 0 && v >= max_) || (delta <= 0 && v <= min_)) return;
    v += delta;  // updateNodeLogOdds
    if (v < min_) {
      v = min_;
      return;
    }
    if (v > max_) v = max_;
  };
  for (const auto& k : r.free_list) update(k, miss_);
  for (const auto& k : r.occupied_list) update(k, hit_);
}

template <class F>
void OccupancyAccumulator::for_each_leaf(F&& f) const {
  for (std::size_t b = 0; b < leaves_.size(); ++b)
    for_each_bit(leaves_[b].present, [&](unsigned c) {
      std::uint32_t x, y, z;
      voxel_of({leaves_.key(b), c}, x, y, z);
      f(octomap::OcTreeKey(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y), static_cast<octomap::key_type>(z)),
        leaves_[b].logodds[c]);
    });
}

void OccupancyAccumulator::build(octomap::OcTree& tree) const {
  for_each_leaf([&](const octomap::OcTreeKey& k, float v) { tree.setNodeValue(k, v, true); });
  tree.updateInnerOccupancy();
}

namespace {
// Spreads the 16 bits of v to every third bit (bit b to bit 3 b) by shifts and masks.
std::uint64_t spread3(std::uint64_t v) {
  v &= 0xffff;
  v = (v | (v << 16)) & 0x0000ff0000ffull;
  v = (v | (v << 8)) & 0x00f00f00f00full;
  v = (v | (v << 4)) & 0x0c30c30c30c3ull;
  v = (v | (v << 2)) & 0x249249249249ull;
  return v;
}
// The octree's child index at depth d (0: the root's children) is bit (15 - d) of x, plus 2 times
// that of y, plus 4 times that of z. Interleaving the key bits, three per level, gives a code whose
// ascending order is the depth-first child order.
std::uint64_t morton(std::uint64_t x, std::uint64_t y, std::uint64_t z) { return spread3(x) | (spread3(y) << 1) | (spread3(z) << 2); }

constexpr int kTreeDepth = 16;

struct BinaryWriter {
  const std::vector<std::uint64_t>& codes;  // sorted Morton codes; bit 0: occupied
  std::string& out;
  std::size_t inner_nodes = 0;  // the root and every node above the leaves, one per call
  // The node covering codes[lo, hi) at depth d (all share their first 3 d bits).
  void node(std::size_t lo, std::size_t hi, int d) {
    ++inner_nodes;
    const int shift = 1 + 3 * (kTreeDepth - 1 - d);  // the child digit at depth d + 1 (above the flag bit)
    std::size_t begin[9];
    std::size_t i = lo;
    for (unsigned c = 0; c < 8; ++c) {
      begin[c] = i;
      while (i < hi && ((codes[i] >> shift) & 7) == c) ++i;
    }
    begin[8] = hi;
    unsigned char bytes[2] = {0, 0};
    const bool leaves = d + 1 == kTreeDepth;
    for (unsigned c = 0; c < 8; ++c) {
      if (begin[c] == begin[c + 1]) continue;  // 00: no such child
      // The child's two bits (bit 2c first): free leaf 1, occupied leaf 2, inner node 3.
      const unsigned bits = leaves ? ((codes[begin[c]] & 1) ? 2u : 1u) : 3u;
      bytes[c / 4] = static_cast<unsigned char>(bytes[c / 4] | (bits << (2 * (c % 4))));
    }
    out.push_back(static_cast<char>(bytes[0]));
    out.push_back(static_cast<char>(bytes[1]));
    if (leaves) return;
    for (unsigned c = 0; c < 8; ++c)
      if (begin[c] != begin[c + 1]) node(begin[c], begin[c + 1], d + 1);
  }
};
}  // namespace

OccupancyAccumulator::BinaryMap OccupancyAccumulator::encode_binary() const {
  // The blocks in Morton order (a few thousand to sort), each block's cells in Morton order (one
  // table): the leaves' codes come out sorted.
  std::vector<std::pair<std::uint64_t, std::size_t>> blocks(leaves_.size());
  for (std::size_t b = 0; b < leaves_.size(); ++b) {
    std::uint32_t x, y, z;
    voxel_of({leaves_.key(b), 0}, x, y, z);
    blocks[b] = {morton(x, y, z), b};  // the block's first cell: the block's code, 9 zero bits below
  }
  std::sort(blocks.begin(), blocks.end());
  static const std::array<std::pair<unsigned, unsigned>, 512> cells_in_order = [] {
    std::array<std::pair<unsigned, unsigned>, 512> t{};  // (Morton code within the block, cell)
    for (unsigned c = 0; c < 512; ++c) t[c] = {static_cast<unsigned>(morton(c & 7, (c >> 3) & 7, c >> 6)), c};
    std::sort(t.begin(), t.end());
    return t;
  }();
  std::vector<std::uint64_t> codes;
  codes.reserve(cells_);
  BinaryMap map;
  for (const auto& [code, b] : blocks) {
    const LeafBlock& blk = leaves_[b];
    for (const auto& [m, c] : cells_in_order) {
      if (!((blk.present[c >> 6] >> (c & 63)) & 1u)) continue;
      const bool occupied = blk.logodds[c] >= occupied_;  // OcTree::isNodeOccupied
      map.occupied_leaves += occupied;
      codes.push_back(((code | m) << 1) | (occupied ? 1u : 0u));
    }
  }
  // The tree is walked first: the header needs its node count (inner nodes and leaves).
  std::string body;
  std::size_t inner = 0;
  if (!codes.empty()) {
    BinaryWriter w{codes, body};
    w.node(0, codes.size(), 0);
    inner = w.inner_nodes;
  }
  map.nodes = inner + codes.size();
  std::ostringstream header;  // the text OcTree::writeBinaryConst writes
  header << "# Octomap OcTree binary file\n# (feel free to add / change comments, but leave the first line as it is!)\n#\n"
         << "id OcTree\nsize " << map.nodes << "\nres " << resolution_ << "\ndata\n";
  map.bytes = header.str() + body;
  return map;
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
