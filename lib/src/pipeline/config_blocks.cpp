// The fixed blocks of a pipeline (sensor, mount, pose_sigma) and its top-level options, each option
// declared once and bound to the member of the struct it sets (config.hpp); the member initialisers
// are the defaults.
#include "pcdp/pipeline/config.hpp"

namespace pcdp {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

const Options<SensorParams>& sensor_options() {
  using P = SensorParams;
  static const auto o = Options<P>()
      .add("range_min", &P::range_min, at_least(0), "m",
           "shortest valid calibrated range; shorter returns are labelled out_of_range")
      .add("range_max", &P::range_max, greater_than(0), "m",
           "longest valid calibrated range; longer returns are labelled out_of_range")
      .add("beam_divergence", &P::beam_divergence, bounds(0, 0.2), "rad",
           "full-angle beam divergence (alpha, Liu et al. 2005)")
      .add("transceiver_separation", &P::transceiver_separation, bounds(0, 1), "m",
           "transmitter-receiver separation (s - q, Liu et al. 2005)")
      .add("transceiver_angle", &P::transceiver_angle,
           {{"fixed", TransceiverAngle::kFixed}, {"mirror", TransceiverAngle::kMirror}},
           "fixed: always separated (theta = 0); mirror: theta = bearing + offset")
      .add("transceiver_angle_offset", &P::transceiver_angle_offset, bounds(-kPi, kPi), "rad",
           "offset added to the bearing for the mirror transceiver angle")
      .add("min_amplitude", &P::min_amplitude, at_least(0), "", "minimum detectable amplitude (sensor units)")
      .add("amplitude_saturation", &P::amplitude_saturation, greater_than(0), "",
           "amplitudes at or above this are clipped (sensor units; above the largest the sensor reports: none are): they say nothing about a mixture")
      .add("range_sigma", &P::range_sigma, bounds(0, 1), "m", "1-sigma range noise (Ye & Borenstein eq. 6)")
      .add("range_calibration.k", &P::range_k, bounds(0.5, 2).excluding_min(), "",
           "scale of the linear range calibration: true = k * measured + b")
      .add("range_calibration.b", &P::range_b, bounds(-1, 1), "m",
           "offset of the linear range calibration: true = k * measured + b")
      .add("encoder_resolution", &P::encoder_resolution, bounds(0, 0.1), "rad",
           "nod-encoder resolution (0.072 deg in Broten & Collier)")
      .add("encoder_latency", &P::encoder_latency, bounds(-1, 1), "s",
           "a line's encoder reading describes the nod at its last return's stamp minus this")
      .add("encoder_latency_sigma", &P::encoder_latency_sigma, bounds(0, 1), "s",
           "1-sigma uncertainty of encoder_latency (times the nod rate, a nod error)")
      .add("bearing_resolution", &P::bearing_resolution, bounds(0, 0.1), "rad",
           "quantization of the in-plane beam angle (uniform: sigma = resolution / sqrt 12)")
      .rule("range_min < range_max", [](const P& s) { return s.range_min < s.range_max; },
            "the valid calibrated ranges are the interval between them",
            "range_min ({range_min} m) must be less than range_max ({range_max} m)");
  return o;
}

const Options<MountParams>& mount_options() {
  using P = MountParams;
  static const auto o = Options<P>()
      .add("x", [](P& m) -> double& { return m.translation.x(); }, bounds(-100, 100), "m",
           "nod-axis origin in the vehicle frame, forward")
      .add("y", [](P& m) -> double& { return m.translation.y(); }, bounds(-100, 100), "m",
           "nod-axis origin in the vehicle frame, left")
      .add("z", [](P& m) -> double& { return m.translation.z(); }, bounds(-100, 100), "m",
           "nod-axis origin in the vehicle frame, up")
      .add("roll", [](P& m) -> double& { return m.rpy.roll; }, bounds(-kPi, kPi), "rad",
           "mount roll (rpy_order applies)")
      .add("pitch", [](P& m) -> double& { return m.rpy.pitch; }, bounds(-kPi, kPi), "rad",
           "mount pitch (rpy_order applies; positive tips the laser's x axis down)")
      .add("yaw", [](P& m) -> double& { return m.rpy.yaw; }, bounds(-kPi, kPi), "rad", "mount yaw (rpy_order applies)");
  return o;
}

const Options<PoseSigma>& pose_sigma_options() {
  using P = PoseSigma;
  static const auto o = Options<P>()
      .add("position", &P::position, bounds(0, 100), "m", "1-sigma position uncertainty of the poses")
      .add("rpy", &P::rpy, bounds(0, 1), "rad", "1-sigma roll/pitch/yaw uncertainty of the poses");
  return o;
}

const Options<PipelineConfig>& top_level_options() {
  using P = PipelineConfig;
  static const auto o = Options<P>()
      .add("allow_empty_output", &P::allow_empty_output,
           "false: a run that keeps no return, or leaves more than half of its in-range returns without "
           "a pose (a time-base mismatch?), fails with exit 3 before writing; true: it writes and warns")
      .add("crs", &P::crs,
           "the map frame's coordinate reference system: EPSG:<code> (or its WKT) of a projected CRS in "
           "metres, checked against PROJ's database; written as elevation.tif's GeoKeys, kept by merge; "
           "empty: none");
  return o;
}

const OptionSchema& sensor_schema() { return sensor_options().schema(); }
const OptionSchema& mount_schema() { return mount_options().schema(); }
const OptionSchema& pose_sigma_schema() { return pose_sigma_options().schema(); }
const OptionSchema& top_level_schema() { return top_level_options().schema(); }

}  // namespace pcdp
