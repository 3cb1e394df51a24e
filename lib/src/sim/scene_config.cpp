// Scene YAML for the simulator. Uses the same strict block validation as pipelines (the helpers of
// pipeline/config_yaml.cpp, declared below; the rules are the schema).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "pcdp/sim/nodding_sim.hpp"

namespace pcdp {

namespace detail {
// Defined in pipeline/config_yaml.cpp.
OptionValues validate_yaml_block(const std::string& source, const YAML::Node& block, const OptionSchema& schema,
                                 const std::string& what, const std::string& key_prefix);
YAML::Node parse_yaml(const std::string& text, const std::string& source);
std::string where(const std::string& source, const YAML::Node& n);
}  // namespace detail

const OptionSchema& scanner_schema() {
  static const OptionSchema s = {
      opt_int("beams", 181, 1.0, 10000.0, "", "returns per scan line"),
      opt_double("bearing_min", -1.5707963, -3.15, 3.15, "rad", "bearing of the first beam"),
      opt_double("bearing_max", 1.5707963, -3.15, 3.15, "rad", "bearing of the last beam"),
      opt_double("line_period", 0.0133, 1e-4, 10.0, "s", "time of one sweep (SICK LMS 200: 13.3 ms; Broten & Collier 3.2)"),
      opt_enum("profile", "constant_rate", {"constant_rate", "uniform_distance"},
               "nodding profile (Broten & Collier 4.1 / 4.2 with motion compensation 5.1)"),
      opt_double("nod_min", -0.5, -1.57, 1.57, "rad", "lowest nod angle (eta > 0 above the horizon)"),
      opt_double("nod_max", 0.1, -1.57, 1.57, "rad", "highest nod angle"),
      opt_double("nod_rate", 0.5, 0.0, 10.0, "rad/s", "constant_rate profile: nod rate (triangle wave)"),
      opt_double("sample_distance", 0.2, 0.001, 10.0, "m", "uniform_distance profile: ground distance between lines"),
      opt_double("max_nod_rate", 1.5708, 0.01, 20.0, "rad/s", "uniform_distance profile: mechanism's maximum rate (90 deg/s)"),
      opt_double("dead_zone_time", 0.0, 0.0, 60.0, "s", "uniform_distance: do not look nearer than speed x this (5.2); 0: off"),
      opt_double("encoder_resolution", 0.0012566, 0.0, 0.1, "rad", "encoder readings are quantized to this (0.072 deg)"),
      opt_double("range_min", 0.1, 0.0, 100.0, "m", "false ranges are drawn from [range_min, range_max]"),
      opt_double("range_max", 30.0, 0.1, 1000.0, "m", "no power from beyond this range"),
      opt_double("range_n", 0.9998, 0.5, 2.0, "", "range model scale n (Ye & Borenstein eq. 6)"),
      opt_double("range_c", 0.0036, -1.0, 1.0, "m", "range model offset c (Ye & Borenstein eq. 6: 3.6 mm)"),
      opt_double("range_sigma", 0.0053, 0.0, 1.0, "m", "range noise sigma (Ye & Borenstein eq. 6: 5.3 mm)"),
      opt_double("range_quantum", 0.001, 0.0, 1.0, "m", "output resolution (LMS 200: integer millimetres)"),
      opt_double("beam_divergence", 0.004, 0.0, 0.2, "rad", "full-angle divergence alpha (Liu et al. eq. 2)"),
      opt_int("subrays", 19, 1.0, 1000.0, "", "rays sampling each beam footprint"),
      opt_double("transceiver_separation", 0.04, 0.0, 1.0, "m", "s - q (Liu et al. eq. 4); 0: coaxial"),
      opt_enum("transceiver_angle", "fixed", {"fixed", "mirror"},
               "fixed: theta = offset; mirror: theta = bearing + offset (Liu et al. Fig. 15)"),
      opt_double("transceiver_angle_offset", 0.0, -3.15, 3.15, "rad", "theta offset; 0: separated in the scan plane"),
      opt_double("amplitude_scale", 2000.0, 0.0, 1e7, "", "amplitude = scale * reflectivity * cos(incidence) / d^p"),
      opt_double("amplitude_range_exponent", 1.0, 0.0, 4.0, "", "p; 2 for raw power, about 1 fits Liu et al.'s P1, P2"),
      opt_double("amplitude_sigma", 2.0, 0.0, 100.0, "", "noise of the reported amplitude"),
      opt_double("min_amplitude", 18.0, 0.0, 255.0, "", "minimum detectable amplitude (Liu et al. Fig. 17)"),
      opt_double("false_range_probability", 0.5, 0.0, 1.0, "", "below min_amplitude: chance of a false range (else 0)"),
      opt_double("mixed_pixel_tolerance", 0.05, 0.0, 10.0, "m", "truth: a return farther than this from every lit surface is a mixed pixel"),
  };
  return s;
}

const OptionSchema& motion_schema() {
  static const OptionSchema s = {
      opt_double("start.x", 0.0, -1e6, 1e6, "m", "vehicle position at t0, x"),
      opt_double("start.y", 0.0, -1e6, 1e6, "m", "vehicle position at t0, y"),
      opt_double("start.z", 0.0, -1e4, 1e4, "m", "vehicle z at t0 (height above the terrain with follow_terrain)"),
      opt_double("speed", 1.0, 0.0, 100.0, "m/s", "forward speed"),
      opt_double("yaw", 0.0, -3.15, 3.15, "rad", "initial heading"),
      opt_double("yaw_rate", 0.0, -2.0, 2.0, "rad/s", "turn rate"),
      opt_bool("follow_terrain", true, "vehicle height, pitch and roll follow the terrain"),
      opt_double("roll_amplitude", 0.0, 0.0, 0.5, "rad", "sinusoidal roll sway"),
      opt_double("pitch_amplitude", 0.0, 0.0, 0.5, "rad", "sinusoidal pitch sway"),
      opt_double("sway_frequency", 0.5, 0.0, 50.0, "Hz", "frequency of the sway"),
      opt_double("pose_rate", 100.0, 1.0, 10000.0, "Hz", "rate of the written pose file"),
      opt_double("position_sigma", 0.005, 0.0, 10.0, "m", "noise of the written positions (per axis)"),
      opt_double("rpy_sigma", 0.00035, 0.0, 0.5, "rad", "noise of the written roll, pitch, yaw"),
  };
  return s;
}

const OptionSchema& terrain_schema() {
  static const OptionSchema s = {
      opt_double("ground_z", 0.0, -1e4, 1e4, "m", "mean ground height"),
      opt_double("undulation_amplitude", 0.0, 0.0, 100.0, "m", "z = ground_z + a sin(2 pi x / L) cos(2 pi y / L)"),
      opt_double("undulation_wavelength", 10.0, 0.1, 1e4, "m", "L of the undulation"),
      opt_double("reflectivity", 0.4, 0.0, 1.0, "", "ground reflectivity"),
  };
  return s;
}

namespace {
Eigen::Vector3d vec3(const std::string& src, const YAML::Node& n, const std::string& what) {
  if (!n || !n.IsSequence() || n.size() != 3)
    throw ConfigError(detail::where(src, n) + ": " + what + " must be a list of 3 numbers [x, y, z]");
  Eigen::Vector3d v;
  for (std::size_t i = 0; i < 3; ++i) {
    char* end = nullptr;
    const std::string t = n[i].IsScalar() ? n[i].Scalar() : "";
    v[static_cast<int>(i)] = std::strtod(t.c_str(), &end);
    if (t.empty() || *end != '\0' || !std::isfinite(v[static_cast<int>(i)]) ||
        t.find_first_not_of("+-.0123456789eE") != std::string::npos)
      throw ConfigError(detail::where(src, n) + ": " + what + ": '" + t + "' is not a finite number");
  }
  return v;
}
}  // namespace

namespace {
/// simulate holds every pass in memory and casts `subrays` rays per return against the terrain
/// and every box: the work is bounded before it starts (docs/simulator.md, "Limits"), so a
/// scene within the per-key limits that could not finish in about a minute is refused up front.
void check_scene_work(const std::string& src, const sim::SimConfig& c) {
  constexpr double kMaxReturns = 5e6;     // ~70 bytes each in memory, plus the written files
  constexpr double kMaxRayWork = 1e7;     // terrain-ray equivalents: about 30 s on one core
  constexpr double kBoxesPerTerrain = 160;  // a box test costs about 1/160 of a terrain intersection
  constexpr double kMaxPoses = 2e6;       // rows of poses.csv
  const auto num = [](double v) {
    std::ostringstream os;
    os << std::setprecision(3) << v;
    return os.str();
  };
  const double returns = static_cast<double>(c.passes) * c.lines_per_pass * c.scanner.beams;
  const std::string product = std::to_string(c.passes) + " x " + std::to_string(c.lines_per_pass) + " x " +
                              std::to_string(c.scanner.beams);
  if (returns > kMaxReturns)
    throw ConfigError(src + ": the scene needs passes x lines_per_pass x scanner.beams = " + product + " = " +
                      num(returns) + " returns; simulate holds them in memory and is limited to " + num(kMaxReturns) +
                      ": reduce passes, lines_per_pass or scanner.beams (or simulate in parts with other t0 and seed)");
  const double boxes = static_cast<double>(c.scene.boxes.size() + c.scene.posts.size());
  const double work = returns * c.scanner.subrays * (1.0 + boxes / kBoxesPerTerrain);
  if (work > kMaxRayWork)
    throw ConfigError(src + ": the scene needs passes x lines_per_pass x scanner.beams x scanner.subrays = " + product +
                      " x " + std::to_string(c.scanner.subrays) + " = " +
                      num(returns * c.scanner.subrays) + " rays" +
                      (boxes > 0 ? " against the terrain and " + num(boxes) + " boxes and posts (" + num(work) + " ray equivalents)"
                                 : std::string()) +
                      "; simulate is limited to " + num(kMaxRayWork) +
                      " (about half a minute): reduce passes, lines_per_pass, scanner.beams, scanner.subrays or the boxes");
  const double seconds = static_cast<double>(c.passes) * c.lines_per_pass * c.scanner.line_period;
  const double poses = seconds * c.motion.pose_rate;
  if (poses > kMaxPoses)
    throw ConfigError(src + ": the scene lasts passes x lines_per_pass x scanner.line_period = " + num(seconds) +
                      " s, at motion.pose_rate " + num(c.motion.pose_rate) + " Hz that is " + num(poses) +
                      " poses; simulate is limited to " + num(kMaxPoses) + ": lower motion.pose_rate or shorten the scene");
}
}  // namespace

sim::SimConfig load_scene_from_string(const std::string& yaml, const std::string& src) {
  const YAML::Node root = detail::parse_yaml(yaml, src);
  if (!root.IsMap()) throw ConfigError(src + ": a scene must be a mapping of keys");
  const std::vector<std::string> keys = {"description", "seed", "rpy_order", "passes", "lines_per_pass", "t0",
                                         "mount", "scanner", "motion", "terrain", "boxes", "posts"};
  for (const auto& kv : root) {
    const std::string k = kv.first.Scalar();
    if (std::find(keys.begin(), keys.end(), k) == keys.end())
      throw ConfigError(detail::where(src, kv.first) + ": unknown key '" + k + "'" + did_you_mean(k, keys));
  }
  static const OptionSchema run_schema = {
      opt_int("seed", 1, 0.0, 4e18, "", "random seed (the output is bit-identical for a given seed)"),
      opt_enum("rpy_order", "xyz", {"xyz", "zyx"}, "roll-pitch-yaw order of the mount and the written poses"),
      opt_int("passes", 1, 1.0, 10000.0, "", "number of pass files"),
      opt_int("lines_per_pass", 100, 1.0, 1e6, "", "scan lines per pass"),
      opt_double("t0", 0.0, -1e12, 1e12, "s", "stamp of the first return"),
  };
  YAML::Node top(YAML::NodeType::Map);
  for (const auto& o : run_schema)
    if (root[o.name]) top[o.name] = root[o.name];
  const OptionValues run = detail::validate_yaml_block(src, top, run_schema, "scene", "");
  const OptionValues mount = detail::validate_yaml_block(src, root["mount"], mount_schema(), "mount", "mount");
  const OptionValues sc = detail::validate_yaml_block(src, root["scanner"], scanner_schema(), "scanner", "scanner");
  const OptionValues mo = detail::validate_yaml_block(src, root["motion"], motion_schema(), "motion", "motion");
  const OptionValues te = detail::validate_yaml_block(src, root["terrain"], terrain_schema(), "terrain", "terrain");

  sim::SimConfig c;
  c.seed = static_cast<std::uint64_t>(run.get_int("seed"));
  c.rpy_order = rpy_order_from_name(run.get_string("rpy_order"));
  c.passes = static_cast<int>(run.get_int("passes"));
  c.lines_per_pass = static_cast<int>(run.get_int("lines_per_pass"));
  c.t0 = run.get_double("t0");
  c.mount_translation = {mount.get_double("x"), mount.get_double("y"), mount.get_double("z")};
  c.mount_rpy = {mount.get_double("roll"), mount.get_double("pitch"), mount.get_double("yaw")};
  auto& s = c.scanner;
  s.beams = static_cast<int>(sc.get_int("beams"));
  s.bearing_min = sc.get_double("bearing_min");
  s.bearing_max = sc.get_double("bearing_max");
  s.line_period = sc.get_double("line_period");
  s.profile = sc.get_string("profile") == "uniform_distance" ? sim::NodProfile::kUniformDistance
                                                              : sim::NodProfile::kConstantRate;
  s.nod_min = sc.get_double("nod_min");
  s.nod_max = sc.get_double("nod_max");
  s.nod_rate = sc.get_double("nod_rate");
  s.sample_distance = sc.get_double("sample_distance");
  s.max_nod_rate = sc.get_double("max_nod_rate");
  s.dead_zone_time = sc.get_double("dead_zone_time");
  s.encoder_resolution = sc.get_double("encoder_resolution");
  s.range_min = sc.get_double("range_min");
  s.range_max = sc.get_double("range_max");
  s.range_n = sc.get_double("range_n");
  s.range_c = sc.get_double("range_c");
  s.range_sigma = sc.get_double("range_sigma");
  s.range_quantum = sc.get_double("range_quantum");
  s.beam_divergence = sc.get_double("beam_divergence");
  s.subrays = static_cast<int>(sc.get_int("subrays"));
  s.transceiver_separation = sc.get_double("transceiver_separation");
  s.mirror = sc.get_string("transceiver_angle") == "mirror";
  s.transceiver_angle_offset = sc.get_double("transceiver_angle_offset");
  s.amplitude_scale = sc.get_double("amplitude_scale");
  s.amplitude_range_exponent = sc.get_double("amplitude_range_exponent");
  s.amplitude_sigma = sc.get_double("amplitude_sigma");
  s.min_amplitude = sc.get_double("min_amplitude");
  s.false_range_probability = sc.get_double("false_range_probability");
  s.mixed_pixel_tolerance = sc.get_double("mixed_pixel_tolerance");
  if (s.range_min >= s.range_max)
    throw ConfigError(src + ": scanner: range_min (" + format_value(s.range_min) + ") must be less than range_max (" +
                      format_value(s.range_max) + ")");
  if (s.nod_min >= s.nod_max)
    throw ConfigError(src + ": scanner: nod_min (" + format_value(s.nod_min) + ") must be less than nod_max (" +
                      format_value(s.nod_max) + ")");
  auto& m = c.motion;
  m.start = {mo.get_double("start.x"), mo.get_double("start.y"), mo.get_double("start.z")};
  m.speed = mo.get_double("speed");
  m.yaw = mo.get_double("yaw");
  m.yaw_rate = mo.get_double("yaw_rate");
  m.roll_amplitude = mo.get_double("roll_amplitude");
  m.pitch_amplitude = mo.get_double("pitch_amplitude");
  m.sway_frequency = mo.get_double("sway_frequency");
  m.pose_rate = mo.get_double("pose_rate");
  m.follow_terrain = mo.get_bool("follow_terrain");
  m.position_sigma = mo.get_double("position_sigma");
  m.rpy_sigma = mo.get_double("rpy_sigma");
  c.scene.ground_z = te.get_double("ground_z");
  c.scene.undulation_amplitude = te.get_double("undulation_amplitude");
  c.scene.undulation_wavelength = te.get_double("undulation_wavelength");
  c.scene.ground_reflectivity = te.get_double("reflectivity");
  // One number of a box or post: a scalar within [lo, hi].
  const auto number = [&](const YAML::Node& n, const char* what, const char* key, double lo, double hi) {
    const std::string t = n.IsScalar() ? n.Scalar() : "";
    OptionValue v;
    if (!parse_option_value(opt_double(key, 0.0, lo, hi, "", ""), t, v)) return std::get<double>(v);
    std::ostringstream os;
    os << detail::where(src, n) << ": " << what << ": " << key << " '" << t << "' must be a number in [" << lo << ", " << hi
       << "]";
    throw ConfigError(os.str());
  };
  if (root["boxes"]) {
    if (!root["boxes"].IsSequence()) throw ConfigError(detail::where(src, root["boxes"]) + ": 'boxes' must be a list");
    for (const auto& b : root["boxes"]) {
      if (!b.IsMap()) throw ConfigError(detail::where(src, b) + ": each box is a mapping {min, max, reflectivity, yaw}");
      for (const auto& kv : b) {
        const std::string k = kv.first.Scalar();
        if (k != "min" && k != "max" && k != "reflectivity" && k != "yaw" && k != "name")
          throw ConfigError(detail::where(src, kv.first) + ": box: unknown key '" + k + "'" +
                            did_you_mean(k, {"min", "max", "reflectivity", "yaw", "name"}));
      }
      sim::Box box;
      box.min = vec3(src, b["min"], "box min");
      box.max = vec3(src, b["max"], "box max");
      if ((box.max - box.min).minCoeff() <= 0.0)
        throw ConfigError(detail::where(src, b) + ": box: max must exceed min on every axis");
      if (b["reflectivity"]) {
        const std::string t = b["reflectivity"].IsScalar() ? b["reflectivity"].Scalar() : "";
        OptionValue v;
        if (!parse_option_value(opt_double("reflectivity", 0.0, 0.0, 1.0, "", ""), t, v))
          box.reflectivity = std::get<double>(v);
        else
          throw ConfigError(detail::where(src, b["reflectivity"]) + ": box: reflectivity '" + t + "' must be in [0, 1]");
      }
      if (b["yaw"]) box.yaw = number(b["yaw"], "box", "yaw", -6.3, 6.3);
      c.scene.boxes.push_back(box);
    }
  }
  if (root["posts"]) {
    if (!root["posts"].IsSequence()) throw ConfigError(detail::where(src, root["posts"]) + ": 'posts' must be a list");
    const std::vector<std::string> post_keys = {"x", "y", "radius", "z_min", "z_max", "reflectivity", "name"};
    for (const auto& n : root["posts"]) {
      if (!n.IsMap())
        throw ConfigError(detail::where(src, n) + ": each post is a mapping {x, y, radius, z_min, z_max, reflectivity}");
      for (const auto& kv : n) {
        const std::string k = kv.first.Scalar();
        if (std::find(post_keys.begin(), post_keys.end(), k) == post_keys.end())
          throw ConfigError(detail::where(src, kv.first) + ": post: unknown key '" + k + "'" + did_you_mean(k, post_keys));
      }
      for (const char* k : {"x", "y", "radius", "z_min", "z_max"})
        if (!n[k]) throw ConfigError(detail::where(src, n) + ": post: '" + k + "' is required");
      sim::Post p;
      p.x = number(n["x"], "post", "x", -1e6, 1e6);
      p.y = number(n["y"], "post", "y", -1e6, 1e6);
      p.radius = number(n["radius"], "post", "radius", 1e-3, 100.0);
      p.z_min = number(n["z_min"], "post", "z_min", -1e4, 1e4);
      p.z_max = number(n["z_max"], "post", "z_max", -1e4, 1e4);
      if (p.z_max <= p.z_min) throw ConfigError(detail::where(src, n) + ": post: z_max must exceed z_min");
      if (n["reflectivity"]) p.reflectivity = number(n["reflectivity"], "post", "reflectivity", 0.0, 1.0);
      c.scene.posts.push_back(p);
    }
  }
  check_scene_work(src, c);
  return c;
}

sim::SimConfig load_scene(const std::string& path, std::string* text) {
  if (const std::string problem = io::regular_file_problem(path, "scene file"); !problem.empty())
    throw ConfigError(path + ": " + problem);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot read the scene file (" + std::strerror(errno) + ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (text) *text = ss.str();
  return load_scene_from_string(ss.str(), path);
}

}  // namespace pcdp
