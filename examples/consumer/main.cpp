// Cleans a cloud the way a mapping stack would embed the library: a simulated nodding scan,
// registered, then mixed pixels removed through the library API. Prints what it did.
#include <cstdio>

#include "pcdp/pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"

int main() {
  pcdp::sim::SimConfig c;
  c.scene.boxes.push_back({{6.0, -1.0, -1.0}, {7.0, 1.0, 1.5}, 0.5});
  c.scanner.beam_divergence = 0.008;
  c.scanner.subrays = 7;
  c.lines_per_pass = 60;
  const auto run = pcdp::sim::simulate(c);
  const pcdp::PoseTrack poses(run.poses);
  pcdp::Pass pass = run.passes[0].pass;
  pcdp::SensorParams sensor;
  sensor.transceiver_separation = 0.0;
  pcdp::register_pass(pass, {}, sensor, pcdp::make_transform(c.mount_translation, c.mount_rpy, c.rpy_order), &poses);
  const std::size_t before = pass.kept();
  const std::size_t mixed = pcdp::reject_mixed_pixels(pass, {}, sensor);
  std::printf("consumer: %zu returns, %zu registered, %zu mixed pixels removed\n", pass.size(), before, mixed);
  return before > 0 ? 0 : 1;
}
