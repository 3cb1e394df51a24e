// A physical nodding-LADAR simulator with ground truth (issue: simulator).
//
// A 2-D scanner nods on a vehicle that drives over a height-field terrain among boxes (boxes,
// walls, steps, kerbs, table tops; each may be turned about the vertical) and vertical cylinders
// (posts). Each effect is configurable and documented with its source:
//  - finite beam footprint: every beam is `subrays` rays spread uniformly over the divergence
//    cone (full angle alpha), each carrying an equal share of the power (Liu et al. 2005,
//    assumption 1: power uniform over the cross-section);
//  - non-coaxial receiver: the receiver sits `transceiver_separation` (s - q) from the
//    transmitter, perpendicular to the beam at the transceiver angle theta (0: in the scan plane,
//    "separated"; 90 deg: across it, "coaxial" for edges crossed by the scan). Light from a lit
//    point that the scene hides from the receiver is lost (Liu et al. section 4);
//  - amplitude: each visible sub-ray returns scale * reflectivity * cos(incidence) / d^p; the
//    reported amplitude is the sum plus Gaussian noise, clamped to 0..255 (Liu et al. section 3);
//  - minimum detectable amplitude: below it the sensor reads no return (0) or, with probability
//    `false_range_probability`, a false arbitrary range (Liu et al. sections 3-4);
//  - mixed pixels: a footprint split over surfaces returns the power-weighted mean range
//    (Ye & Borenstein 4.5: "a combination of the foreground and background"); truth calls it a
//    mixed pixel when the footprint lit two or more objects and the range is more than
//    mixed_pixel_tolerance from the depth interval each object's lit part spans;
//  - range model: z = Int_mm(n y + c + xi), xi ~ N(0, sigma) (Ye & Borenstein eq. 6);
//  - nodding: constant rate (Broten & Collier 4.1) or uniform sample distance with vehicle-motion
//    compensation (4.2, 5.1) limited by the maximum rate, the dead zone (5.2) and the encoder
//    resolution; the encoder is read at the end of each line (3.2);
//  - vehicle: follows the terrain (height, pitch and roll from its slope) plus sway; the written
//    pose file has Gaussian position and roll/pitch/yaw noise.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp::sim {

/// A box: [min, max] in its own frame, turned by `yaw` (rad, counter-clockwise seen from above)
/// about the vertical axis through the centre of its footprint; yaw 0 is axis-aligned, so its
/// edges can run oblique to the scan lines.
struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Ones();
  double reflectivity = 0.5;  ///< 0..1
  double yaw = 0.0;           ///< rad, about z through ((min + max) / 2).xy
  /// Whether the map point (x, y) lies inside the box's footprint.
  bool covers(double x, double y) const;
};

/// A vertical cylinder (a post, pole or table leg): axis at (x, y), from z_min to z_max.
struct Post {
  double x = 0.0, y = 0.0;
  double radius = 0.05;  ///< m
  double z_min = 0.0, z_max = 1.0;
  double reflectivity = 0.5;  ///< 0..1
};

struct Scene {
  double ground_z = 0.0;
  double undulation_amplitude = 0.0;    ///< m: z = ground_z + a * sin(2 pi x / L) * cos(2 pi y / L)
  double undulation_wavelength = 10.0;  ///< m
  double ground_reflectivity = 0.4;
  std::vector<Box> boxes;
  std::vector<Post> posts;  ///< object ids follow the boxes': post k is object boxes.size() + k

  double terrain_height(double x, double y) const;
  /// Top-surface height at (x, y): the highest box or post top covering it, else the terrain.
  double top_height(double x, double y) const;
};

enum class NodProfile { kConstantRate, kUniformDistance };

struct Scanner {
  int beams = 181;                    ///< returns per line
  double bearing_min = -1.5707963;    ///< rad, first beam
  double bearing_max = 1.5707963;     ///< rad, last beam
  double line_period = 0.0133;        ///< s, one sweep (SICK LMS 200: 13.3 ms)
  // Nodding.
  NodProfile profile = NodProfile::kConstantRate;
  double nod_min = -0.5;              ///< rad, lowest nod angle
  double nod_max = 0.1;               ///< rad, highest nod angle
  double nod_rate = 0.5;              ///< rad/s, constant-rate profile (triangle wave)
  double sample_distance = 0.2;       ///< m, uniform profile: ground distance between lines
  double max_nod_rate = 1.5708;       ///< rad/s, mechanism limit (90 deg/s)
  double dead_zone_time = 0.0;        ///< s: stopping distance = speed * this; 0: no dead zone
  double encoder_resolution = 0.0;    ///< rad; readings are quantized to this (0: exact)
  // Ranging.
  double range_min = 0.1;             ///< m
  double range_max = 30.0;            ///< m: no power from beyond this range
  double range_n = 1.0;               ///< Ye & Borenstein eq. 6 scale
  double range_c = 0.0;               ///< m, Ye & Borenstein eq. 6 offset
  double range_sigma = 0.0;           ///< m, Gaussian range noise
  double range_quantum = 0.0;         ///< m, output resolution (0.001: integer millimetres)
  // Footprint, receiver and amplitude.
  double beam_divergence = 0.0;       ///< rad, full angle alpha
  int subrays = 1;                    ///< rays per beam footprint
  double transceiver_separation = 0.0;///< m, s - q
  bool mirror = false;                ///< transceiver angle: false fixed (theta = offset), true theta = bearing + offset
  double transceiver_angle_offset = 0.0;  ///< rad
  double amplitude_scale = 2000.0;    ///< see header comment
  double amplitude_range_exponent = 1.0;  ///< p in d^p
  double amplitude_sigma = 0.0;       ///< reported-amplitude noise (amplitude units)
  double min_amplitude = 0.0;         ///< minimum detectable amplitude
  double false_range_probability = 0.0;  ///< below the threshold: false range (else no return)
  double mixed_pixel_tolerance = 0.05;   ///< m: a return this far from every lit surface is a mixed pixel
};

struct Motion {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  ///< x, y at t0; z: height of the vehicle origin above the terrain
  double speed = 1.0;                               ///< m/s along the heading
  double yaw = 0.0;                                 ///< rad, initial heading
  double yaw_rate = 0.0;                            ///< rad/s
  bool follow_terrain = false;                      ///< height, pitch and roll follow the terrain
  double roll_amplitude = 0.0, pitch_amplitude = 0.0;  ///< rad, sinusoidal sway
  double sway_frequency = 0.5;                      ///< Hz
  double pose_rate = 100.0;                         ///< Hz of the written pose file
  double position_sigma = 0.0;                      ///< m, noise of the written positions
  double rpy_sigma = 0.0;                           ///< rad, noise of the written roll/pitch/yaw
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

/// What a beam's visible footprint lit (BeamResult's near/far fields, stored per return).
struct BeamFootprint {
  float near = 0, far = 0;  ///< m, nearest and farthest lit depth (0: nothing lit)
  std::int32_t near_object = -1, far_object = -1;
  float near_reflectivity = 0, far_reflectivity = 0, near_power_share = 0;
};

/// Truth labels use the codes of the data contract (labels.hpp): kKept (valid), kNoReturn,
/// kOcclusion (false range caused by the receiver's occlusion dip), kMixedPixel, kLowAmplitude
/// (false range from a weak return without occlusion).
struct SimPass {
  Pass pass;                                ///< raw returns (range, bearing, amplitude, nod, stamp)
  std::vector<Eigen::Vector3d> true_point;  ///< noise-free measurement point in the map frame (NaN: none)
  std::vector<float> true_nod;              ///< true nod angle at the return's stamp
  std::vector<Label> truth;                 ///< truth label
  std::vector<float> true_amplitude;        ///< noise-free received amplitude
  std::vector<BeamFootprint> footprint;     ///< what each beam's footprint lit (see BeamResult)
};

struct SimResult {
  std::vector<SimPass> passes;
  std::vector<PoseSample> poses;       ///< written (noisy) T_M_V at motion.pose_rate
  std::vector<PoseSample> true_poses;  ///< the same stamps, noise-free
};

/// True vehicle pose T_M_V at time t.
Eigen::Isometry3d vehicle_pose(const SimConfig& cfg, double t);

/// The true nod angle as a function of time: piecewise linear between the angles at line starts.
class NodTrajectory {
 public:
  NodTrajectory(const SimConfig& cfg, std::size_t lines);
  double at(double t) const;
  const std::vector<double>& line_angles() const { return eta_; }

 private:
  double t0_, period_;
  std::vector<double> eta_;  ///< angle at the start of line k (k = 0..lines)
};

/// Triangle wave between nod_min and nod_max at nod_rate, starting at nod_min at t = t0.
double constant_rate_nod(const Scanner& s, double t);

/// Received power of one beam, summed over its footprint (exposed for tests of the physics).
struct BeamResult {
  double amplitude = 0.0;       ///< visible (what the receiver gets)
  double amplitude_full = 0.0;  ///< if nothing hid the footprint from the receiver
  double range = 0.0;           ///< power-weighted mean range of the visible part (0: nothing)
  double min_dev = 0.0;         ///< distance from range to the nearest lit object's depth interval
  int objects = 0;              ///< distinct objects (boxes, posts, terrain) the visible footprint lit
  bool any_hit = false;
  // What the visible footprint lit (for analysing misses): the nearest and farthest lit depth,
  // the objects there (-1 terrain, box index, boxes.size() + post index), their reflectivity,
  // and the share of the received power from the nearest object.
  double near = 0.0, far = 0.0;
  int near_object = -1, far_object = -1;
  double near_reflectivity = 0.0, far_reflectivity = 0.0, near_power_share = 0.0;
};
BeamResult cast_beam(const SimConfig& cfg, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                     const Eigen::Vector3d& u, const Eigen::Vector3d& v, double bearing);

SimResult simulate(const SimConfig& cfg);

/// The config with every effect off: one ray per beam, no noise, exact encoder (for geometry tests).
SimConfig geometric(SimConfig cfg);

/// Writes pass k as `dir/pass_%03d.pcd` (organized, binary) for every pass, and `dir/poses.csv`.
std::vector<std::string> write_run(const SimResult& r, const SimConfig& cfg, const std::string& dir);

/// Writes the truth as `dir/truth/pass_%03d.pcd` (line beam x y z nod label amplitude; x y z as float32) and the
/// true top-surface height grid `dir/truth/height.pcd` (organized, x y z at `grid_resolution`).
void write_truth(const SimResult& r, const SimConfig& cfg, const std::string& dir, double grid_resolution = 0.1);

/// Writes one raw pass as a PCD in the docs/data_contract.md contract (organized, binary).
void write_pass_pcd(const Pass& pass, const std::string& path);

/// Writes a pose CSV (stamp,x,y,z,roll,pitch,yaw in `order`).
void write_pose_csv(const std::vector<PoseSample>& poses, RpyOrder order, const std::string& path);

}  // namespace pcdp::sim
