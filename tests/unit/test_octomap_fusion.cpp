#include <gtest/gtest.h>

#include <set>
#include <sstream>

#include "pcdp/octomap_fusion.hpp"
#include "pcdp/pass.hpp"
#include "pcdp/sim/bench_scenes.hpp"
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
}
