// fuse_octomap's batched insertion against OctoMap's own insertPointCloud on the same rays (a
// static vehicle, so one sensor origin per pass), 0.1 m resolution, 30 m range. Prints the times,
// the ratio and the agreement of the occupied keys; several repetitions, median.
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "pcdp/fusion/octomap_fusion.hpp"
#include "pcdp/core/pass.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/register.hpp"

using namespace pcdp;
using Clock = std::chrono::steady_clock;

int main() {
  bench::Setting st = bench::make_setting('A', 1);
  st.sim.motion.speed = 0.0;
  st.sim.motion.roll_amplitude = st.sim.motion.pitch_amplitude = 0.0;
  const auto r = sim::simulate(st.sim);
  const PoseTrack poses(r.true_poses);
  std::vector<Pass> passes;
  std::vector<octomap::Pointcloud> clouds;
  std::vector<octomap::point3d> origins;
  std::size_t rays = 0;
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, RegisterParams{}, st.sensor,
                  make_transform(st.sim.mount_translation, st.sim.mount_rpy, st.sim.rpy_order), &poses);
    octomap::Pointcloud c;
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (!p.is_kept(i) || !std::isfinite(p.x[i])) continue;
      c.push_back(static_cast<float>(p.x[i]), static_cast<float>(p.y[i]), static_cast<float>(p.z[i]));
      origins.resize(passes.size() + 1, octomap::point3d(static_cast<float>(p.ox[i]), static_cast<float>(p.oy[i]),
                                                         static_cast<float>(p.oz[i])));
      ++rays;
    }
    clouds.push_back(c);
    passes.push_back(std::move(p));
  }
  OctoMapParams prm;
  prm.max_range = 30.0;
  std::vector<double> t_ours, t_theirs, t_lazy;
  std::size_t occ_ours = 0, occ_theirs = 0, common = 0;
  for (int rep = 0; rep < 3; ++rep) {
    octomap::OcTree ours = make_octree(prm), theirs = make_octree(prm);
    auto t0 = Clock::now();
    for (const auto& p : passes) insert_pass(ours, p, prm);
    t_ours.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    t0 = Clock::now();
    for (std::size_t k = 0; k < clouds.size(); ++k) theirs.insertPointCloud(clouds[k], origins[k], prm.max_range);
    t_theirs.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    octomap::OcTree lazy = make_octree(prm);
    t0 = Clock::now();
    for (std::size_t k = 0; k < clouds.size(); ++k) lazy.insertPointCloud(clouds[k], origins[k], prm.max_range, true);
    lazy.updateInnerOccupancy();
    t_lazy.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    if (rep == 0) {
      // Finest keys on both sides: pruned leaves are expanded, so the counts compare cell for cell.
      const auto mine = occupied_keys(ours), their_keys = occupied_keys(theirs);
      occ_ours = mine.size();
      occ_theirs = their_keys.size();
      for (const auto& k : their_keys) common += mine.count(k);
    }
  }
  std::sort(t_ours.begin(), t_ours.end());
  std::sort(t_theirs.begin(), t_theirs.end());
  std::sort(t_lazy.begin(), t_lazy.end());
  const double a = t_ours[1], b = t_theirs[1], c = t_lazy[1];
  const double n = static_cast<double>(rays);
  std::printf("OctoMap insertion, %zu rays in %zu passes, 0.1 m, 30 m range (median of 3):\n", rays, passes.size());
  std::printf("  fuse_octomap (batched, per-return origins)      %8.3f s  %10.0f rays/s\n", a, n / a);
  std::printf("  OctoMap insertPointCloud (defaults)             %8.3f s  %10.0f rays/s  (%.2fx ours)\n", b, n / b, b / a);
  std::printf("  OctoMap insertPointCloud (lazy_eval + update)   %8.3f s  %10.0f rays/s  (%.2fx ours)\n", c, n / c, c / a);
  std::printf("  occupied leaves: ours %zu, insertPointCloud %zu, common %zu (%.2f %% of insertPointCloud's)\n", occ_ours,
              occ_theirs, common, 100.0 * static_cast<double>(common) / static_cast<double>(occ_theirs));
  return 0;
}
