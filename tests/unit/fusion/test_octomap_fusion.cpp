#include <gtest/gtest.h>

#include <bitset>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <sstream>

#include "pipeline/ordered_parallel.hpp"
#include "pcdp/fusion/octomap_fusion.hpp"
#include "pcdp/core/pass.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/register.hpp"

using namespace pcdp;

namespace {
std::vector<Pass> static_vehicle_passes() {
  bench::Setting st = bench::make_setting('A', 1);
  st.sim.motion.speed = 0.0;  // one sensor origin per pass: insertPointCloud sees the same rays
  st.sim.motion.roll_amplitude = st.sim.motion.pitch_amplitude = 0.0;
  st.sim.passes = 2;
  const auto r = sim::simulate(st.sim);
  const PoseTrack poses(r.true_poses);
  std::vector<Pass> out;
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, RegisterParams{}, st.sensor,
                  make_transform(st.sim.mount_translation, st.sim.mount_rpy, st.sim.rpy_order), &poses);
    out.push_back(std::move(p));
  }
  return out;
}
}  // namespace

TEST(OctoMapFusion, AgreesWithInsertPointCloudFedTheSameRays) {
  const auto passes = static_vehicle_passes();
  OctoMapParams prm;
  prm.max_range = 30.0;
  octomap::OcTree ours = make_octree(prm), theirs = make_octree(prm);
  for (const auto& p : passes) {
    insert_pass(ours, p, prm);
    octomap::Pointcloud cloud;
    octomap::point3d origin;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (!p.is_kept(i) || !std::isfinite(p.x[i])) continue;
      cloud.push_back(static_cast<float>(p.x[i]), static_cast<float>(p.y[i]), static_cast<float>(p.z[i]));
      origin = octomap::point3d(static_cast<float>(p.ox[i]), static_cast<float>(p.oy[i]), static_cast<float>(p.oz[i]));
    }
    theirs.insertPointCloud(cloud, origin, prm.max_range);
  }
  const auto a = occupied_keys(ours), b = occupied_keys(theirs);
  std::size_t common = 0;
  for (const auto& k : b) common += a.count(k);
  std::cout << "occupied keys: ours " << a.size() << ", insertPointCloud " << b.size() << ", common " << common << "\n";
  ASSERT_GT(b.size(), 1000u);
  EXPECT_GE(static_cast<double>(common), 0.99 * static_cast<double>(b.size()));
  EXPECT_GE(static_cast<double>(common), 0.99 * static_cast<double>(a.size()));
}

TEST(OctoMapFusion, InsertingLineByLineLosesOccupiedCells) {
  const auto passes = static_vehicle_passes();
  OctoMapParams prm;
  octomap::OcTree batched = make_octree(prm), by_line = make_octree(prm);
  for (const auto& p : passes) {
    insert_pass(batched, p, prm);
    for (std::size_t k = 0; k < p.line_count(); ++k) {  // the same rays, one line at a time
      Pass line = p;
      for (std::size_t i = 0; i < p.size(); ++i)
        if (i < p.line_begin[k] || i >= p.line_begin[k + 1]) line.label[i] = Label::kOutlier;
      insert_pass(by_line, line, prm);
    }
  }
  const double nb = static_cast<double>(occupied_keys(batched).size()), nl = static_cast<double>(occupied_keys(by_line).size());
  std::cout << "occupied keys: batched per pass " << nb << ", line by line " << nl << " (" << 100 * (1 - nl / nb)
            << " % lost)\n";
  EXPECT_LT(nl, 0.9 * nb);
}

TEST(OctoMapFusion, AccumulatedLogOddsBuildTheTreeThatPassByPassUpdatesBuild) {
  // fuse_octomap accumulates each leaf's clamped log-odds in a flat map and builds the tree once;
  // updating the tree pass by pass (apply_rays) must give the same leaves, values and file. Tight
  // clamping makes the thresholds and the early abort matter.
  const auto passes = static_vehicle_passes();
  OctoMapParams p;
  p.clamping_min = 0.3;
  p.clamping_max = 0.8;
  octomap::OcTree direct = make_octree(p), built = make_octree(p);
  OccupancyAccumulator acc(p);
  for (int round = 0; round < 3; ++round)  // the same passes again: leaves reach the thresholds
    for (const auto& pass : passes) {
      const PassRays r = cast_pass(direct, pass, p);
      apply_rays(direct, r);
      acc.add(r);
    }
  acc.build(built);
  ASSERT_GT(acc.cells(), 1000u);
  EXPECT_EQ(direct.size(), built.size());
  std::size_t leaves = 0, at_max = 0;
  for (auto it = direct.begin_leafs(), end = direct.end_leafs(); it != end; ++it) {
    const octomap::OcTreeNode* n = built.search(it.getKey());
    ASSERT_NE(n, nullptr);
    EXPECT_EQ(n->getLogOdds(), it->getLogOdds());
    ++leaves;
    at_max += it->getLogOdds() == direct.getClampingThresMaxLog();
  }
  EXPECT_EQ(leaves, acc.cells());
  EXPECT_GT(at_max, 100u);  // the clamping was exercised
  std::ostringstream a, b;
  direct.writeBinaryConst(a);
  built.writeBinaryConst(b);
  EXPECT_TRUE(a.str() == b.str());
  // fuse_octomap writes map.bt without building the tree: the same bytes, node and occupied counts.
  const OccupancyAccumulator::BinaryMap enc = acc.encode_binary();
  EXPECT_TRUE(enc.bytes == a.str());
  EXPECT_EQ(enc.nodes, direct.size());
  std::size_t occupied = 0;
  for (auto it = direct.begin_leafs(), end = direct.end_leafs(); it != end; ++it) occupied += direct.isNodeOccupied(*it);
  EXPECT_EQ(enc.occupied_leaves, occupied);
}

TEST(OctoMapFusion, EncodedBinaryIsOctoMapsOwnFileForAnyLeaves) {
  // Keys at both ends of the key space and in dense clusters (siblings at every depth), a leaf
  // exactly at the occupancy threshold (occupied: OctoMap uses >=), an odd resolution (the header's
  // number format), and an empty map.
  OctoMapParams p;
  p.resolution = 0.123456789;
  p.prob_miss = 0.4;
  p.occupancy_threshold = 0.4;  // a leaf missed once sits exactly at the threshold
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> any(0, 65535), near(-3, 3);
  PassRays r;
  std::set<std::tuple<int, int, int>> used;
  const auto put = [&](int x, int y, int z, bool hit) {
    if (x < 0 || y < 0 || z < 0 || x > 65535 || y > 65535 || z > 65535 || !used.insert({x, y, z}).second) return;
    using K = octomap::key_type;
    (hit ? r.occupied_list : r.free_list).push_back(octomap::OcTreeKey(static_cast<K>(x), static_cast<K>(y), static_cast<K>(z)));
  };
  for (int c = 0; c < 40; ++c) {
    const int cx = any(rng), cy = any(rng), cz = any(rng);
    for (int k = 0; k < 60; ++k) put(cx + near(rng), cy + near(rng), cz + near(rng), k % 3 == 0);
  }
  for (int x : {0, 65535})
    for (int y : {0, 65535})
      for (int z : {0, 65535}) put(x, y, z, (x + y + z) % 2 == 0);
  OccupancyAccumulator acc(p);
  acc.add(r);
  octomap::OcTree tree = make_octree(p);
  acc.build(tree);
  std::ostringstream want;
  tree.writeBinaryConst(want);
  const OccupancyAccumulator::BinaryMap enc = acc.encode_binary();
  ASSERT_GT(r.free_list.size(), 1000u);
  EXPECT_TRUE(enc.bytes == want.str()) << "sizes " << enc.bytes.size() << " vs " << want.str().size();
  EXPECT_EQ(enc.nodes, tree.size());
  EXPECT_EQ(enc.occupied_leaves, r.free_list.size() + r.occupied_list.size());  // every leaf >= the threshold
  // It reads back as the same tree.
  std::istringstream in(enc.bytes);
  octomap::OcTree back(0.1);
  ASSERT_TRUE(back.readBinary(in));
  EXPECT_EQ(back.size(), tree.size());
  EXPECT_DOUBLE_EQ(back.getResolution(), 0.123457);  // the format's header keeps 6 digits (OctoMap's own writer too)

  OccupancyAccumulator none(p);
  octomap::OcTree empty = make_octree(p);
  std::ostringstream empty_file;
  empty.writeBinaryConst(empty_file);
  EXPECT_TRUE(none.encode_binary().bytes == empty_file.str());
  EXPECT_EQ(none.encode_binary().nodes, 0u);
}

TEST(OctoMapFusion, RayWalkGivesComputeRayKeysKeysInOrder) {
  // walk_ray_keys replaces computeRayKeys in cast_pass: every key and its order must agree, on
  // rays of every kind (random, axis-aligned, diagonal, within one cell, ends on cell
  // boundaries, one end outside the tree), at two resolutions.
  for (const double res : {0.1, 0.037}) {
    octomap::OcTree tree(res);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-20.0f, 20.0f);
    std::vector<std::pair<octomap::point3d, octomap::point3d>> rays;
    for (int i = 0; i < 3000; ++i) rays.push_back({{u(rng), u(rng), u(rng) * 0.1f}, {u(rng), u(rng), u(rng) * 0.1f}});
    const octomap::point3d o(0.31f, -1.2f, 0.5f);
    for (int a = 0; a < 3; ++a)
      for (const float d : {-7.3f, 4.0f}) {
        octomap::point3d e = o;
        e(a) += d;
        rays.push_back({o, e});  // along one axis
      }
    rays.push_back({o, o + octomap::point3d(3.0f, 3.0f, 3.0f)});               // through cell corners
    rays.push_back({o, o + octomap::point3d(0.01f, 0.0f, 0.01f)});             // one cell
    rays.push_back({{0.0f, 0.0f, 0.0f}, {static_cast<float>(res) * 30, 0.0f, 0.0f}});  // boundary to boundary
    rays.push_back({o, {1e6f, 0.0f, 0.0f}});                                  // end outside the tree
    // Cell centre to cell centre by small whole numbers of cells: boundaries crossed at once on
    // two or three axes, or within rounding of each other, where the tie rule and the arithmetic
    // decide the cells.
    std::uniform_int_distribution<int> cell(-12, 12);
    for (int i = 0; i < 3000; ++i) {
      const octomap::OcTreeKey k0(static_cast<octomap::key_type>(32768 + cell(rng)), static_cast<octomap::key_type>(32768 + cell(rng)),
                                  static_cast<octomap::key_type>(32768 + cell(rng)));
      const octomap::OcTreeKey k1(static_cast<octomap::key_type>(k0[0] + cell(rng)), static_cast<octomap::key_type>(k0[1] + cell(rng)),
                                  static_cast<octomap::key_type>(k0[2] + cell(rng)));
      rays.push_back({tree.keyToCoord(k0), tree.keyToCoord(k1)});
    }
    octomap::KeyRay expected;
    std::size_t compared = 0;
    for (const auto& [a, b] : rays) {
      std::vector<octomap::OcTreeKey> got;
      const bool ok = walk_ray_keys(tree, a, b, [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
        got.emplace_back(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y), static_cast<octomap::key_type>(z));
      });
      ASSERT_EQ(ok, tree.computeRayKeys(a, b, expected)) << a << " -> " << b;
      if (!ok) {
        EXPECT_TRUE(got.empty());
        continue;
      }
      ASSERT_EQ(got.size(), expected.size()) << a << " -> " << b;
      std::size_t i = 0;
      for (const auto& k : expected) ASSERT_EQ(got[i++], k) << a << " -> " << b << " key " << i - 1;
      compared += got.size();
    }
    EXPECT_GT(compared, 3000u * 100u);  // the random rays are long: a real comparison
  }
}

namespace {
// Runs the tasks last to first: as if other threads had taken the first ones.
class ReversedShare final : public WorkShare {
 public:
  std::size_t tasks = 0;
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    tasks += n;
    for (std::size_t i = n; i-- > 0;) task(i);
  }
};
}  // namespace

TEST(OctoMapFusion, CastListsTheSameCellsInTheSameOrderWhoeverCastsTheRanges) {
  // cast_pass hands ranges of returns to a WorkShare and merges them. The lists must be those of
  // one walk over every ray in return order: the blocks in the order that walk first touches
  // them, each block's free-only cells, then its occupied ones, in cell order (the reference
  // below, a map instead of blocks). Serial, reversed and on two threads alike.
  const Pass pass = static_vehicle_passes().front();
  ASSERT_GE(pass.size(), 4u * 2048u);  // several ranges
  OctoMapParams prm;
  const octomap::OcTree tree = make_octree(prm);

  std::vector<std::uint64_t> order;  // blocks as first touched
  std::map<std::uint64_t, std::pair<std::bitset<512>, std::bitset<512>>> bits;  // free, occupied
  std::uint64_t rays = 0;
  const auto mark = [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, bool occupied) {
    const BlockPos b = block_pos(x, y, z);
    auto [it, fresh] = bits.try_emplace(b.block);
    if (fresh) order.push_back(b.block);
    (occupied ? it->second.second : it->second.first).set(b.cell);
  };
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.x[i]) || !std::isfinite(pass.ox[i])) continue;
    const octomap::point3d o(static_cast<float>(pass.ox[i]), static_cast<float>(pass.oy[i]), static_cast<float>(pass.oz[i]));
    const octomap::point3d e(static_cast<float>(pass.x[i]), static_cast<float>(pass.y[i]), static_cast<float>(pass.z[i]));
    ++rays;
    walk_ray_keys(tree, o, e, [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { mark(x, y, z, false); });
    octomap::OcTreeKey k;
    if (tree.coordToKeyChecked(e, k)) mark(k[0], k[1], k[2], true);
  }
  std::vector<octomap::OcTreeKey> free_ref, occupied_ref;
  for (const std::uint64_t b : order) {
    const auto& [fr, oc] = bits.at(b);
    for (unsigned c = 0; c < 512; ++c) {
      std::uint32_t x, y, z;
      voxel_of({b, c}, x, y, z);
      const octomap::OcTreeKey k(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y), static_cast<octomap::key_type>(z));
      if (fr[c] && !oc[c]) free_ref.push_back(k);
    }
    for (unsigned c = 0; c < 512; ++c) {
      std::uint32_t x, y, z;
      voxel_of({b, c}, x, y, z);
      if (oc[c]) occupied_ref.emplace_back(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y), static_cast<octomap::key_type>(z));
    }
  }
  ASSERT_GT(free_ref.size(), 10000u);
  ASSERT_GT(occupied_ref.size(), 1000u);

  ReversedShare reversed;
  std::vector<PassRays> got;
  got.push_back(cast_pass(tree, pass, prm));
  got.push_back(cast_pass(tree, pass, prm, reversed));
  EXPECT_GT(reversed.tasks, 1u);
  detail::ordered_parallel<int>(
      2, 2, 2,
      [&](std::size_t k, WorkShare& share) {
        if (k == 1) got.push_back(cast_pass(tree, pass, prm, share));  // item 0 ends at once: its worker helps
        return 0;
      },
      [](std::size_t, int) {});
  ASSERT_EQ(got.size(), 3u);
  for (std::size_t g = 0; g < got.size(); ++g) {
    EXPECT_EQ(got[g].rays, rays) << g;
    EXPECT_TRUE(got[g].free_list == free_ref) << g;
    EXPECT_TRUE(got[g].occupied_list == occupied_ref) << g;
  }
}
