// A geometric nodding-laser simulator: a 2-D scanner nodding at a constant rate on a moving
// vehicle, ray-cast against flat/undulating terrain and boxes, with exact ground truth per return.
//
// This is the noise-free geometric core (beam = one ray). It writes passes and poses in the
// DESIGN.md contract so that every test of registration knows the true map point of every return.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/pass.hpp"
#include "pcdp/transforms.hpp"

namespace pcdp::sim {

struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Ones();
  double reflectivity = 0.5;  ///< 0..1
};

struct Scene {
  double ground_z = 0.0;
  double undulation_amplitude = 0.0;   ///< m: z = ground_z + a * sin(2 pi x / L) * cos(2 pi y / L)
  double undulation_wavelength = 10.0; ///< m
  double ground_reflectivity = 0.4;
  std::vector<Box> boxes;

  double terrain_height(double x, double y) const;
};

struct Scanner {
  int beams = 181;                    ///< returns per line
  double bearing_min = -1.5707963;    ///< rad, first beam
  double bearing_max = 1.5707963;     ///< rad, last beam
  double line_period = 0.0133;        ///< s, one sweep (SICK LMS 200: 13.3 ms)
  double nod_min = -0.5;              ///< rad
  double nod_max = 0.1;               ///< rad
  double nod_rate = 0.5;              ///< rad/s, constant-rate profile (triangle wave)
  double encoder_resolution = 0.0;    ///< rad; readings are quantized to this (0: exact)
  double range_max = 30.0;            ///< m: beyond this, no return (range 0)
  double range_sigma = 0.0;           ///< m, Gaussian range noise
  double amplitude_scale = 2000.0;    ///< amplitude = scale * reflectivity * cos(incidence) / r
};

struct Motion {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  ///< vehicle origin at t = 0 (z above ground_z)
  double speed = 1.0;                               ///< m/s along the initial heading
  double yaw = 0.0;                                 ///< rad, initial heading
  double yaw_rate = 0.0;                            ///< rad/s
  double roll_amplitude = 0.0, pitch_amplitude = 0.0;  ///< rad, sinusoidal sway
  double sway_frequency = 0.5;                      ///< Hz
  double pose_rate = 100.0;                         ///< Hz of the written pose file
};

struct SimConfig {
  Scene scene;
  Scanner scanner;
  Motion motion;
  Eigen::Vector3d mount_translation{0.5, 0.0, 1.0};
  Rpy mount_rpy{0.0, 0.2, 0.0};
  RpyOrder rpy_order = RpyOrder::kXyz;
  int passes = 1;
  int lines_per_pass = 100;
  double t0 = 0.0;  ///< stamp of the first return
  std::uint64_t seed = 1;
};

/// A simulated pass with ground truth.
struct SimPass {
  Pass pass;                                 ///< raw returns (range, bearing, amplitude, nod, stamp)
  std::vector<Eigen::Vector3d> true_point;   ///< true map point per return (NaN: no return)
  std::vector<float> true_nod;               ///< true nod angle at the return's stamp
};

struct SimResult {
  std::vector<SimPass> passes;
  std::vector<PoseSample> poses;  ///< T_M_V sampled at motion.pose_rate over the whole run
};

/// True vehicle pose T_M_V at time t.
Eigen::Isometry3d vehicle_pose(const SimConfig& cfg, double t);
/// True nod angle at time t (triangle wave between nod_min and nod_max, starting at nod_min).
double true_nod(const Scanner& s, double t);

SimResult simulate(const SimConfig& cfg);

/// Writes pass k as `dir/pass_%03d.pcd` (organized, binary) for every pass, and `dir/poses.csv`.
/// Returns the pass file paths.
std::vector<std::string> write_run(const SimResult& r, const SimConfig& cfg, const std::string& dir);

/// Writes the ground truth of every pass as `dir/truth/pass_%03d.pcd`: line beam x y z (true map
/// point, NaN without a return) nod (true nod at the return's stamp) label (truth label code:
/// 0 valid, 1 no return).
void write_truth(const SimResult& r, const std::string& dir);

/// Writes one raw pass as a PCD in the DESIGN.md contract (organized when every line has the
/// same number of returns). `data` is "binary" or "ascii".
void write_pass_pcd(const Pass& pass, const std::string& path);

/// Writes a pose CSV (stamp,x,y,z,roll,pitch,yaw in `order`).
void write_pose_csv(const std::vector<PoseSample>& poses, RpyOrder order, const std::string& path);

}  // namespace pcdp::sim
