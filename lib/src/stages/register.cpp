#include "pcdp/stages/register.hpp"

#include <cmath>
#include <limits>
#include <memory>

#include "pcdp/pass.hpp"
#include "pcdp/skew.hpp"
#include "pcdp/uncertainty.hpp"
#include "../small_angle.hpp"

namespace pcdp {

const OptionSchema& register_schema() {
  static const OptionSchema s = {
      opt_bool("skew_correction", true,
               "give each return the nod angle at its own stamp, interpolated from the per-line encoder readings"),
      opt_double("max_pose_gap", 1.0, 0.0, std::nullopt, "s",
                 "returns inside a pose-file gap longer than this get no_pose (0: never)"),
      opt_bool("covariance", true, "propagate each point's 3x3 covariance (sensor and pose_sigma) to cloud.pcd"),
      opt_int("blind_lines", 5, 0.0, 1e6, "lines", "warn of this many consecutive lines without any return (0: never)"),
  };
  return s;
}

void register_pass(Pass& pass, const RegisterParams& params, const SensorParams& sensor,
                   const Eigen::Isometry3d& T_V_N, const PoseTrack* poses, const PoseSigma& pose_sigma,
                   RpyOrder order) {
  const std::size_t n = pass.size();
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  pass.range_cal.assign(n, std::numeric_limits<float>::quiet_NaN());
  pass.nod_at_return.assign(n, 0.0f);
  pass.x.assign(n, kNaN);
  pass.y.assign(n, kNaN);
  pass.z.assign(n, kNaN);
  pass.ox.assign(n, kNaN);
  pass.oy.assign(n, kNaN);
  pass.oz.assign(n, kNaN);

  const EncoderTrack track = encoder_track(pass, sensor.encoder_latency);
  std::size_t enc_hint = 0, pose_hint = 0, rate_hint = 0;
  if (params.covariance) pass.cov.assign(6 * n, std::numeric_limits<float>::quiet_NaN());
  PointSigmas sig;
  sig.range = sensor.range_k * sensor.range_sigma;
  sig.bearing = quantization_sigma(sensor.bearing_resolution);
  sig.position = Eigen::Vector3d::Constant(pose_sigma.position);
  sig.rpy = Eigen::Vector3d::Constant(pose_sigma.rpy);
  const double enc_var = std::pow(quantization_sigma(sensor.encoder_resolution), 2);

  constexpr std::size_t kBearingCache = 4096;  // power of two; indexed by beam
  struct CachedBearing {
    float bearing;
    double c, s;
  };
  std::vector<CachedBearing> bearing_cache(kBearingCache, {std::numeric_limits<float>::quiet_NaN(), 0.0, 0.0});
  // The nod's sine and cosine: those of a base angle (the reading that starts the return's
  // encoder bracket, or the line's own reading without skew correction), computed once per base,
  // turned by the small step to the return's angle (angle addition with the step's sine and
  // cosine by their series: equal to std::sin / std::cos to rounding). The base depends only on
  // the return's bracket, not on what came before, so a streamed line gets the same values.
  double base = kNaN, base_c = 1.0, base_s = 0.0;
  const auto nod_sincos = [&](double eta, double b, double& c, double& s) {
    if (!(b == base)) {
      base = b;
      base_c = std::cos(b);
      base_s = std::sin(b);
    }
    const double d = eta - b;
    if (std::fabs(d) <= detail::kSmallAngle) {
      const double cd = detail::cos_small(d), sd = detail::sin_small(d);
      c = base_c * cd - base_s * sd;
      s = base_s * cd + base_c * sd;
    } else {
      c = std::cos(eta);
      s = std::sin(eta);
    }
  };
  // The pose of the current pose segment in closed form (SegmentMotion: T_M_V and T_M_N =
  // T_M_V T_V_N as R0 + sin(a) B + (1 - cos(a)) C), rebuilt when a return falls in another
  // segment. Like the nod's base, it depends only on the segment, so a streamed line gets the
  // same values. Without poses, T_M_V is the identity.
  constexpr std::size_t kNoSegment = std::numeric_limits<std::size_t>::max();
  std::size_t seg_k = kNoSegment;
  SegmentMotion mv, mn = SegmentMotion{}.then(T_V_N);
  const SegmentMotion::Weights fixed;  // s = 0, no turn: R0 and t0
  // The nod's sigma depends on the encoder bracket's rate only: computed once per bracket.
  std::size_t sig_k = kNoSegment;
  // Covariances are computed in batches, several returns per vector instruction.
  const int ia = inner_pose_axis(order);
  const std::unique_ptr<CovarianceBatch> batch = params.covariance ? std::make_unique<CovarianceBatch>(order, sig) : nullptr;
  for (std::size_t i = 0; i < n; ++i) {
    const double stamp = pass.stamp[i];
    const double eta = params.skew_correction ? track.angle_at(stamp, enc_hint) : static_cast<double>(pass.nod[i]);
    // angle_at left the return's bracket [k, k + 1] in the hint; with fewer than two readings
    // (or no skew correction) there is no bracket and the angle is its own base.
    const double eta_base = params.skew_correction && track.size() > 1 ? track.reading(enc_hint) : eta;
    pass.nod_at_return[i] = static_cast<float>(eta);

    const float r = pass.range[i];
    const bool has_return = r > 0.0f;  // false for 0 and NaN
    double rc = kNaN;
    if (has_return) {
      rc = sensor.calibrated_range(r);
      pass.range_cal[i] = static_cast<float>(rc);
    }

    bool has_pose = true;
    if (poses) {
      has_pose = poses->covers(stamp);
      if (has_pose) {
        const std::size_t k = poses->size() > 1 ? (pose_hint = poses->bracket(stamp, pose_hint)) : 0;
        if (k != seg_k) {
          mv = poses->motion(k);
          mn = mv.then(T_V_N);
          seg_k = k;
        }
        // The segment's duration is the gap between the two poses around the stamp.
        has_pose = params.max_pose_gap <= 0.0 || poses->size() < 2 || mv.duration <= params.max_pose_gap;
      }
    }

    if (!has_return) {
      pass.label[i] = Label::kNoReturn;
    } else if (!(rc >= sensor.range_min && rc <= sensor.range_max)) {
      pass.label[i] = Label::kOutOfRange;
    } else if (!has_pose) {
      pass.label[i] = Label::kNoPose;
    }
    if (!has_pose) continue;

    const SegmentMotion::Weights w = poses ? mn.weights(stamp) : fixed;
    const Eigen::Vector3d o = mn.translation(w);
    pass.ox[i] = o.x();
    pass.oy[i] = o.y();
    pass.oz[i] = o.z();
    if (!has_return) continue;
    const Eigen::Matrix3d R_MN = mn.rotation(w);
    // The bearing's sine and cosine repeat from line to line for a beam: computed once per value.
    const float bearing = pass.bearing[i];
    double cn, sn;
    const std::size_t slot = static_cast<std::size_t>(pass.beam[i]) & (kBearingCache - 1);
    if (bearing_cache[slot].bearing == bearing) {
      cn = bearing_cache[slot].c;
      sn = bearing_cache[slot].s;
    } else {
      cn = std::cos(static_cast<double>(bearing));
      sn = std::sin(static_cast<double>(bearing));
      bearing_cache[slot] = {bearing, cn, sn};
    }
    double ce, se;
    nod_sincos(eta, eta_base, ce, se);
    const Eigen::Vector3d p = R_MN * Eigen::Vector3d(rc * cn * ce, rc * sn, rc * cn * se) + o;  // nod_frame_point
    pass.x[i] = p.x();
    pass.y[i] = p.y();
    pass.z[i] = p.z();
    if (params.covariance) {
      if (!(sig_k == enc_hint)) {
        const double omega = sensor.encoder_latency_sigma > 0 ? track.rate_at(stamp, rate_hint) : 0.0;
        sig.nod = std::sqrt(enc_var + std::pow(omega * sensor.encoder_latency_sigma, 2));
        // Without skew correction the hint does not follow the stamp: no caching then.
        sig_k = params.skew_correction ? enc_hint : kNoSegment;
      }
      const Eigen::Vector3d inner = mv.R0.col(ia) + w.sin_a * mv.B.col(ia) + w.vers_a * mv.C.col(ia);
      const Eigen::Vector3d Rp = p - mv.translation(w);
      float* c = &pass.cov[6 * i];
      if (!batch->add(rc, cn, sn, ce, se, R_MN, inner, Rp, sig.nod, c)) {  // gimbal lock: the angle path
        const Eigen::Matrix3d C = point_covariance_fast(rc, cn, sn, ce, se, mv.rotation(w), T_V_N, R_MN, Rp, order, sig);
        c[0] = static_cast<float>(C(0, 0));
        c[1] = static_cast<float>(C(0, 1));
        c[2] = static_cast<float>(C(0, 2));
        c[3] = static_cast<float>(C(1, 1));
        c[4] = static_cast<float>(C(1, 2));
        c[5] = static_cast<float>(C(2, 2));
      }
      if (batch->full()) batch->compute();
    }
  }
  if (batch) batch->compute();
}

std::vector<std::string> blind_runs(const Pass& pass, int min_lines) {
  std::vector<std::string> out;
  if (min_lines <= 0) return out;
  std::size_t run_start = 0, run_len = 0;
  const auto flush = [&](std::size_t end_line) {
    if (run_len >= static_cast<std::size_t>(min_lines))
      out.push_back(pass.source + ": lines " + std::to_string(pass.line[pass.line_begin[run_start]]) + "-" +
                    std::to_string(pass.line[pass.line_begin[end_line]]) + " (" + std::to_string(run_len) +
                    " lines) returned nothing: sensor blinded (sunlight?) or obstructed");
    run_len = 0;
  };
  for (std::size_t k = 0; k < pass.line_count(); ++k) {
    bool any = false;
    for (std::size_t i = pass.line_begin[k]; i < pass.line_begin[k + 1] && !any; ++i) any = pass.range[i] > 0.0f;
    if (!any) {
      if (run_len == 0) run_start = k;
      ++run_len;
    } else if (run_len) {
      flush(k - 1);
    }
  }
  if (run_len) flush(pass.line_count() - 1);
  return out;
}

namespace {
class RegisterStage final : public Stage {
 public:
  RegisterStage(RegisterParams p, const RunContext& ctx) : params_(p), ctx_(ctx) {
    const PipelineConfig& cfg = *ctx.config;
    T_V_N_ = make_transform(cfg.mount.translation, cfg.mount.rpy, cfg.rpy_order);
  }
  bool concurrent() const override { return true; }
  int stream_reach() const override { return 1; }  // the previous line's encoder reading
  void process(Pass& pass, StageReport& report) override {
    register_pass(pass, params_, ctx_.config->sensor, T_V_N_, ctx_.poses.get(), ctx_.config->pose_sigma,
                  ctx_.config->rpy_order);
    report.metrics["lines"] += static_cast<double>(pass.line_count());
    for (const auto& w : blind_runs(pass, params_.blind_lines)) report.warnings.push_back(w);
  }

 private:
  RegisterParams params_;
  RunContext ctx_;
  Eigen::Isometry3d T_V_N_;
};
}  // namespace

StageInfo register_stage_info() {
  return {"register",
          "raw returns -> map frame: range calibration, skew correction, mount and pose transforms",
          register_schema(),
          [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            RegisterParams p;
            p.skew_correction = sc.options.get_bool("skew_correction");
            p.max_pose_gap = sc.options.get_double("max_pose_gap");
            p.covariance = sc.options.get_bool("covariance");
            p.blind_lines = static_cast<int>(sc.options.get_int("blind_lines"));
            return std::make_unique<RegisterStage>(p, ctx);
          }};
}

}  // namespace pcdp
