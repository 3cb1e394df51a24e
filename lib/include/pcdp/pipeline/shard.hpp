// Shards: one pipeline run split into tasks over contiguous pass ranges, on one machine or a
// batch cluster, with products byte-identical to Pipeline::run (docs/scaling.md).
//
// Phases: "evidence" (when the pipeline has a two-phase stage: each task collects that stage's
// evidence of its passes), "passes" (each task merges every evidence partial, then labels its
// passes and collects the accumulators' partials, and writes its returns.pcd / cloud.pcd
// records), "reduce" (one task: merges every partial in pass order, writes the products with
// the all-or-nothing commit of a run). Every partial file carries the pipeline hash, its phase,
// task and pass range; a missing, duplicated or foreign one is refused, naming the tasks to rerun.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/pipeline/pipeline.hpp"

namespace pcdp {

struct ShardPlan {
  std::string pipeline;           ///< absolute path of the pipeline file
  std::vector<std::string> sets;  ///< --set key=value, as given
  std::string output_dir;         ///< absolute; empty: the pipeline's own
  std::string cwd;                ///< the working directory --set paths are relative to
  std::string hash;               ///< of the pipeline file, the --set list, the scans and output_dir
  std::size_t passes = 0, shards = 0;
  std::vector<std::pair<std::size_t, std::size_t>> ranges;  ///< per task: [first, last) passes
  std::vector<std::string> phases;                          ///< "evidence" (maybe), "passes", "reduce"
  /// The number of tasks of `phase` (1 for the reduce).
  std::size_t tasks(const std::string& phase) const { return phase == "reduce" ? 1 : shards; }
};

/// Validates the pipeline (reads no scan) and plans contiguous pass ranges for `shards` tasks.
/// ConfigError (exit 2) for a plan that cannot work (more shards than passes, two two-phase stages).
ShardPlan make_shard_plan(const std::string& pipeline, const std::vector<std::string>& sets,
                          const std::string& output_dir, std::size_t shards);
/// Writes W/plan.json (refusing, ConfigError, a work dir that holds another pipeline's plan).
void write_shard_plan(const std::string& work_dir, const ShardPlan& plan);
/// Reads W/plan.json (InputError naming it when missing or malformed).
ShardPlan read_shard_plan(const std::string& work_dir);
/// Runs task `index` of `phase` ("evidence" or "passes"): writes its partial file atomically.
void run_shard_task(const std::string& work_dir, const std::string& phase, std::size_t index);
/// The reduce: merges every partial, writes the products into the output folder and commits.
/// InputError naming the tasks to rerun when a partial is missing, duplicated or foreign.
RunSummary run_shard_reduce(const std::string& work_dir);

}  // namespace pcdp
