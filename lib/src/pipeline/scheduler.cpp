#include "pipeline/scheduler.hpp"

#include <algorithm>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pipeline/ordered_parallel.hpp"

namespace pcdp::detail {

LabelHistogram histogram(const Pass& p) {
  LabelHistogram h{};
  for (Label l : p.label) ++h[static_cast<std::size_t>(l)];
  return h;
}

void merge_report(StageReport& into, const StageReport& r) {
  into.in += r.in;
  into.out += r.out;
  for (std::size_t l = 0; l < kLabelCount; ++l) into.rejected[l] += r.rejected[l];
  into.seconds += r.seconds;
  for (const auto& [k, v] : r.metrics) into.metrics[k] += v;
  into.warnings.insert(into.warnings.end(), r.warnings.begin(), r.warnings.end());
}

/// A pass the last evidence phase kept as the stages before its stage left it (with their share
/// of the reports): the passes phase takes it from there instead of reading and labelling it again.
struct Scheduler::Kept {
  Pass pass;
  std::vector<StageReport> reports;
};

Scheduler::Scheduler(const std::vector<std::unique_ptr<Stage>>& stages, const PipelineConfig& cfg, RunSummary& sum,
                     const ProgressFn& progress)
    : stages_(stages), cfg_(cfg), sum_(sum), progress_(progress), window_(sum.threads + 1), running_(stages.size()) {}

Scheduler::~Scheduler() = default;

void Scheduler::label_counted(std::size_t s, Pass& pass, StageReport& rep) const {
  const LabelHistogram before = histogram(pass);
  const auto t0 = std::chrono::steady_clock::now();
  stages_[s]->label(pass, rep);
  rep.seconds += seconds_since(t0);
  const LabelHistogram after = histogram(pass);
  rep.in += before[0];
  rep.out += after[0];
  for (std::size_t l = 1; l < kLabelCount; ++l)
    if (after[l] > before[l]) rep.rejected[l] += after[l] - before[l];
}

void Scheduler::evidence() {
  std::size_t last = stages_.size();  // the last two-phase stage
  for (std::size_t s = 0; s < stages_.size(); ++s)
    if (kind(s) == StageKind::kTwoPhase) last = s;
  if (last == stages_.size()) return;
  // The first passes the last evidence phase reads are kept, as the stages before it left them,
  // when those stages all label (an accumulator before it would still have to collect them). At
  // most `window_` of them, so memory stays bounded by a few passes.
  bool keep = true;
  for (std::size_t e = 0; e < last; ++e) keep = keep && kind(e) != StageKind::kAccumulator;
  if (keep) {
    kept_.resize(std::min(cfg_.scans.size(), window_));
    resume_ = last;
  }
  for (std::size_t s = 0; s <= last; ++s)
    if (kind(s) == StageKind::kTwoPhase) evidence_of(s, last);
}

void Scheduler::evidence_of(std::size_t s, std::size_t last) {
  const std::string& name = cfg_.stages[s].name;
  const PhaseTimer phase(sum_, "prepass " + name);
  const std::size_t np = cfg_.scans.size();
  Stage& stage = *stages_[s];
  StageReport& rep = sum_.stages[s];
  struct Evidence {
    std::unique_ptr<Partial> partial;
    StageReport report;
  };
  std::unique_ptr<Partial> all;
  // Only the evidence travels to the calling thread, so more may wait for the merge: the stage
  // keeps every pass's evidence anyway, and a worker then need not wait for the calling thread.
  detail::ordered_parallel<Evidence>(
      np, sum_.threads, 4 * window_,
      [&](std::size_t k, WorkShare& share) {
        Evidence r;
        Pass pass = read_pass(cfg_.scans[k], k);
        const bool keep = s == last && k < kept_.size();
        StageReport scratch;
        std::vector<StageReport> reports(keep ? s : 0);
        for (std::size_t e = 0; e < s; ++e) {
          if (kind(e) == StageKind::kAccumulator) continue;  // they do not change the pass
          if (keep)
            label_counted(e, pass, reports[e]);  // its share of the run's report, as in the passes phase
          else
            stages_[e]->label(pass, scratch);
        }
        const auto t0 = std::chrono::steady_clock::now();
        r.partial = stage.collect(pass, r.report, share);
        r.report.seconds += seconds_since(t0);
        if (keep) kept_[k] = Kept{std::move(pass), std::move(reports)};  // slot k: this worker's alone
        return r;
      },
      [&](std::size_t k, Evidence&& r) {
        if (progress_) progress_({k, np, cfg_.scans[k], "prepass " + name});
        const auto t0 = std::chrono::steady_clock::now();
        if (!all)
          all = std::move(r.partial);
        else if (r.partial)
          stage.merge(*all, std::move(*r.partial));
        // The stage's own evidence work counts in its time (the stages before it, run again for
        // the evidence, are not counted anywhere: they are the price of streaming passes).
        r.report.seconds += seconds_since(t0);
        r.report.metrics["prepass_seconds"] += r.report.seconds;
        merge_report(rep, r.report);
      });
  const auto t0 = std::chrono::steady_clock::now();
  for (auto& w : stage.finish(std::move(all), rep, sum_.threads)) writers_.emplace_back(s, std::move(w));
  const double dt = seconds_since(t0);
  rep.seconds += dt;
  rep.metrics["prepass_seconds"] += dt;
}

void Scheduler::passes(const std::function<void(const Pass&)>& arrive, const std::function<void(Pass&)>& done) {
  const PhaseTimer phase(sum_, "passes");
  const std::size_t np = cfg_.scans.size(), ns = stages_.size();
  struct Processed {
    Pass pass;
    std::vector<StageReport> reports;  ///< this pass's share of each stage's report
    std::vector<std::unique_ptr<Partial>> partials;
  };
  detail::ordered_parallel<Processed>(
      np, sum_.threads, window_,
      [&](std::size_t k, WorkShare& share) {
        Processed r;
        r.reports.resize(ns);
        r.partials.resize(ns);
        std::size_t first = 0;  // the first stage to run here
        if (k < kept_.size() && kept_[k]) {
          r.pass = std::move(kept_[k]->pass);
          for (std::size_t e = 0; e < resume_; ++e) r.reports[e] = std::move(kept_[k]->reports[e]);
          kept_[k].reset();
          first = resume_;
        } else {
          r.pass = read_pass(cfg_.scans[k], k);
        }
        for (std::size_t s = first; s < ns; ++s) {
          StageReport& rep = r.reports[s];
          if (kind(s) != StageKind::kAccumulator) {
            label_counted(s, r.pass, rep);
            continue;
          }
          const auto t0 = std::chrono::steady_clock::now();
          r.partials[s] = stages_[s]->collect(r.pass, rep, share);
          rep.seconds += seconds_since(t0);
          rep.in += r.pass.kept();
          rep.out += r.pass.kept();
        }
        return r;
      },
      [&](std::size_t k, Processed&& r) {
        arrive(r.pass);
        for (std::size_t s = 0; s < ns; ++s) {
          if (progress_) progress_({k, np, cfg_.scans[k], cfg_.stages[s].name});
          StageReport& rep = sum_.stages[s];
          if (r.partials[s]) {
            const auto t0 = std::chrono::steady_clock::now();
            if (!running_[s])
              running_[s] = std::move(r.partials[s]);
            else
              stages_[s]->merge(*running_[s], std::move(*r.partials[s]));
            const double dt = seconds_since(t0);
            rep.seconds += dt;
            rep.metrics["in_order_seconds"] += dt;  // the part threads cannot share
          }
          merge_report(rep, r.reports[s]);
        }
        if (progress_) progress_({k, np, cfg_.scans[k], "write"});
        done(r.pass);
      });
}

void Scheduler::products(OutputSink& sink, const std::vector<Extra>& extra) {
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    if (kind(s) != StageKind::kAccumulator) continue;
    const auto t0 = std::chrono::steady_clock::now();
    auto w = stages_[s]->finish(std::move(running_[s]), sum_.stages[s], sum_.threads);
    sum_.stages[s].seconds += seconds_since(t0);
    for (auto& x : w) writers_.emplace_back(s, std::move(x));
  }
  // Writers are kept in stage order: errors are reported in that order, whatever the threads.
  std::stable_sort(writers_.begin(), writers_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::vector<std::string>> staged(writers_.size());
  for (std::size_t t = 0; t < writers_.size(); ++t) {
    const auto& [s, w] = writers_[t];
    const auto& declared = stages_[s]->products();
    for (const auto& f : w.files) {
      if (std::find(declared.begin(), declared.end(), f) == declared.end())
        throw std::logic_error("stage '" + cfg_.stages[s].name + "' writes " + f + ", which it did not declare");
      staged[t].push_back(sink.staged_path(f));
    }
  }
  // Every writer at once with threads: the longest (elevation.tif) beside the others; closing
  // returns.pcd and cloud.pcd (each copies its body behind the header) last. A writer may hand
  // tasks to the WorkShare (elevation.tif compresses one group of bands per task): a thread with
  // no writer left helps.
  const std::size_t nw = writers_.size(), n = nw + extra.size();
  detail::ordered_parallel<StageReport>(
      n, sum_.threads, n,
      [&](std::size_t t, WorkShare& share) {
        StageReport rep;
        if (t >= nw) {
          extra[t - nw]();
          return rep;
        }
        const auto t0 = std::chrono::steady_clock::now();
        writers_[t].second.write(staged[t], rep, share);
        const double dt = seconds_since(t0);
        rep.seconds += dt;
        if (dt > 1e-4) rep.metrics["finish_seconds"] += dt;  // products written at the end
        return rep;
      },
      [&](std::size_t t, StageReport&& rep) {
        if (t < nw) merge_report(sum_.stages[writers_[t].first], rep);
      });
  writers_.clear();
}

}  // namespace pcdp::detail
