// Internal to the shard commands (shard.cpp, shard_reduce.cpp, shard_files.cpp): the partial files'
// headers, reports and checks, and the pipeline as the tasks prepare it (docs/scaling.md).
#pragma once

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/pipeline/shard.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp::detail::shard {

namespace fs = std::filesystem;

std::string json_string(const std::string& s);
std::string read_text(const std::string& path);

/// The configured stages, as Pipeline::prepare builds them.
struct Prepared {
  PipelineConfig cfg;
  RunContext context;
  std::vector<std::unique_ptr<Stage>> stages;
  std::size_t two_phase = std::numeric_limits<std::size_t>::max();  ///< the two-phase stage, if any
};

/// The pipeline of the plan, prepared (in the plan's working directory, for --set paths).
std::unique_ptr<Prepared> prepare(const ShardPlan& plan);
/// The plan's hash of the pipeline file, --set list, output folder, scans and poses.
std::string hash_of(const ShardPlan& plan, const PipelineConfig& cfg);
void put_report(std::ostream& o, const StageReport& r);
void get_report(std::istream& i, StageReport& r);
/// W/<phase>/task-NNNN.part
std::string part_path(const std::string& w, const std::string& phase, std::size_t t);
/// An empty partial of the stage's type: collect() of a pass with no returns (the merge identity).
std::unique_ptr<Partial> empty_partial(const Stage& stage);
/// The provenance at the start of every partial file.
void put_header(std::ostream& o, const ShardPlan& plan, const std::string& phase, std::size_t t);
/// Opens every partial of `phase`, each checked; an InputError naming the tasks to rerun.
std::vector<std::unique_ptr<std::ifstream>> open_all(const std::string& w, const ShardPlan& plan, const std::string& phase);
/// label() with the accounting of what it changed (as the scheduler does).
void label_counted(const Stage& st, Pass& pass, StageReport& rep);

/// Writes with a temporary name, renamed into place when complete.
class AtomicOut {
 public:
  explicit AtomicOut(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp") {
    fs::create_directories(fs::path(path_).parent_path());
    out_.open(tmp_, std::ios::binary | std::ios::trunc);
    if (!out_) throw OutputError(tmp_ + ": cannot write it (" + std::strerror(errno) + ")");
  }
  std::ostream& stream() { return out_; }
  void commit() {
    out_.flush();
    if (!out_) throw OutputError(tmp_ + ": cannot write it (" + std::strerror(errno) + ")");
    out_.close();
    fs::rename(tmp_, path_);
  }

 private:
  std::string path_, tmp_;
  std::ofstream out_;
};

/// Runs f; an InputError gets `path` in front.
template <class F>
void named(const std::string& path, F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

}  // namespace pcdp::detail::shard
