// Simulated scenes shared by the quality benchmarks: the sample scene's layout under two sensor
// settings, with the layout jittered by the seed.
#pragma once

#include <random>
#include <string>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/sim/nodding_sim.hpp"

namespace pcdp::bench {

struct Setting {
  std::string name;
  sim::SimConfig sim;
  SensorParams sensor;  ///< what the pipeline is told about the sensor
};

/// The sensor block that tells the pipeline a simulated scanner's true values (range
/// calibration inverted: the scanner reads n r + c, the pipeline corrects with k = 1 / n, b = -c / n).
inline SensorParams true_sensor(const sim::Scanner& s) {
  SensorParams p;
  p.range_min = s.range_min;
  p.range_max = s.range_max;
  p.beam_divergence = s.beam_divergence;
  p.transceiver_separation = s.transceiver_separation;
  p.transceiver_angle = s.mirror ? TransceiverAngle::kMirror : TransceiverAngle::kFixed;
  p.transceiver_angle_offset = s.transceiver_angle_offset;
  p.min_amplitude = s.min_amplitude;
  p.amplitude_saturation = 255.0;  // the simulator clamps amplitudes to 0..255
  p.range_sigma = s.range_sigma;
  p.range_k = 1.0 / s.range_n;
  p.range_b = -s.range_c / s.range_n;
  p.encoder_resolution = s.encoder_resolution;
  return p;
}

/// Setting "A": the sample's sensor (fixed transceiver angle, 8 cm separation, 8 mrad).
/// Setting "B": a mirror scanner (theta = bearing), 5 cm separation, 5 mrad, 181 beams over 180 deg.
inline Setting make_setting(char which, std::uint64_t seed) {
  sim::SimConfig c;
  std::mt19937_64 rng(seed * 7919 + static_cast<std::uint64_t>(which));
  std::uniform_real_distribution<double> j(-0.5, 0.5);
  auto& s = c.scanner;
  s.beams = 241;
  s.bearing_min = -1.2;
  s.bearing_max = 1.2;
  s.nod_min = -0.45;
  s.nod_max = 0.05;
  s.nod_rate = 1.0;
  s.encoder_resolution = 0.0012566;
  s.range_n = 0.9998;
  s.range_c = 0.0036;
  s.range_sigma = 0.0053;
  s.range_quantum = 0.001;
  s.beam_divergence = 0.008;
  s.subrays = 19;
  s.transceiver_separation = 0.08;
  s.amplitude_scale = 5000;
  s.amplitude_sigma = 2.0;
  s.min_amplitude = 18;
  s.false_range_probability = 0.4;
  if (which == 'B') {
    s.beams = 181;
    s.bearing_min = -1.5708;
    s.bearing_max = 1.5708;
    s.beam_divergence = 0.005;
    s.transceiver_separation = 0.05;
    s.mirror = true;
    s.false_range_probability = 0.6;
  }
  c.mount_translation = {0.5, 0.0, 1.64};
  c.mount_rpy = {0.0, 0.19775, 0.0};
  c.motion.speed = 1.0;
  c.motion.yaw_rate = 0.02;
  c.motion.follow_terrain = true;
  c.motion.roll_amplitude = 0.01;
  c.motion.pitch_amplitude = 0.01;
  c.motion.sway_frequency = 0.4;
  c.motion.position_sigma = 0.005;
  c.motion.rpy_sigma = 0.00035;
  c.scene.undulation_amplitude = 0.1;
  c.scene.undulation_wavelength = 12.0;
  c.scene.ground_reflectivity = 0.5;
  const auto box = [&](double x0, double y0, double x1, double y1, double top, double refl) {
    const double dx = j(rng), dy = j(rng);
    c.scene.boxes.push_back({{x0 + dx, y0 + dy, -0.2}, {x1 + dx, y1 + dy, top}, refl});
  };
  box(7.0, -2.5, 8.0, -1.0, 0.8, 0.05);
  box(9.0, 1.0, 10.2, 2.2, 1.1, 0.9);
  box(11.0, -0.6, 11.15, -0.45, 1.8, 0.5);
  box(12.5, 0.8, 12.65, 0.95, 1.8, 0.2);
  box(8.5, -4.0, 8.65, -3.85, 1.5, 0.1);
  box(13.5, -2.0, 13.65, -1.85, 1.5, 0.8);
  c.scene.boxes.push_back({{16.0, -8.0, -0.2}, {16.4, 8.0, 2.5}, 0.6});
  c.passes = 4;
  c.lines_per_pass = 75;
  c.t0 = 1000.0;
  c.seed = seed;

  return {std::string(1, which), c, true_sensor(s)};
}

}  // namespace pcdp::bench
