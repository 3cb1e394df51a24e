// Stage `reject_mixed_pixels` as the pipeline schedules it: a per-pass labeller, the lines it
// reads on each side in streaming, and its construction from the validated options. The
// algorithm is in reject_mixed_pixels.cpp, the options in reject_mixed_pixels_options.cpp.
#include <algorithm>
#include <array>
#include <iterator>
#include <utility>
#include <memory>

#include "pcdp/core/pass.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "reject_mixed_pixels_detail.hpp"

namespace pcdp {

using namespace mixed_detail;

namespace {
class RejectMixedPixelsStage final : public Stage {
 public:
  RejectMixedPixelsStage(MixedPixelParams p, const RunContext& ctx)
      : params_(p), sensor_(ctx.config->sensor), pose_sigma_(ctx.poses ? ctx.config->pose_sigma : PoseSigma{0.0, 0.0}) {}
  StageKind kind() const override { return StageKind::kLabeller; }
  // Across lines it looks MixedPixelParams::window lines (fixed at 8 for pipelines; kObjectReach
  // for a spike's object, within it) each way, past up to kFootprintReach lines inside a
  // footprint, plus one to read a nod reversal at the last of them: 31 lines with the extra
  // rounds. The max and min below keep it right for any window.
  int reach() const override {
    // Without the tests across lines, a side's 2-D patch still reads whether the same beam on the
    // lines before and after is usable, which each extra round reads after the round before has
    // labelled those lines: one line, plus one per round.
    if (!params_.across_lines) return 1 + kMaxExtraRounds;
    // Each extra round (runs of mixtures) reads its narrower window across the lines the round
    // before labelled (the nod reversals it also reads are raw data: no more lines).
    return std::max(params_.window + kFootprintReach, params_.spikes ? static_cast<int>(kObjectReach) : 0) + 1 +
           kMaxExtraRounds * std::min(params_.window, kRoundWindow);
  }
  void label(Pass& pass, StageReport& report) const override {
    // What found the mixed pixels this call labels (Pass::flags), counted into report.json's
    // metrics: the counts after less those before (another instance of the stage may have run).
    static constexpr std::pair<std::uint8_t, const char*> kEvidence[] = {
        {kFlagMixedAlong, "found_along_lines"}, {kFlagMixedAcross, "found_across_lines"},
        {kFlagBesideVoid, "found_beside_a_void"}, {kFlagSpike, "found_as_spikes"}, {kFlagMixedRun, "found_in_later_rounds"}};
    const auto count = [&] {
      std::array<double, std::size(kEvidence)> n{};
      for (std::size_t i = 0; i < pass.flags.size(); ++i)
        if (pass.label[i] == Label::kMixedPixel)
          for (std::size_t k = 0; k < n.size(); ++k) n[k] += (pass.flags[i] & kEvidence[k].first) != 0;
      return n;
    };
    const auto before = count();
    reject_mixed_pixels(pass, params_, sensor_, pose_sigma_);
    const auto after = count();
    for (std::size_t k = 0; k < after.size(); ++k) report.metrics[kEvidence[k].second] += after[k] - before[k];
  }

 private:
  MixedPixelParams params_;
  SensorParams sensor_;
  PoseSigma pose_sigma_;
};
}  // namespace

StageInfo reject_mixed_pixels_stage_info() {
  return {"reject_mixed_pixels",
          "mixed pixels (veil points) between foreground and background: geometry and amplitude mixing",
          reject_mixed_pixels_schema(),
          [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            const MixedPixelParams p = reject_mixed_pixels_options().bind(sc.options);
            return std::make_unique<RejectMixedPixelsStage>(p, ctx);
          }};
}

}  // namespace pcdp
