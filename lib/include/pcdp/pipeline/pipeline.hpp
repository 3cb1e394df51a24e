// Prepare, then execute. prepare() validates the whole pipeline (configuration, stage rules,
// the pose file) and reads no scan; run() streams the passes through the stages, scheduled by
// what each stage is (Stage::kind, lib/src/pipeline/scheduler.hpp), and writes the outputs
// atomically.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp {

struct PassSummary {
  std::string file;
  std::uint64_t returns = 0;
  std::uint64_t lines = 0;
  std::uint64_t kept = 0;
};

struct RunSummary {
  std::uint64_t input_returns = 0;
  LabelHistogram labels{};
  std::vector<PassSummary> passes;
  std::vector<StageReport> stages;
  std::vector<std::string> warnings;
  double seconds = 0.0;
  unsigned threads = 1;
  /// The run's phases in order ("prepass <stage>": the evidence of each two-phase stage,
  /// "passes", "finish": writing the products, "digest"): wall time and the process's CPU time over it.
  /// With as many cores as threads, threads x seconds - cpu_seconds is the core time the phase
  /// left idle.
  struct Phase {
    std::string name;
    double seconds = 0.0, cpu_seconds = 0.0;
  };
  std::vector<Phase> phases;
  std::string output_dir;
  std::vector<std::string> outputs;  ///< final paths written
  /// When the run started: UTC, ISO 8601 to the second ("2026-11-25T18:40:12Z").
  std::string started_at;
  /// A file the run read or wrote, with its size and SHA-256 (report.json `inputs` and `outputs`).
  struct FileRecord {
    std::string file;  ///< inputs: the path as configured; outputs: the product's name in output_dir
    std::string kind;  ///< inputs: "scan" or "poses"; outputs: empty
    std::uint64_t bytes = 0;
    std::string sha256;
  };
  std::vector<FileRecord> input_files;
  std::vector<FileRecord> output_files;  ///< every product but report.json, by name
  /// The map origin the products are relative to (pcdp/core/georef.hpp); zero: absolute.
  Eigen::Vector3d map_origin = Eigen::Vector3d::Zero();
};

/// Progress events: one per pass and stage ("read", stage names, "write").
struct ProgressEvent {
  std::size_t pass = 0;
  std::size_t passes = 0;
  std::string file;
  std::string step;
};
using ProgressFn = std::function<void(const ProgressEvent&)>;

class Pipeline {
 public:
  /// Builds every stage (its type looked up in `stages`: an embedder may pass builtin_stages()
  /// plus its own) and checks the rules between them (check_stage_order, one writer per product);
  /// loads the pose file. Throws ConfigError / InputError. Reads no scan.
  static Pipeline prepare(PipelineConfig config, const std::vector<StageInfo>& stages = builtin_stages());

  const PipelineConfig& config() const { return *config_; }
  /// Streams every pass through the stages, writes returns.pcd, cloud.pcd, the stages' products
  /// and report.json into a staging folder, then swaps it with output_dir (io::StagedOutputs:
  /// the complete old or new set, whatever fails or is killed). With threads > 1, passes are
  /// labelled and collected on that many worker threads (at most threads + 1 passes in memory)
  /// and merged in pass order: the outputs are identical whatever the thread count.
  /// Progress events come from the calling thread.
  RunSummary run(const ProgressFn& progress = {}, unsigned threads = 1);

 private:
  Pipeline() = default;
  std::shared_ptr<PipelineConfig> config_;
  RunContext context_;
  std::vector<std::unique_ptr<Stage>> stages_;
};

/// ConfigError naming the stage unless the stage list is in an order that works: every type known
/// in `stages`, each of a stage's StageInfo::needs provided by a stage before it, each thing
/// provided by one stage only (e.g. one `register`, before every stage that needs registered points).
void check_stage_order(const PipelineConfig& config, const std::vector<StageInfo>& stages = builtin_stages());

/// The report of a run as JSON text (effective configuration, versions, counts, timings).
std::string report_json(const PipelineConfig& config, const RunSummary& summary);

}  // namespace pcdp
