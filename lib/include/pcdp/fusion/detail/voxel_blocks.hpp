// Sparse voxel grids stored as dense 8 x 8 x 8 blocks, for the ray walks of check_consistency
// and fuse_octomap.
//
// Why blocks: a walk visits neighbouring voxels one after another. A hash set keyed by voxel
// scatters them over the whole table, so nearly every step is a cache miss once the table
// outgrows the cache (one pass of the benchmark setting walks 1.7 M steps over 173 k distinct
// voxels: 4.6 MB of hash table). Kept in blocks, the same voxels need 829 blocks of 64 bytes
// for a one-bit set (53 kB), and 8 successive steps mostly stay in one block, found again
// without a lookup. Blocks are kept in the order they were first touched, so iterating one is
// deterministic for a given sequence of inserts.
//
// Coordinates are voxel indices made non-negative, each below 2^21 (callers add an offset and
// mask).
//
// detail/: implementation that public fusion headers include for their members; not API, may
// change without notice (docs/architecture.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "pcdp/fusion/detail/flat_map.hpp"

namespace pcdp {

/// The block (its key) and the voxel within it (0-511: x fastest, then y, then z).
struct BlockPos {
  std::uint64_t block;
  unsigned cell;
};

inline constexpr std::uint32_t kVoxelCoordMask = (1u << 21) - 1;

/// The voxel's index within its block (x fastest, then y, then z).
inline unsigned cell_of(std::uint32_t x, std::uint32_t y, std::uint32_t z) { return (x & 7u) | ((y & 7u) << 3) | ((z & 7u) << 6); }

inline BlockPos block_pos(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  return {(static_cast<std::uint64_t>(x >> 3) << 42) | (static_cast<std::uint64_t>(y >> 3) << 21) | (z >> 3),
          cell_of(x, y, z)};
}

/// The voxel's coordinates from its block and cell (the inverse of block_pos).
inline void voxel_of(const BlockPos& p, std::uint32_t& x, std::uint32_t& y, std::uint32_t& z) {
  x = static_cast<std::uint32_t>(((p.block >> 42) & 0x3ffff) << 3) | (p.cell & 7u);
  y = static_cast<std::uint32_t>(((p.block >> 21) & 0x3ffff) << 3) | ((p.cell >> 3) & 7u);
  z = static_cast<std::uint32_t>((p.block & 0x3ffff) << 3) | (p.cell >> 6);
}

/// Voxel coordinate bounds, inclusive, of the voxels a grid will be given.
struct VoxelBounds {
  std::uint32_t lo[3] = {kVoxelCoordMask, kVoxelCoordMask, kVoxelCoordMask}, hi[3] = {0, 0, 0};
  void add(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    const std::uint32_t c[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = c[a] < lo[a] ? c[a] : lo[a];
      hi[a] = c[a] > hi[a] ? c[a] : hi[a];
    }
  }
};

template <class Block>
class BlockGrid {
 public:
  explicit BlockGrid(std::uint64_t salt = 0) : index_(salt) {}
  /// A grid that finds the blocks within `b` by a dense directory (an array index, no hashing)
  /// when the bounds span at most `max_directory` blocks, and by hashing otherwise. Voxels
  /// outside the bounds may still be given: they are hashed.
  BlockGrid(const VoxelBounds& b, std::uint64_t salt, std::size_t max_directory = std::size_t{1} << 22) : index_(salt) {
    std::size_t n = 1;
    for (int a = 0; a < 3; ++a) {
      if (b.hi[a] < b.lo[a]) return;  // empty bounds
      lo_[a] = b.lo[a] >> 3;
      n_[a] = (b.hi[a] >> 3) - lo_[a] + 1;
      n *= n_[a];
      if (n > max_directory) return;
    }
    dir_.assign(n, 0);
  }

  /// The block with block coordinates (voxel coordinates / 8), inserted value-initialised if
  /// absent. References stay valid as blocks are added (the blocks are never moved: large blocks
  /// copied on every growth of a vector cost 2 % of a run).
  Block& block(std::uint32_t bx, std::uint32_t by, std::uint32_t bz) {
    const std::uint64_t key = pack(bx, by, bz);
    std::uint32_t& slot = slot_of(bx, by, bz, key);  // position + 1; 0: new
    if (slot == 0) {
      blocks_.emplace_back();
      keys_.push_back(key);
      slot = static_cast<std::uint32_t>(blocks_.size());
    }
    return blocks_[slot - 1];
  }
  Block& block(std::uint64_t key) {
    return block(static_cast<std::uint32_t>(key >> 42), static_cast<std::uint32_t>((key >> 21) & 0x1fffff),
                 static_cast<std::uint32_t>(key & 0x1fffff));
  }
  /// nullptr when absent.
  const Block* find(std::uint64_t key) const {
    const std::uint32_t* slot = nullptr;
    const std::size_t i = dir_.empty() ? kOutside
                                       : dir_index(static_cast<std::uint32_t>(key >> 42), static_cast<std::uint32_t>((key >> 21) & 0x1fffff),
                                                   static_cast<std::uint32_t>(key & 0x1fffff));
    if (i != kOutside)
      slot = dir_[i] ? &dir_[i] : nullptr;
    else
      slot = index_.find(key);
    return slot ? &blocks_[*slot - 1] : nullptr;
  }

  std::size_t size() const { return blocks_.size(); }
  /// The i-th block's key (as block_pos gives it) and the block; i in the order first touched.
  std::uint64_t key(std::size_t i) const { return keys_[i]; }
  const Block& operator[](std::size_t i) const { return blocks_[i]; }

 private:
  static constexpr std::size_t kOutside = ~std::size_t{0};
  static std::uint64_t pack(std::uint32_t bx, std::uint32_t by, std::uint32_t bz) {
    return (static_cast<std::uint64_t>(bx) << 42) | (static_cast<std::uint64_t>(by) << 21) | bz;
  }
  std::size_t dir_index(std::uint32_t bx, std::uint32_t by, std::uint32_t bz) const {
    const std::uint32_t x = bx - lo_[0], y = by - lo_[1], z = bz - lo_[2];  // wrap: below lo is outside too
    if (x >= n_[0] || y >= n_[1] || z >= n_[2]) return kOutside;
    return (static_cast<std::size_t>(z) * n_[1] + y) * n_[0] + x;
  }
  std::uint32_t& slot_of(std::uint32_t bx, std::uint32_t by, std::uint32_t bz, std::uint64_t key) {
    if (!dir_.empty()) {
      const std::size_t i = dir_index(bx, by, bz);
      if (i != kOutside) return dir_[i];
    }
    return index_[key];
  }

  FlatMap<std::uint32_t> index_;
  std::vector<std::uint32_t> dir_;  // dense directory over the bounds (empty: hash only)
  std::uint32_t lo_[3] = {0, 0, 0}, n_[3] = {0, 0, 0};
  std::vector<std::uint64_t> keys_;
  std::deque<Block> blocks_;  // the last block touched is remembered by a BlockCursor, not here
};

/// Finds blocks of one grid, keeping the current block in the cursor itself: a walk that stays
/// in one block reaches it without a lookup. Use it as a local variable (then it lives in
/// registers; a block pointer kept in the grid would be reloaded after every store to a block).
template <class Block>
class BlockCursor {
 public:
  explicit BlockCursor(BlockGrid<Block>& g) : grid_(g) {}
  /// The block holding voxel (x, y, z), inserted if absent.
  Block& at(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    const std::uint64_t k = (static_cast<std::uint64_t>(x >> 3) << 42) | (static_cast<std::uint64_t>(y >> 3) << 21) | (z >> 3);
    if (k != key_) {
      block_ = &grid_.block(x >> 3, y >> 3, z >> 3);
      key_ = k;
    }
    return *block_;
  }

 private:
  BlockGrid<Block>& grid_;
  Block* block_ = nullptr;
  std::uint64_t key_ = ~0ull;
};

/// One bit per voxel of a block.
struct BitBlock {
  std::uint64_t w[8] = {};
  void set(unsigned cell) { w[cell >> 6] |= 1ull << (cell & 63); }
  bool test(unsigned cell) const { return (w[cell >> 6] >> (cell & 63)) & 1u; }
};

/// Calls f(cell) for every set bit of the 8 words `w`, in ascending cell order.
template <class F>
void for_each_bit(const std::uint64_t (&w)[8], F&& f) {
  for (unsigned i = 0; i < 8; ++i)
    for (std::uint64_t b = w[i]; b != 0; b &= b - 1) f(64 * i + static_cast<unsigned>(__builtin_ctzll(b)));
}

/// A set of voxels.
class VoxelSet {
 public:
  explicit VoxelSet(std::uint64_t salt = 0) : grid_(salt) {}
  /// A set for voxels mostly within `b` (see BlockGrid).
  VoxelSet(const VoxelBounds& b, std::uint64_t salt) : grid_(b, salt) {}
  void insert(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    grid_.block(x >> 3, y >> 3, z >> 3).set(cell_of(x, y, z));
  }
  /// Inserts like insert(), through a BlockCursor (see there).
  class Cursor {
   public:
    explicit Cursor(VoxelSet& s) : cursor_(s.grid_) {}
    void insert(std::uint32_t x, std::uint32_t y, std::uint32_t z) { cursor_.at(x, y, z).set(cell_of(x, y, z)); }

   private:
    BlockCursor<BitBlock> cursor_;
  };
  bool contains(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
    const BlockPos p = block_pos(x, y, z);
    const BitBlock* b = grid_.find(p.block);
    return b && b->test(p.cell);
  }
  /// Number of voxels in the set.
  std::size_t count() const {
    std::size_t n = 0;
    for (std::size_t i = 0; i < grid_.size(); ++i)
      for (const std::uint64_t w : grid_[i].w) n += static_cast<std::size_t>(__builtin_popcountll(w));
    return n;
  }
  const BlockGrid<BitBlock>& blocks() const { return grid_; }
  /// f(x, y, z) for every voxel: blocks in the order first touched, voxels in cell order.
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t i = 0; i < grid_.size(); ++i)
      for_each_bit(grid_[i].w, [&](unsigned c) {
        std::uint32_t x, y, z;
        voxel_of({grid_.key(i), c}, x, y, z);
        f(x, y, z);
      });
  }

 private:
  BlockGrid<BitBlock> grid_;
};

}  // namespace pcdp
