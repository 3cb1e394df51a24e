// Simulation speed in returns per second (items_per_second), for the physical configuration of
// the sample scene and for the geometric core (one ray, no receiver check).
#include <benchmark/benchmark.h>

#include "pcdp/sim/nodding_sim.hpp"

using namespace pcdp;

namespace {
sim::SimConfig scene(int subrays, double separation) {
  sim::SimConfig c;
  c.scanner.beams = 241;
  c.scanner.bearing_min = -1.2;
  c.scanner.bearing_max = 1.2;
  c.scanner.nod_min = -0.45;
  c.scanner.nod_max = 0.05;
  c.scanner.nod_rate = 1.0;
  c.scanner.beam_divergence = subrays > 1 ? 0.008 : 0.0;
  c.scanner.subrays = subrays;
  c.scanner.transceiver_separation = separation;
  c.scanner.range_sigma = 0.0053;
  c.scanner.amplitude_scale = 5000;
  c.scanner.min_amplitude = 18;
  c.scene.undulation_amplitude = 0.1;
  c.scene.undulation_wavelength = 12.0;
  c.mount_translation = {0.5, 0, 1.64};
  c.mount_rpy = {0, 0.19775, 0};
  c.motion.follow_terrain = true;
  for (int i = 0; i < 6; ++i)
    c.scene.boxes.push_back({{7.0 + 1.5 * i, -3.0 + i, -0.2}, {7.5 + 1.5 * i, -2.0 + i, 1.2}, 0.1 + 0.15 * i});
  c.scene.boxes.push_back({{16.0, -8.0, -0.2}, {16.4, 8.0, 2.5}, 0.6});
  c.lines_per_pass = 75;
  return c;
}

void run(benchmark::State& state, const sim::SimConfig& c) {
  std::size_t returns = 0;
  for (auto _ : state) {
    const auto r = sim::simulate(c);
    returns += r.passes[0].pass.size();
    benchmark::DoNotOptimize(r.passes[0].pass.range.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(returns));
}
}  // namespace

static void BM_SimulatePhysical(benchmark::State& state) {
  run(state, scene(static_cast<int>(state.range(0)), 0.08));
}
BENCHMARK(BM_SimulatePhysical)->Arg(19)->Arg(7)->Unit(benchmark::kMillisecond);

static void BM_SimulateGeometric(benchmark::State& state) { run(state, scene(1, 0.0)); }
BENCHMARK(BM_SimulateGeometric)->Unit(benchmark::kMillisecond);
