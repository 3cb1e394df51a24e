// Stage `reject_dim_returns`: kept returns whose amplitude, normalised to a reference range, is
// below a floor. A laser return's amplitude falls with the square of its range from an extended
// surface; normalised to 10 m, what is left measures how much light the surface sends back. A
// return from a surface that sends back little (dark, wet, or hit at a glancing angle) has a low
// signal-to-noise ratio, and its range is the noisiest of the scan.
#pragma once

#include <cmath>
#include <memory>
#include <string>

#include "pcdp/core/pass.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

struct DimReturnsParams {
  double min_amplitude = 20.0;     ///< amplitude units, at reference_range
  double reference_range = 10.0;   ///< m
};

inline const OptionSchema& reject_dim_returns_schema() {
  static const OptionSchema s = {
      opt_double("min_amplitude", 20.0, 0.0, 1e6, "", "floor of the amplitude normalised to reference_range"),
      opt_double("reference_range", 10.0, 0.1, 1e4, "m", "range the amplitudes are normalised to: A (r / reference_range)^2"),
  };
  return s;
}

/// The stage's function: labels the dim kept returns of `pass` low_amplitude; returns how many.
/// Returns without an amplitude (NaN) or without a calibrated range are left as they are.
inline std::size_t reject_dim_returns(Pass& pass, const DimReturnsParams& p) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || i >= pass.range_cal.size()) continue;
    const double a = pass.amplitude[i], r = pass.range_cal[i];
    if (!std::isfinite(a) || !std::isfinite(r)) continue;
    const double q = r / p.reference_range;
    if (a * q * q < p.min_amplitude) {
      pass.label[i] = Label::kLowAmplitude;
      ++n;
    }
  }
  return n;
}

namespace {
class RejectDimReturnsStage final : public Stage {
 public:
  explicit RejectDimReturnsStage(DimReturnsParams p) : params_(p) {}
  StageKind kind() const override { return StageKind::kLabeller; }
  int reach() const override { return 0; }  // each return on its own: no other line
  void label(Pass& pass, StageReport& report) const override {
    report.metrics["dim"] += static_cast<double>(reject_dim_returns(pass, params_));
  }

 private:
  DimReturnsParams params_;
};
}  // namespace

inline StageInfo reject_dim_returns_stage_info() {
  return {"reject_dim_returns", "returns whose range-normalised amplitude is below a floor (dark, wet, glancing surfaces)",
          reject_dim_returns_schema(), [](const StageConfig& sc, const RunContext&) -> std::unique_ptr<Stage> {
            DimReturnsParams p;
            p.min_amplitude = sc.options.get_double("min_amplitude");
            p.reference_range = sc.options.get_double("reference_range");
            return std::make_unique<RejectDimReturnsStage>(p);
          }};
}

}  // namespace pcdp
