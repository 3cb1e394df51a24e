// Per-stage speed (Google Benchmark, items_per_second = returns per second) on one pass of the
// benchmark setting A (241 beams x 75 lines, the sample's sensor), each stage on a copy of the pass
// as the stage before it left it. ->Threads(2) runs two copies at once: the per-core rate should
// hold if the stage scales (it shares nothing).
//   ./build/bench/pcdp_stage_bench --benchmark_min_time=0.5
#include <benchmark/benchmark.h>

#include <chrono>

#include "pcdp/pipeline/work_share.hpp"
#include "pcdp/fusion/elevation.hpp"
#include "pcdp/fusion/octomap_fusion.hpp"
#include "pcdp/core/pass.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/check_consistency.hpp"
#include "pcdp/stages/fuse_elevation.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/stages/reject_occlusion.hpp"

using namespace pcdp;

namespace {
struct Data {
  bench::Setting setting = bench::make_setting('A', 1);
  PoseTrack poses;
  Eigen::Isometry3d T_V_N;
  Pass raw, registered, occluded, mixed;
  /// wide: a footprint 3.4 beam steps wide (721 beams over 180 deg, 15 mrad), where
  /// reject_mixed_pixels runs its two extra rounds for runs of mixtures.
  explicit Data(bool wide = false) {
    if (wide) {
      setting.sim.scanner.beams = 721;
      setting.sim.scanner.beam_divergence = 0.015;
      setting.sensor.beam_divergence = 0.015;
    }
    setting.sim.passes = 1;
    const auto r = sim::simulate(setting.sim);
    poses = PoseTrack(r.poses);
    T_V_N = make_transform(setting.sim.mount_translation, setting.sim.mount_rpy, setting.sim.rpy_order);
    raw = r.passes[0].pass;
    registered = raw;
    register_pass(registered, RegisterParams{}, setting.sensor, T_V_N, &poses);
    occluded = registered;
    reject_occlusion(occluded, OcclusionParams{}, setting.sensor);
    mixed = occluded;
    reject_mixed_pixels(mixed, MixedPixelParams{}, setting.sensor);
  }
};
const Data& data() {
  static const Data d;
  return d;
}
const Data& wide_data() {
  static const Data d(true);
  return d;
}

template <class F>
void per_pass(benchmark::State& state, const Pass& input, F&& f) {
  for (auto _ : state) {
    state.PauseTiming();
    Pass p = input;
    state.ResumeTiming();
    f(p);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * input.size()));
}
}  // namespace

static void BM_Register(benchmark::State& state) {
  const Data& d = data();
  RegisterParams rp;
  rp.covariance = state.range(0) != 0;
  per_pass(state, d.raw, [&](Pass& p) { register_pass(p, rp, d.setting.sensor, d.T_V_N, &d.poses); });
}
BENCHMARK(BM_Register)->ArgName("covariance")->Arg(1)->Arg(0)->Threads(1)->Threads(2)->UseRealTime();

static void BM_RejectOcclusion(benchmark::State& state) {
  const Data& d = data();
  per_pass(state, d.registered, [&](Pass& p) { reject_occlusion(p, OcclusionParams{}, d.setting.sensor); });
}
BENCHMARK(BM_RejectOcclusion)->Threads(1)->Threads(2)->UseRealTime();

static void BM_RejectMixedPixels(benchmark::State& state) {
  const Data& d = data();
  per_pass(state, d.occluded, [&](Pass& p) { reject_mixed_pixels(p, MixedPixelParams{}, d.setting.sensor); });
}
BENCHMARK(BM_RejectMixedPixels)->Threads(1)->Threads(2)->UseRealTime();

static void BM_RejectMixedPixelsWideFootprint(benchmark::State& state) {
  const Data& d = wide_data();
  per_pass(state, d.occluded, [&](Pass& p) { reject_mixed_pixels(p, MixedPixelParams{}, d.setting.sensor); });
}
BENCHMARK(BM_RejectMixedPixelsWideFootprint)->Threads(1)->UseRealTime();

static void BM_CheckConsistencyCollect(benchmark::State& state) {
  const Data& d = data();
  const ConsistencyEvidence ev{ConsistencyParams{}};
  per_pass(state, d.mixed, [&](Pass& p) { benchmark::DoNotOptimize(ev.collect(p)); });
}
BENCHMARK(BM_CheckConsistencyCollect)->Threads(1)->Threads(2)->UseRealTime();

// The whole stage on four passes of setting A (as the pipeline runs it: every pass's evidence,
// finalize, then every pass labelled), on `threads` threads inside finalize.
static void BM_CheckConsistency(benchmark::State& state) {
  static const std::vector<Pass> passes = [] {
    bench::Setting s = bench::make_setting('A', 1);
    s.sim.passes = 4;
    const auto r = sim::simulate(s.sim);
    const PoseTrack poses(r.poses);
    const Eigen::Isometry3d T_V_N = make_transform(s.sim.mount_translation, s.sim.mount_rpy, s.sim.rpy_order);
    std::vector<Pass> out;
    for (const auto& sp : r.passes) {
      Pass p = sp.pass;
      register_pass(p, RegisterParams{}, s.sensor, T_V_N, &poses);
      reject_occlusion(p, OcclusionParams{}, s.sensor);
      reject_mixed_pixels(p, MixedPixelParams{}, s.sensor);
      out.push_back(std::move(p));
    }
    return out;
  }();
  std::size_t n = 0;
  for (const Pass& p : passes) n += p.size();
  double phase[3] = {0.0, 0.0, 0.0};
  for (auto _ : state) {
    state.PauseTiming();
    std::vector<Pass> work = passes;
    state.ResumeTiming();
    const auto t0 = std::chrono::steady_clock::now();
    ConsistencyEvidence ev{ConsistencyParams{}};
    for (const Pass& p : work) ev.add_pass(p);
    const auto t1 = std::chrono::steady_clock::now();
    ev.finalize(*WorkShare::threads(static_cast<unsigned>(state.range(0))));
    const auto t2 = std::chrono::steady_clock::now();
    for (Pass& p : work) benchmark::DoNotOptimize(ev.label(p));
    const auto t3 = std::chrono::steady_clock::now();
    phase[0] += std::chrono::duration<double>(t1 - t0).count();
    phase[1] += std::chrono::duration<double>(t2 - t1).count();
    phase[2] += std::chrono::duration<double>(t3 - t2).count();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  // Where the time goes, ms per run: the prepass's evidence, finalize, the labels.
  const double it = static_cast<double>(state.iterations());
  state.counters["evidence_ms"] = 1e3 * phase[0] / it;
  state.counters["finalize_ms"] = 1e3 * phase[1] / it;
  state.counters["label_ms"] = 1e3 * phase[2] / it;
}
BENCHMARK(BM_CheckConsistency)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);

static void BM_FuseElevation(benchmark::State& state) {
  const Data& d = data();
  FuseElevationParams fp;
  per_pass(state, d.mixed, [&](Pass& p) {
    ElevationGrid g(fp.resolution, fp.band, fp.min_support);
    fuse_pass(g, p, fp, 1e-4);
    benchmark::DoNotOptimize(g);
  });
}
BENCHMARK(BM_FuseElevation)->Threads(1)->Threads(2)->UseRealTime();

// The pipeline's case: one more pass into a grid that persists (here one that already holds the
// same area, as the passes of a run overlap), so its cells exist and only their sums change.
static void BM_FuseElevationIntoGrid(benchmark::State& state) {
  const Data& d = data();
  FuseElevationParams fp;
  ElevationGrid g(fp.resolution, fp.band, fp.min_support);
  fuse_pass(g, d.mixed, fp, 1e-4);
  per_pass(state, d.mixed, [&](Pass& p) {
    fuse_pass(g, p, fp, 1e-4);
    benchmark::DoNotOptimize(g);
  });
}
BENCHMARK(BM_FuseElevationIntoGrid)->UseRealTime();

static void BM_OctoMapCast(benchmark::State& state) {
  const Data& d = data();
  const OctoMapParams op;
  const octomap::OcTree tree = make_octree(op);
  per_pass(state, d.mixed, [&](Pass& p) { benchmark::DoNotOptimize(cast_pass(tree, p, op)); });
}
BENCHMARK(BM_OctoMapCast)->Threads(1)->Threads(2)->UseRealTime();

// The in-order part of fuse_octomap on one pass's cells (cast once, outside the timing).
template <class F>
void per_pass_cells(benchmark::State& state, F&& f) {
  const Data& d = data();
  const OctoMapParams op;
  const PassRays rays = cast_pass(make_octree(op), d.mixed, op);
  for (auto _ : state) f(op, rays);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * d.mixed.size()));
}

static void BM_OctoMapApply(benchmark::State& state) {
  per_pass_cells(state, [](const OctoMapParams& op, const PassRays& rays) {
    octomap::OcTree tree = make_octree(op);
    apply_rays(tree, rays);
    benchmark::DoNotOptimize(tree.size());
  });
}
BENCHMARK(BM_OctoMapApply)->UseRealTime();

static void BM_OctoMapAccumulateAndEncode(benchmark::State& state) {
  // What fuse_octomap does in pass order (add) and once at the end (encode map.bt), for one pass.
  per_pass_cells(state, [](const OctoMapParams& op, const PassRays& rays) {
    OccupancyAccumulator acc(op);
    acc.add(rays);
    benchmark::DoNotOptimize(acc.encode_binary().bytes.size());
  });
}
BENCHMARK(BM_OctoMapAccumulateAndEncode)->UseRealTime();

static void BM_OctoMapAccumulateAndBuild(benchmark::State& state) {
  // The same leaves put into OctoMap's tree (what map.ot still needs; map.bt came from it before).
  per_pass_cells(state, [](const OctoMapParams& op, const PassRays& rays) {
    OccupancyAccumulator acc(op);
    acc.add(rays);
    octomap::OcTree tree = make_octree(op);
    acc.build(tree);
    benchmark::DoNotOptimize(tree.size());
  });
}
BENCHMARK(BM_OctoMapAccumulateAndBuild)->UseRealTime();
