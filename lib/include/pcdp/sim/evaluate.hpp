// Scoring a run against simulator ground truth (`pcd_pipeline evaluate`).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "pcdp/core/labels.hpp"

namespace pcdp {

struct LabelScore {
  std::uint64_t truth = 0;          ///< returns with this truth label
  std::uint64_t rejected = 0;       ///< of those, not kept by the run (any reason)
  std::uint64_t same_label = 0;     ///< of those, given exactly this label by the run
  std::uint64_t run_labelled = 0;   ///< returns the run gave this label (any truth)
  double recall() const { return truth ? static_cast<double>(rejected) / static_cast<double>(truth) : 0.0; }
  double precision() const {
    return run_labelled ? static_cast<double>(same_label) / static_cast<double>(run_labelled) : 0.0;
  }
};

/// How far off the true surface an elevation cell may lie before it counts as a phantom obstacle
/// (above) or a missing one (below), m.
inline constexpr double kOffTheSurface = 0.3;

struct Evaluation {
  std::uint64_t returns = 0;
  LabelHistogram truth{};
  LabelHistogram run{};
  std::map<std::string, LabelScore> by_label;  ///< occlusion, mixed_pixel, low_amplitude
  std::uint64_t valid = 0;                     ///< truth-valid returns with a pose and in range
  std::uint64_t valid_wrongly_rejected = 0;    ///< of those, rejected by a filter label
  double valid_false_rejection() const {
    return valid ? static_cast<double>(valid_wrongly_rejected) / static_cast<double>(valid) : 0.0;
  }
  // Registration error of kept truth-valid returns, m.
  std::uint64_t compared = 0;
  double error_median = 0, error_p95 = 0, error_rms = 0;
  double implied_median = 0;  ///< median over returns of the RMS error the noise model implies (0: unknown)
  // Elevation (when the run has elevation.tif and the truth has height.pcd).
  bool has_elevation = false;
  std::uint64_t truth_cells = 0, observed_cells = 0;  ///< of the true grid, observed by the run
  std::uint64_t scored_cells = 0;                      ///< observed, away from edges of the true surface
  double elevation_rmse = 0, elevation_bias = 0, elevation_abs_median = 0, elevation_abs_p95 = 0;
  /// Observed cells (edges included) whose surface lies more than kOffTheSurface above the highest
  /// true height over the cell and its 8 neighbours (phantom obstacles), or below the lowest.
  std::uint64_t cells_above = 0, cells_below = 0;
  double coverage() const { return truth_cells ? static_cast<double>(observed_cells) / static_cast<double>(truth_cells) : 0.0; }
};

/// Noise of the simulated sensor, for the implied registration error (from truth/scene.yaml).
struct NoiseModel {
  double range_sigma = 0, encoder_resolution = 0, position_sigma = 0, rpy_sigma = 0;
  bool known = false;
};

/// Scores `run_dir`/returns.pcd against `truth_dir`/truth/pass_*.pcd (matched by pass, line,
/// beam). Throws InputError when files are missing or do not match.
Evaluation evaluate_run(const std::string& truth_dir, const std::string& run_dir, const NoiseModel& noise);

std::string evaluation_table(const Evaluation& e);
std::string evaluation_json(const Evaluation& e);

}  // namespace pcdp
