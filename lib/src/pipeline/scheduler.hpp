// The schedule of a run, picked from what each stage is (Stage::kind, stage.hpp). Threads, the
// order of merges, work sharing and the bounded window of passes in memory live here only.
//
// Phases, in order:
//  1. evidence, for each two-phase stage: every pass is read, the stages before it label it (on
//     worker threads), the stage collects its evidence (workers), the partials are merged in pass
//     order (calling thread), then finish() readies its label();
//  2. passes: every pass through the whole chain on workers (labels, collects), the partials of
//     each accumulator merged in pass order, the pass handed to the caller in pass order;
//  3. products: each accumulator's finish(), then every product writer and the caller's own
//     writers (closing returns.pcd and cloud.pcd) at the same time.
// Results do not depend on the thread count: labels are pure, merges run in pass order.
#pragma once

#include <chrono>
#include <ctime>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp::detail {

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Times one phase of a run into RunSummary::phases: wall and process CPU time (all threads).
class PhaseTimer {
 public:
  PhaseTimer(RunSummary& sum, std::string name)
      : sum_(sum), name_(std::move(name)), wall0_(std::chrono::steady_clock::now()), cpu0_(std::clock()) {}
  ~PhaseTimer() {
    sum_.phases.push_back({name_, seconds_since(wall0_),
                           static_cast<double>(std::clock() - cpu0_) / static_cast<double>(CLOCKS_PER_SEC)});
  }
  PhaseTimer(const PhaseTimer&) = delete;
  PhaseTimer& operator=(const PhaseTimer&) = delete;

 private:
  RunSummary& sum_;
  std::string name_;
  std::chrono::steady_clock::time_point wall0_;
  std::clock_t cpu0_;
};

LabelHistogram histogram(const Pass& p);
/// Adds a pass's (or a writer's) share of a stage's report.
void merge_report(StageReport& into, const StageReport& r);

/// The run-level checks of what the passes kept (pipeline.cpp; docs/robustness.md): an InputError
/// for a run that keeps nothing or leaves most returns without a pose (unless allow_empty_output),
/// else warnings appended to `warnings`. Shared by Pipeline::run and the shard reduce.
void check_what_was_kept(const PipelineConfig& cfg, const PoseTrack* poses, const RunSummary& sum, double stamp_min,
                         double stamp_max, std::vector<std::string>& warnings);
/// The run's warnings in report.json's order: `run_warnings` (check_what_was_kept's), each stage's,
/// then poses so far from the map origin that the float32 products lose 1 mm.
void collect_warnings(const PipelineConfig& cfg, const PoseTrack* poses, const std::vector<std::string>& run_warnings,
                      RunSummary& sum);
/// Every file a pipeline run may write into its output folder (an earlier run's product that this
/// run does not write, map.ot after write_ot: false say, or evaluate's evaluation.json of the
/// earlier set, does not stay beside the new set).
const std::vector<std::string>& run_products();
/// The files a run reads that a commit into its output folder could replace (its scans and poses).
std::vector<std::string> run_inputs(const PipelineConfig& cfg);
/// report.json's inputs and products (every staged file but report.json), each with its size and
/// SHA-256, hashed on sum.threads threads.
void digest_files(const PipelineConfig& cfg, io::StagedOutputs& out, RunSummary& sum);

class Scheduler {
 public:
  /// `sum.stages` holds one report per stage; `sum.threads` the thread count.
  Scheduler(const std::vector<std::unique_ptr<Stage>>& stages, const PipelineConfig& cfg, RunSummary& sum,
            const ProgressFn& progress);
  ~Scheduler();

  /// Phase 1, for every two-phase stage in order.
  void evidence();
  /// Phase 2. `arrive(pass)` first (checks), then the accumulators' merges, then `done(pass)`:
  /// both on the calling thread, in pass order.
  void passes(const std::function<void(const Pass&)>& arrive, const std::function<void(Pass&)>& done);
  /// A writer of the caller's, run beside the stages' product writers.
  using Extra = std::function<void()>;
  /// Phase 3. `sink` gives the staged paths (called on this thread only); `extra` run last.
  void products(io::StagedOutputs& out, const std::vector<Extra>& extra);

 private:
  struct Kept;
  void evidence_of(std::size_t s, std::size_t last);
  /// label() with the accounting of what it changed.
  void label_counted(std::size_t s, Pass& pass, StageReport& rep) const;
  StageKind kind(std::size_t s) const { return stages_[s]->kind(); }

  const std::vector<std::unique_ptr<Stage>>& stages_;
  const PipelineConfig& cfg_;
  RunSummary& sum_;
  const ProgressFn& progress_;
  std::size_t window_;                               ///< passes in memory at once: threads + 1
  std::vector<std::unique_ptr<Partial>> running_;    ///< per accumulator: every pass merged so far
  std::vector<std::pair<std::size_t, ProductWriter>> writers_;  ///< (stage, writer)
  std::vector<std::optional<Kept>> kept_;            ///< passes kept from the last evidence phase
  std::size_t resume_ = 0;                           ///< the first stage a kept pass still needs
};

}  // namespace pcdp::detail
