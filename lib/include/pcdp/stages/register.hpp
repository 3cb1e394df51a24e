// Stage `register`: raw returns -> map frame (docs/data_contract.md "Units and frames").
//
// For every return: calibrated range (Ye & Borenstein eqs. 1-3, true = k * measured + b), the nod
// angle at the return's own stamp (skew correction, skew.hpp), the point in the nod frame, the
// mount T_V_N, and T_M_V interpolated at the return's stamp (linear position, slerp orientation):
//   p_M = R_MV(t) * (R_VN * p_N + t_VN) + t_MV(t).
// With `covariance`, each registered return also gets the 3x3 covariance of its map point from
// range_sigma, bearing_resolution, encoder_resolution and encoder_latency_sigma (times the local
// nod rate) and pose_sigma, propagated to first order (uncertainty.hpp).
// Labels (first that applies): no_return (range 0 or NaN), out_of_range (calibrated range outside
// [sensor.range_min, sensor.range_max]), no_pose (stamp outside the pose file, or inside a gap
// longer than max_pose_gap). Out-of-range returns still get their map point when a pose exists.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/pipeline/stage.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp {

struct RegisterParams {
  bool skew_correction = true;
  double max_pose_gap = 1.0;  ///< s; 0 disables the check
  bool covariance = true;     ///< propagate the per-point covariance (uncertainty.hpp)
  int blind_lines = 5;        ///< warn of this many consecutive lines without a return
};

/// Runs of at least `min_lines` consecutive lines without any return (a sensor blinded by the sun,
/// Broten & Collier 7.5, or covered): one warning each, naming the file and the line range.
std::vector<std::string> blind_runs(const Pass& pass, int min_lines);

/// The options of `register`, bound to RegisterParams; their schema drives validation, describe
/// and docs.
const Options<RegisterParams>& register_options();
const OptionSchema& register_schema();

/// Pure function: registers `pass` in place (labels, range_cal, nod_at_return, x/y/z, origins).
/// `poses` may be null (T_M_V = identity for every stamp).
void register_pass(Pass& pass, const RegisterParams& params, const SensorParams& sensor,
                   const Eigen::Isometry3d& T_V_N, const PoseTrack* poses, const PoseSigma& pose_sigma = PoseSigma{},
                   RpyOrder order = RpyOrder::kXyz);

StageInfo register_stage_info();

}  // namespace pcdp
