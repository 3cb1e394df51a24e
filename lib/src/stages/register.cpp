#include "pcdp/stages/register.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "pcdp/core/pass.hpp"
#include "pcdp/core/skew.hpp"
#include "pcdp/core/uncertainty.hpp"
#include "core/small_angle.hpp"

namespace pcdp {

const Options<RegisterParams>& register_options() {
  using P = RegisterParams;
  static const auto o = Options<P>()
      .add("skew_correction", &P::skew_correction,
           "give each return the nod angle at its own stamp, interpolated from the per-line encoder readings")
      .add("max_pose_gap", &P::max_pose_gap, at_least(0), "s", "returns inside a pose-file gap longer than this get no_pose (0: never)")
      .add("covariance", &P::covariance, "propagate each point's 3x3 covariance (sensor and pose_sigma) to cloud.pcd")
      .add("blind_lines", &P::blind_lines, bounds(0, 1e6), "lines", "warn of this many consecutive lines without any return (0: never)");
  return o;
}

const OptionSchema& register_schema() { return register_options().schema(); }

namespace {

// register_pass works through a pass a chunk of returns at a time, in three sweeps:
//   1. per return, in order (scalar, branchy): the nod angle, labels, the calibrated range, the
//      pose segment and its weights, the bearing's sine and cosine, the nod's base angle and (for
//      the covariance) its sigma;
//   2. per run of returns in one pose segment (straight-line arithmetic over arrays, which the
//      compiler turns into vector instructions): the origin, R_MN, the nod's sine and cosine and
//      the map point, written straight into the pass, and the covariance kernel's inputs;
//   3. (covariance only) the kernel over the chunk, and its results copied to the registered
//      returns.
// Every return goes through the same arithmetic whatever its place in a chunk, so the values do
// not depend on where a chunk or a streamed line begins.
constexpr std::size_t kChunk = 128;  // returns, a multiple of CovarianceLanes::kGroup; the arrays (25 KB) stay in L1
static_assert(kChunk % CovarianceLanes::kGroup == 0, "CovarianceLanes::compute runs whole groups of lanes");

struct Chunk {
  // Sweep 1: pose weights; calibrated range; bearing cosine, sine; the nod's base cosine, sine and
  // the step from the base to the return's angle; the nod's sigma (covariance only).
  // (sin_a and vers_a are filled in sweep 1 only for a turn beyond SegmentMotion::kSmallTurn, in
  // a run of its own; sweep 2 computes the others and stores them.)
  double s[kChunk], sin_a[kChunk], vers_a[kChunk];
  double rc[kChunk], cn[kChunk], sn[kChunk];
  double base_c[kChunk], base_s[kChunk], step[kChunk];
  double sig_nod[kChunk];
  // Sweep 2, covariance only: the covariance kernel's inputs, the middle axis' squared length
  // (gimbal lock) and, after CovarianceLanes::compute, the six entries.
  float in[CovarianceLanes::kInputs][kChunk];
  double middle2[kChunk];
  float res[6][kChunk];
};

// A run of returns [begin, end) of a chunk in one pose segment (motion index into the chunk's
// list), all with a small turn or all with a larger one (`turned`: weights from sweep 1).
struct Run {
  std::size_t begin, end, motion;
  bool turned;
};

// The nod's cosine and sine of return j: the base's turned by the step (angle addition, the
// step's by their series; a step of 0 gives the base's exactly).
inline void nod_cos_sin(const Chunk& c, std::size_t j, double& ce, double& se) {
  const double d = c.step[j], cd = detail::cos_small(d), sd = detail::sin_small(d);
  ce = c.base_c[j] * cd - c.base_s[j] * sd;
  se = c.base_s[j] * cd + c.base_c[j] * sd;
}

// Sweep 2 over one run. The sums are those of the Eigen expressions they replace, term for term
// and in the same order (R0 + sin_a B + vers_a C; t0 + s dt + sin_a tB + vers_a tC; R_MN v + o,
// whose third row Eigen sums right to left), so every coordinate is the same double as before.
template <bool kCovariance, bool kTurned>
void place_run(const SegmentMotion& mn, const SegmentMotion& mv, int ia, bool xyz, Chunk& c, std::size_t b,
               std::size_t e, double* __restrict x, double* __restrict y, double* __restrict z,
               double* __restrict ox, double* __restrict oy, double* __restrict oz) {
  const Eigen::Matrix3d &R0 = mn.R0, &B = mn.B, &C = mn.C;
  const double angle = mn.angle;
  const double r00 = R0(0, 0), r10 = R0(1, 0), r20 = R0(2, 0), r01 = R0(0, 1), r11 = R0(1, 1), r21 = R0(2, 1),
               r02 = R0(0, 2), r12 = R0(1, 2), r22 = R0(2, 2);
  const double b00 = B(0, 0), b10 = B(1, 0), b20 = B(2, 0), b01 = B(0, 1), b11 = B(1, 1), b21 = B(2, 1),
               b02 = B(0, 2), b12 = B(1, 2), b22 = B(2, 2);
  const double c00 = C(0, 0), c10 = C(1, 0), c20 = C(2, 0), c01 = C(0, 1), c11 = C(1, 1), c21 = C(2, 1),
               c02 = C(0, 2), c12 = C(1, 2), c22 = C(2, 2);
  const double t0x = mn.t0.x(), t0y = mn.t0.y(), t0z = mn.t0.z(), dtx = mn.dt.x(), dty = mn.dt.y(), dtz = mn.dt.z();
  const double tbx = mn.tB.x(), tby = mn.tB.y(), tbz = mn.tB.z(), tcx = mn.tC.x(), tcy = mn.tC.y(), tcz = mn.tC.z();
  // For the covariance: the vehicle's translation and inner pose axis (of T_M_V, not T_M_N).
  const double vt0x = mv.t0.x(), vt0y = mv.t0.y(), vt0z = mv.t0.z(), vdtx = mv.dt.x(), vdty = mv.dt.y(),
               vdtz = mv.dt.z(), vtbx = mv.tB.x(), vtby = mv.tB.y(), vtbz = mv.tB.z(), vtcx = mv.tC.x(),
               vtcy = mv.tC.y(), vtcz = mv.tC.z();
  const double i0x = mv.R0(0, ia), i0y = mv.R0(1, ia), i0z = mv.R0(2, ia), ibx = mv.B(0, ia), iby = mv.B(1, ia),
               ibz = mv.B(2, ia), icx = mv.C(0, ia), icy = mv.C(1, ia), icz = mv.C(2, ia);
  // The middle axis' squared length without a branch in the loop: iy^2 + iz^2 for xyz, ix^2 + iy^2
  // for zyx (adding an exact 0 changes no bit).
  const double wx = xyz ? 0.0 : 1.0, wz = xyz ? 1.0 : 0.0;
  using L = CovarianceLanes;
  for (std::size_t j = b; j < e; ++j) {
    // The pose weights (SegmentMotion::weights, the usual small turn here, a larger one from sweep 1).
    const double s = c.s[j];
    double sa, va;
    if constexpr (kTurned) {
      sa = c.sin_a[j];
      va = c.vers_a[j];
    } else {
      SegmentMotion::small_turn(s * angle, sa, va);
      c.sin_a[j] = sa;
      c.vers_a[j] = va;
    }
    const double px = ((t0x + s * dtx) + sa * tbx) + va * tcx;
    const double py = ((t0y + s * dty) + sa * tby) + va * tcy;
    const double pz = ((t0z + s * dtz) + sa * tbz) + va * tcz;
    const double m00 = (r00 + sa * b00) + va * c00, m10 = (r10 + sa * b10) + va * c10, m20 = (r20 + sa * b20) + va * c20;
    const double m01 = (r01 + sa * b01) + va * c01, m11 = (r11 + sa * b11) + va * c11, m21 = (r21 + sa * b21) + va * c21;
    const double m02 = (r02 + sa * b02) + va * c02, m12 = (r12 + sa * b12) + va * c12, m22 = (r22 + sa * b22) + va * c22;
    double ce, se;
    nod_cos_sin(c, j, ce, se);
    const double rc = c.rc[j], rcn = rc * c.cn[j];
    const double v0 = rcn * ce, v1 = rc * c.sn[j], v2 = rcn * se;  // nod_frame_point
    const double qx = ((m00 * v0 + m01 * v1) + m02 * v2) + px;
    const double qy = ((m10 * v0 + m11 * v1) + m12 * v2) + py;
    const double qz = (m20 * v0 + (m21 * v1 + m22 * v2)) + pz;
    ox[j] = px;
    oy[j] = py;
    oz[j] = pz;
    x[j] = qx;
    y[j] = qy;
    z[j] = qz;
    if constexpr (kCovariance) {
      const double ix = (i0x + sa * ibx) + va * icx, iy = (i0y + sa * iby) + va * icy, iz = (i0z + sa * ibz) + va * icz;
      c.middle2[j] = (wx * ix * ix + iy * iy) + wz * iz * iz;  // CovarianceLanes::middle_norm2
      c.in[L::kR][j] = static_cast<float>(rc);
      c.in[L::kCn][j] = static_cast<float>(c.cn[j]);
      c.in[L::kSn][j] = static_cast<float>(c.sn[j]);
      c.in[L::kCe][j] = static_cast<float>(ce);
      c.in[L::kSe][j] = static_cast<float>(se);
      c.in[L::kVarNod][j] = static_cast<float>(c.sig_nod[j] * c.sig_nod[j]);
      c.in[L::kR00][j] = static_cast<float>(m00);
      c.in[L::kR10][j] = static_cast<float>(m10);
      c.in[L::kR20][j] = static_cast<float>(m20);
      c.in[L::kR01][j] = static_cast<float>(m01);
      c.in[L::kR11][j] = static_cast<float>(m11);
      c.in[L::kR21][j] = static_cast<float>(m21);
      c.in[L::kR02][j] = static_cast<float>(m02);
      c.in[L::kR12][j] = static_cast<float>(m12);
      c.in[L::kR22][j] = static_cast<float>(m22);
      c.in[L::kIx][j] = static_cast<float>(ix);
      c.in[L::kIy][j] = static_cast<float>(iy);
      c.in[L::kIz][j] = static_cast<float>(iz);
      c.in[L::kPx][j] = static_cast<float>(qx - (((vt0x + s * vdtx) + sa * vtbx) + va * vtcx));
      c.in[L::kPy][j] = static_cast<float>(qy - (((vt0y + s * vdty) + sa * vtby) + va * vtcy));
      c.in[L::kPz][j] = static_cast<float>(qz - (((vt0z + s * vdtz) + sa * vtbz) + va * vtcz));
    }
  }
}

}  // namespace

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
  // The nod's sine and cosine are those of a base angle (the reading that starts the return's
  // encoder bracket, or the line's own reading without skew correction), computed once per base,
  // turned by the small step to the return's angle (sweep 2). The base depends only on the
  // return's bracket, not on what came before, so a streamed line gets the same values. A step
  // beyond the series' range takes the return's own angle as its base, with a step of 0.
  double base = kNaN, base_c = 1.0, base_s = 0.0;
  // The pose segments met in the current chunk (SegmentMotion: T_M_V and T_M_N = T_M_V T_V_N as
  // R0 + sin(a) B + (1 - cos(a)) C), each built once when a return first falls in it. Like the
  // nod's base, a segment's motion depends only on the segment. Without poses, T_M_V is the
  // identity.
  constexpr std::size_t kNoSegment = std::numeric_limits<std::size_t>::max();
  std::vector<SegmentMotion> mv(1), mn(1, SegmentMotion{}.then(T_V_N));  // [0]: the current segment
  std::size_t seg_k = kNoSegment;
  // The nod's sigma depends on the encoder bracket's rate only: computed once per bracket.
  std::size_t sig_k = kNoSegment;
  const int ia = inner_pose_axis(order);
  const bool xyz = order == RpyOrder::kXyz;
  // Covariances are computed a chunk at a time, several returns per vector instruction.
  const std::unique_ptr<CovarianceLanes> lanes = params.covariance ? std::make_unique<CovarianceLanes>(order, sig) : nullptr;
  const std::unique_ptr<Chunk> chunk = std::make_unique<Chunk>();
  Chunk& c = *chunk;
  std::vector<Run> runs;

  for (std::size_t i0 = 0; i0 < n; i0 += kChunk) {
    const std::size_t m = std::min(kChunk, n - i0);
    // Sweep 1. The chunk's motions start with the segment the last chunk ended in.
    if (mv.size() > 1) {
      mv.front() = mv.back();
      mn.front() = mn.back();
      mv.resize(1);
      mn.resize(1);
    }
    runs.clear();
    for (std::size_t j = 0; j < m; ++j) {
      const std::size_t i = i0 + j;
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
      c.rc[j] = rc;

      bool has_pose = true;
      if (poses) {
        has_pose = poses->covers(stamp);
        if (has_pose) {
          const std::size_t k = poses->size() > 1 ? (pose_hint = poses->bracket(stamp, pose_hint)) : 0;
          if (k != seg_k) {
            mv.push_back(poses->motion(k));
            mn.push_back(mv.back().then(T_V_N));
            seg_k = k;
          }
          // The segment's duration is the gap between the two poses around the stamp.
          has_pose = params.max_pose_gap <= 0.0 || poses->size() < 2 || mv.back().duration <= params.max_pose_gap;
        }
      }

      if (!has_return) {
        pass.label[i] = Label::kNoReturn;
      } else if (!(rc >= sensor.range_min && rc <= sensor.range_max)) {
        pass.label[i] = Label::kOutOfRange;
      } else if (!has_pose) {
        pass.label[i] = Label::kNoPose;
      }
      if (!has_pose) continue;  // no run holds it: its point and origin stay NaN

      if (params.covariance && has_return) {
        if (!(sig_k == enc_hint)) {
          const double omega = sensor.encoder_latency_sigma > 0 ? track.rate_at(stamp, rate_hint) : 0.0;
          sig.nod = std::sqrt(enc_var + std::pow(omega * sensor.encoder_latency_sigma, 2));
          // Without skew correction the hint does not follow the stamp: no caching then.
          sig_k = params.skew_correction ? enc_hint : kNoSegment;
        }
        c.sig_nod[j] = sig.nod;
      }
      // The pose weights as SegmentMotion::weights gives them (without poses, those of the fixed
      // identity: s = 0 and no turn); sweep 2 finishes the usual small turn.
      const SegmentMotion& sm = mn.back();
      const double s = poses ? (stamp - sm.stamp0) * sm.inv_duration : 0.0;
      c.s[j] = s;
      const double a = s * sm.angle;
      const bool turned = !(std::fabs(a) <= SegmentMotion::kSmallTurn);
      if (turned) {
        SegmentMotion::Weights w;
        SegmentMotion::turn(a, w);
        c.sin_a[j] = w.sin_a;
        c.vers_a[j] = w.vers_a;
      }
      const std::size_t motion = mv.size() - 1;
      if (!runs.empty() && runs.back().end == j && runs.back().motion == motion && runs.back().turned == turned)
        ++runs.back().end;
      else
        runs.push_back({j, j + 1, motion, turned});
      // The bearing's sine and cosine repeat from line to line for a beam: computed once per value.
      const float bearing = pass.bearing[i];
      const std::size_t slot = static_cast<std::size_t>(pass.beam[i]) & (kBearingCache - 1);
      if (!(bearing_cache[slot].bearing == bearing))
        bearing_cache[slot] = {bearing, std::cos(static_cast<double>(bearing)), std::sin(static_cast<double>(bearing))};
      c.cn[j] = bearing_cache[slot].c;
      c.sn[j] = bearing_cache[slot].s;
      const double d = eta - eta_base;
      if (std::fabs(d) <= detail::kSmallAngle) {
        if (!(eta_base == base)) {
          base = eta_base;
          base_c = std::cos(eta_base);
          base_s = std::sin(eta_base);
        }
        c.base_c[j] = base_c;
        c.base_s[j] = base_s;
        c.step[j] = d;
      } else {
        c.base_c[j] = std::cos(eta);
        c.base_s[j] = std::sin(eta);
        c.step[j] = 0.0;
      }
    }

    // Sweep 2.
    double *x = pass.x.data() + i0, *y = pass.y.data() + i0, *z = pass.z.data() + i0;
    double *ox = pass.ox.data() + i0, *oy = pass.oy.data() + i0, *oz = pass.oz.data() + i0;
    for (const Run& run : runs) {
      const auto place = lanes ? (run.turned ? &place_run<true, true> : &place_run<true, false>)
                               : (run.turned ? &place_run<false, true> : &place_run<false, false>);
      place(mn[run.motion], mv[run.motion], ia, xyz, c, run.begin, run.end, x, y, z, ox, oy, oz);
    }
    if (!lanes) continue;

    // Sweep 3: the covariances of the chunk's lanes, then each registered return's six entries.
    lanes->compute(&c.in[0][0], &c.res[0][0], kChunk, m);
    for (const Run& run : runs) {
      for (std::size_t j = run.begin; j < run.end; ++j) {
        const double rc = c.rc[j];
        if (!(rc == rc)) continue;  // no return
        const std::size_t i = i0 + j;
        float* out = &pass.cov[6 * i];
        if (!(c.middle2[j] < CovarianceLanes::kGimbalLock)) {
          for (int k = 0; k < 6; ++k) out[k] = c.res[k][j];
          continue;
        }
        // Gimbal lock: the angle path, from the same doubles sweep 2 had.
        const SegmentMotion::Weights w{c.s[j], c.sin_a[j], c.vers_a[j]};
        double ce, se;
        nod_cos_sin(c, j, ce, se);
        const Eigen::Vector3d Rp = Eigen::Vector3d(pass.x[i], pass.y[i], pass.z[i]) - mv[run.motion].translation(w);
        sig.nod = c.sig_nod[j];
        const Eigen::Matrix3d C = point_covariance_fast(rc, c.cn[j], c.sn[j], ce, se, mv[run.motion].rotation(w), T_V_N,
                                                        mn[run.motion].rotation(w), Rp, order, sig);
        out[0] = static_cast<float>(C(0, 0));
        out[1] = static_cast<float>(C(0, 1));
        out[2] = static_cast<float>(C(0, 2));
        out[3] = static_cast<float>(C(1, 1));
        out[4] = static_cast<float>(C(1, 2));
        out[5] = static_cast<float>(C(2, 2));
      }
    }
  }
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
  StageKind kind() const override { return StageKind::kLabeller; }
  int reach() const override { return 1; }  // the previous line's encoder reading
  // The run's poses are relative to its map origin (Pipeline::prepare, pcdp/core/georef.hpp): every
  // coordinate placed here is too, computed in double, whatever the pose file's magnitude.
  void label(Pass& pass, StageReport& report) const override {
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
            const RegisterParams p = register_options().bind(sc.options);
            return std::make_unique<RegisterStage>(p, ctx);
          },
          /*needs=*/{},
          /*provides=*/{kRegisteredPoints}};
}

}  // namespace pcdp
