#include "pcdp/pipeline/stream.hpp"

#include <chrono>
#include <cmath>
#include <limits>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/pipeline/pipeline.hpp"

namespace pcdp {

LineStream::LineStream(PipelineConfig config, std::size_t block_lines, const std::vector<StageInfo>& stages)
    : config_(std::make_shared<PipelineConfig>(std::move(config))), block_(block_lines) {
  const PipelineConfig& cfg = *config_;
  if (block_ < 1) throw ConfigError("stream: block_lines must be at least 1");
  check_stage_order(cfg, stages);
  poses_ = std::make_shared<PoseTrack>(cfg.poses.empty() ? PoseTrack{} : io::read_pose_csv(cfg.poses, cfg.rpy_order));
  context_.config = config_.get();
  context_.poses = poses_;
  for (const auto& sc : cfg.stages) {
    auto st = find_stage(sc.type, stages)->create(sc, context_);
    // Labellers with a reach run on windows of lines; accumulators and two-phase stages need
    // every pass.
    if (st->kind() != StageKind::kLabeller || st->reach() < 0)
      throw ConfigError(sc.where + ": stage '" + sc.name + "' (" + sc.type +
                        ") cannot stream: it needs whole passes (a streaming pipeline holds register and the reject stages)");
    ahead_ += st->reach();
    stages_.push_back(std::move(st));
    StageReport r;
    r.name = sc.name;
    r.type = sc.type;
    reports_.push_back(r);
  }
}

LineStream::~LineStream() = default;
LineStream::LineStream(LineStream&&) noexcept = default;
LineStream& LineStream::operator=(LineStream&&) noexcept = default;

void LineStream::add_pose(const PoseSample& pose) {
  // RegisterStage holds the same PoseTrack (context_.poses), so it sees the new sample.
  poses_->append(pose);
}

std::vector<Pass> LineStream::push(const ScanLine& l) {
  const std::string where = "stream: line " + std::to_string(l.line);
  const std::size_t n = l.range.size();
  if (l.bearing.size() != n || l.stamp.size() != n || (!l.amplitude.empty() && l.amplitude.size() != n))
    throw InputError(where + ": range, bearing, stamp (and amplitude, if given) must have one value per return");
  if (static_cast<std::int64_t>(l.line) <= last_line_)
    throw InputError(where + ": field 'line' must increase (the last was " + std::to_string(last_line_) + ")");
  if (!std::isfinite(l.nod)) throw InputError(where + ": field 'nod' is not finite");
  double newest = last_stamp_;  // committed only when the whole line is valid: a refused line changes nothing
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(l.range[i]) || l.range[i] < 0 || !std::isfinite(l.bearing[i]) || !std::isfinite(l.stamp[i]))
      throw InputError(where + ", return " + std::to_string(i) + ": range must be finite and >= 0, bearing and stamp finite");
    if (l.stamp[i] <= newest)
      throw InputError(where + ", return " + std::to_string(i) + ": field 'stamp' must increase along the line and from line to line");
    newest = l.stamp[i];
  }
  last_stamp_ = newest;
  last_line_ = l.line;
  lines_.push_back(l);
  const std::size_t last = first_ + lines_.size() - 1;  // pass-relative index of this line
  if (last < static_cast<std::size_t>(ahead_)) return {};
  const std::size_t ready = last - static_cast<std::size_t>(ahead_);  // newest line whose context is complete
  if (ready + 1 < next_out_ + block_) return {};
  return finish(ready, false);
}

std::vector<Pass> LineStream::end_pass() {
  std::vector<Pass> out;
  if (!lines_.empty()) out = finish(first_ + lines_.size() - 1, true);
  lines_.clear();
  first_ = next_out_ = 0;
  ++pass_index_;
  return out;
}

std::vector<Pass> LineStream::finish(std::size_t upto, bool to_end) {
  std::vector<Pass> out;
  if (upto < next_out_) return out;
  // The window: `ahead_` lines before the first line to finish (its backward context) up to the
  // newest line (the forward context of the last one).
  const std::size_t from = next_out_ >= static_cast<std::size_t>(ahead_) ? next_out_ - static_cast<std::size_t>(ahead_) : 0;
  Pass w;
  w.index = pass_index_;
  w.source = "stream pass " + std::to_string(pass_index_);
  w.organized = true;
  for (std::size_t k = from; k < first_ + lines_.size(); ++k) {
    const ScanLine& l = lines_[k - first_];
    w.line_begin.push_back(w.range.size());
    for (std::size_t i = 0; i < l.range.size(); ++i) {
      w.line.push_back(l.line);
      w.beam.push_back(static_cast<std::uint32_t>(i));
      w.range.push_back(l.range[i]);
      w.bearing.push_back(l.bearing[i]);
      w.amplitude.push_back(l.amplitude.empty() ? std::numeric_limits<float>::quiet_NaN() : l.amplitude[i]);
      w.nod.push_back(l.nod);
      w.stamp.push_back(l.stamp[i]);
    }
  }
  w.line_begin.push_back(w.range.size());
  w.label.assign(w.range.size(), Label::kKept);
  w.flags.assign(w.range.size(), 0);
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    stages_[s]->label(w, reports_[s]);
    reports_[s].seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  // Cut the finished lines out of the window.
  for (std::size_t k = next_out_; k <= upto; ++k) {
    Pass o = lines_of(w, k - from, k - from + 1);
    out.push_back(std::move(o));
  }
  next_out_ = upto + 1;
  // Keep only the backward context of the next line to finish.
  const std::size_t keep_from = next_out_ >= static_cast<std::size_t>(ahead_) ? next_out_ - static_cast<std::size_t>(ahead_) : 0;
  while (!to_end && first_ < keep_from && !lines_.empty()) {
    lines_.pop_front();
    ++first_;
  }
  return out;
}

}  // namespace pcdp
