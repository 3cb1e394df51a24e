#include <gtest/gtest.h>

#include <random>
#include <unordered_map>

#include "pcdp/fusion/detail/flat_map.hpp"

using namespace pcdp;

TEST(FlatMap, BehavesLikeAMapOfKeysToValues) {
  FlatMap<int> m;
  std::unordered_map<std::uint64_t, int> ref;
  std::mt19937_64 rng(4);
  for (int i = 0; i < 100000; ++i) {
    const std::uint64_t k = rng() % 50000 * 977;  // repeats, and keys sharing low bits
    m[k] += i % 7;
    ref[k] += i % 7;
  }
  EXPECT_EQ(m.size(), ref.size());
  for (const auto& [k, v] : ref) {
    const int* f = m.find(k);
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(*f, v);
  }
  EXPECT_EQ(m.find(3), nullptr);
  std::size_t seen = 0;
  m.for_each([&](std::uint64_t k, int v) {
    ++seen;
    EXPECT_EQ(ref.at(k), v);
  });
  EXPECT_EQ(seen, ref.size());
}

TEST(FlatMap, FeedingOneTableFromAnotherNeedsDifferentSalts) {
  // A table iterated in its slot order and inserted into a table hashing alike piles the keys
  // into long probe runs (the run's OctoMap accumulator fed by a pass's cells took 13x longer);
  // a different salt keeps the probes per insert low. Voxel-like keys: x, y, z in 21-bit fields.
  FlatMap<char> source(7);
  for (std::uint64_t x = 0; x < 60; ++x)
    for (std::uint64_t y = 0; y < 60; ++y)
      for (std::uint64_t z = 0; z < 60; ++z) source[(x << 42) | (y << 21) | z] = 1;
  FlatMap<char> alike(7), salted(8);
  source.for_each([&](std::uint64_t k, char) {
    alike[k] = 1;
    salted[k] = 1;
  });
  const double n = static_cast<double>(source.size());
  EXPECT_LT(static_cast<double>(salted.probes()) / n, 2.0);
  EXPECT_GT(static_cast<double>(alike.probes()) / n, 10.0);  // what the salt is for
}
