#include <gtest/gtest.h>

#include <random>
#include <set>
#include <tuple>

#include "pcdp/fusion/detail/voxel_blocks.hpp"

using namespace pcdp;

namespace {
using Voxel = std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>;

// Walk-like inserts (runs of neighbouring voxels) plus scattered ones, some outside `b`.
std::vector<Voxel> voxels(std::uint32_t seed) {
  std::mt19937 gen(seed);
  const auto rng = [&] { return static_cast<std::uint32_t>(gen()); };
  std::vector<Voxel> v;
  for (int run = 0; run < 300; ++run) {
    std::uint32_t x = 1000 + rng() % 200, y = 5000 + rng() % 200, z = 7 + rng() % 40;
    for (int s = 0; s < 60; ++s) {
      v.emplace_back(x, y, z);
      const std::uint32_t a = rng() % 3;
      (a == 0 ? x : a == 1 ? y : z) += (rng() & 1) ? 1 : kVoxelCoordMask;  // +1 or -1, 21-bit wrap
      x &= kVoxelCoordMask, y &= kVoxelCoordMask, z &= kVoxelCoordMask;
    }
  }
  for (int i = 0; i < 2000; ++i) v.emplace_back(rng() & kVoxelCoordMask, rng() & kVoxelCoordMask, rng() & kVoxelCoordMask);
  v.emplace_back(0, 0, 0);
  v.emplace_back(kVoxelCoordMask, kVoxelCoordMask, kVoxelCoordMask);
  return v;
}
}  // namespace

TEST(VoxelBlocks, BlockPositionRoundTrips) {
  std::mt19937 gen(3);
  const auto rng = [&] { return static_cast<std::uint32_t>(gen()); };
  for (int i = 0; i < 10000; ++i) {
    const std::uint32_t x = rng() & kVoxelCoordMask, y = rng() & kVoxelCoordMask, z = rng() & kVoxelCoordMask;
    const BlockPos p = block_pos(x, y, z);
    ASSERT_LT(p.cell, 512u);
    std::uint32_t a, b, c;
    voxel_of(p, a, b, c);
    ASSERT_EQ(Voxel(a, b, c), Voxel(x, y, z));
  }
}

TEST(VoxelBlocks, VoxelSetIsASetOfVoxelsWithOrWithoutADirectory) {
  const std::vector<Voxel> in = voxels(5);
  const std::set<Voxel> ref(in.begin(), in.end());
  VoxelBounds bounds;  // the runs' region only: the scattered voxels fall outside it
  bounds.add(900, 4900, 0);
  bounds.add(1300, 5300, 100);
  VoxelSet hashed(7), directory(bounds, 7), tiny_directory(VoxelBounds{}, 7);
  VoxelSet cursor_set(bounds, 9);
  {
    VoxelSet::Cursor c(cursor_set);
    for (const auto& [x, y, z] : in) {
      hashed.insert(x, y, z);
      directory.insert(x, y, z);
      tiny_directory.insert(x, y, z);
      c.insert(x, y, z);
    }
  }
  for (const VoxelSet* s : {&hashed, &directory, &tiny_directory, &cursor_set}) {
    EXPECT_EQ(s->count(), ref.size());
    std::set<Voxel> seen;
    s->for_each([&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { EXPECT_TRUE(seen.insert({x, y, z}).second); });
    EXPECT_EQ(seen, ref);
    for (const auto& [x, y, z] : ref) ASSERT_TRUE(s->contains(x, y, z));
    EXPECT_FALSE(s->contains(1, 2, 3));
    EXPECT_FALSE(s->contains(1001, 5001, 99));
  }
  // The same inserts give the same iteration order (blocks first touched first).
  std::vector<Voxel> a, b;
  hashed.for_each([&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { a.emplace_back(x, y, z); });
  directory.for_each([&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { b.emplace_back(x, y, z); });
  EXPECT_EQ(a, b);
}

TEST(VoxelBlocks, DirectoryTooLargeFallsBackToHashing) {
  VoxelBounds all;
  all.add(0, 0, 0);
  all.add(kVoxelCoordMask, kVoxelCoordMask, kVoxelCoordMask);  // 2^54 blocks: no directory
  BlockGrid<BitBlock> g(all, 1);
  g.block(5, 6, 7).set(3);
  g.block(block_pos(8 * 5, 8 * 6, 8 * 7).block).set(4);  // the same block by its key
  ASSERT_EQ(g.size(), 1u);
  const BitBlock* b = g.find(block_pos(40, 48, 56).block);
  ASSERT_NE(b, nullptr);
  EXPECT_TRUE(b->test(3) && b->test(4) && !b->test(5));
  EXPECT_EQ(g.find(block_pos(0, 0, 0).block), nullptr);
}
