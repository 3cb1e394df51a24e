// `shard` and `shard-task`: a run split into tasks over pass ranges (docs/scaling.md).
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

namespace pcdp::cli {

struct ShardArgs {
  std::string pipeline, work_dir, output_dir;
  std::vector<std::string> sets;
  std::size_t shards = 0;
  bool local = false, submit = false, wait = false;
  double wait_timeout = 3600;
  std::vector<std::string> sbatch_args;
  // shard-task
  std::string task_work_dir, phase;
  std::string index;  ///< empty: $SLURM_ARRAY_TASK_ID
  CLI::App* shard = nullptr;
  CLI::App* task = nullptr;
};

/// Adds the two subcommands to `app`; their options are bound to `a`.
void add_shard_commands(CLI::App& app, ShardArgs& a);
/// The exit code of the parsed shard command; -1 when neither was given.
int run_shard_commands(const ShardArgs& a);

}  // namespace pcdp::cli
