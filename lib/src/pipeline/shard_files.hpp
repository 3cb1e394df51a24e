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
#include "pcdp/io/atomic_file.hpp"
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

/// Writes with a temporary name of this process (`<path>.tmp.<pid>`), renamed into place when
/// complete, holding the lock of `path` meanwhile: a second copy of the same task (a requeue, a
/// rerun while the first still runs) refuses at once (OutputError) instead of writing over the
/// first's files. Temporaries are removed when the task fails or gets SIGINT, SIGTERM or SIGHUP,
/// and a killed copy's (SIGKILL) by the next copy of the task.
class AtomicOut {
 public:
  explicit AtomicOut(std::string path);
  ~AtomicOut();
  AtomicOut(const AtomicOut&) = delete;
  AtomicOut& operator=(const AtomicOut&) = delete;
  std::ostream& stream() { return out_; }
  /// A further temporary for `final_path` (the task's record files), renamed by commit() before
  /// the partial itself: a partial on disk means its records are complete.
  std::string also(const std::string& final_path);
  void commit();

 private:
  std::string path_, tmp_;
  std::unique_ptr<io::OutputLock> lock_;
  std::vector<std::pair<std::string, std::string>> also_;  // (temporary, final)
  std::vector<int> slots_;  // in the signal cleanup table
  bool committed_ = false;
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
