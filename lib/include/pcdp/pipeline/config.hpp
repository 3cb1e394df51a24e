// The pipeline description: sensor block, mount, poses, inputs, output folder and the ordered
// list of stage instances. YAML is read in lib/src/pipeline/config_yaml.cpp and nowhere else.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/pipeline/options.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp {

enum class TransceiverAngle { kFixed, kMirror };

/// The `sensor:` block (docs/data_contract.md). Units: metres, radians, seconds, amplitude units.
struct SensorParams {
  double range_min = 0.1;
  double range_max = 30.0;
  double beam_divergence = 0.004;         ///< full angle, alpha in Liu et al.
  double transceiver_separation = 0.04;   ///< s - q in Liu et al.
  TransceiverAngle transceiver_angle = TransceiverAngle::kFixed;
  double transceiver_angle_offset = 0.0;
  double min_amplitude = 18.0;
  double amplitude_saturation = 255.0;    ///< amplitudes at or above this are clipped (sensor units)
  double range_sigma = 0.0053;            ///< Ye & Borenstein eq. 6
  double range_k = 1.0;                   ///< true range = k * measured + b (Ye & Borenstein eqs. 1-3)
  double range_b = 0.0;
  double encoder_resolution = 0.0012566;  ///< 0.072 degrees (Broten & Collier 6.3.3)
  double encoder_latency = 0.0;
  double encoder_latency_sigma = 0.0;  ///< s, 1-sigma uncertainty of the latency
  double bearing_resolution = 0.0;     ///< rad, quantization of the in-plane beam angle

  double calibrated_range(double measured) const { return range_k * measured + range_b; }
};

/// The `mount:` block: T_V_N, the nod frame in the vehicle frame.
struct MountParams {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Rpy rpy;
};

/// The `pose_sigma:` block: 1-sigma pose uncertainty.
struct PoseSigma {
  double position = 0.005;
  double rpy = 0.00035;
};

/// One stage instance of the pipeline.
struct StageConfig {
  std::string type;      ///< registered stage type, e.g. "register"
  std::string name;      ///< instance name (defaults to the type), unique in the pipeline
  std::string where;     ///< "file.yaml:12" for messages
  OptionValues options;  ///< validated against the stage type's schema
};

struct PipelineConfig {
  std::string source;  ///< the pipeline file
  RpyOrder rpy_order = RpyOrder::kXyz;
  std::vector<std::string> scan_patterns;  ///< as written (paths or globs), resolved
  std::vector<std::string> scans;          ///< expanded pass files, in run order
  std::string poses;                       ///< pose CSV; empty: T_M_V = identity
  std::string output_dir;                  ///< as given, or out/<file stem> (relative to the working directory)
  MountParams mount;
  SensorParams sensor;
  PoseSigma pose_sigma;
  std::vector<StageConfig> stages;
  /// A run that keeps no return, or leaves most in-range returns without a pose, is a data error
  /// unless this is set (top-level key `allow_empty_output`, see top_level_schema()).
  bool allow_empty_output = false;
  /// The map frame's coordinate reference system (top-level key `crs`), as io::normalize_crs()
  /// returns it: "EPSG:N" or WKT; empty: none. Written as elevation.tif's GeoKeys.
  std::string crs;
  /// Validated values of each fixed block ("sensor", "mount", "pose_sigma"), for the report.
  std::vector<std::pair<std::string, OptionValues>> blocks;
};

/// The options of the fixed blocks, bound to the structs above (config_blocks.cpp); the member
/// initialisers are the defaults. Nested keys use dots ("range_calibration.k").
const Options<SensorParams>& sensor_options();
const Options<MountParams>& mount_options();
const Options<PoseSigma>& pose_sigma_options();
/// The top-level scalar options of a pipeline (`allow_empty_output`, `crs` as written).
const Options<PipelineConfig>& top_level_options();

/// Their schemas (for describe, docs and validation).
const OptionSchema& sensor_schema();
const OptionSchema& mount_schema();
const OptionSchema& pose_sigma_schema();
/// Schema of the top-level scalar options of a pipeline (`allow_empty_output`).
const OptionSchema& top_level_schema();

/// A `--set key=value` override. `key` is dotted: sensor.min_amplitude, input.scans,
/// output_dir, stages.<instance name>.<option>.
struct Override {
  std::string key;
  std::string value;
};
Override parse_override(const std::string& text);  ///< "key=value"; throws ConfigError

struct LoadOptions {
  std::vector<Override> overrides;
  std::string output_dir;  ///< --output-dir, relative to the working directory; wins over all
  bool check_inputs = true;  ///< expand globs and check that input files exist
};

/// Loads, applies overrides, and validates everything: every key known, every value typed and in
/// bounds, every stage known and configured, inputs present. Reads no scan.
/// Throws ConfigError (or InputError for missing input files) with a message naming the file,
/// line, stage instance, key, value and rule.
PipelineConfig load_pipeline(const std::string& path, const LoadOptions& opts = {});

/// Same, from YAML text (for tests); relative paths resolve against `base_dir`.
PipelineConfig load_pipeline_from_string(const std::string& yaml, const std::string& source_name,
                                         const std::string& base_dir, const LoadOptions& opts = {});

}  // namespace pcdp

namespace pcdp::sim {
struct SimConfig;
}

namespace pcdp {

/// Schemas of the simulator's scene blocks (`scanner`, `motion`, `terrain`), for describe/docs.
const OptionSchema& scanner_schema();
const OptionSchema& motion_schema();
const OptionSchema& terrain_schema();

/// Loads and validates a scene YAML for `pcd_pipeline simulate` (same strict rules as pipelines);
/// `text`, when given, receives the file's bytes as read.
sim::SimConfig load_scene(const std::string& path, std::string* text = nullptr);
sim::SimConfig load_scene_from_string(const std::string& yaml, const std::string& source_name);

}  // namespace pcdp
