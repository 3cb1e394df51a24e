// The stage interface and the explicit registry of built-in stages.
//
// A stage is one header + one source + one line in registry.cpp + one test file. Stages see one
// pass at a time (passes are streamed); fusion stages accumulate across passes and write their
// products in finish().
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/core/transforms.hpp"
#include "pcdp/pipeline/work_share.hpp"

namespace pcdp {

struct Pass;

/// What a stage did, filled in by the pipeline (counts, timings) and by the stage (metrics,
/// warnings). Written to report.json.
struct StageReport {
  std::string name;
  std::string type;
  std::uint64_t in = 0;   ///< kept returns entering the stage
  std::uint64_t out = 0;  ///< kept returns leaving it
  LabelHistogram rejected{};  ///< returns this stage moved from kept to each label
  double seconds = 0.0;
  std::map<std::string, double> metrics;  ///< stage-specific numbers (e.g. "repaired")
  std::vector<std::string> warnings;
};

/// Where a stage may write products (fusion outputs); paths are temporary until the run commits.
class OutputSink {
 public:
  virtual ~OutputSink() = default;
  /// A temporary path for `filename` in the output folder; renamed to its final name on commit.
  virtual std::string staged_path(const std::string& filename) = 0;
};

/// The result of a stage's per-pass computation (Stage::compute), applied later in pass order.
struct StageWork {
  virtual ~StageWork() = default;
};

/// How the pipeline may run a stage on several passes at once (threads, identical results):
///  - concurrent(): process() reads no state that changes between passes, so it may run on
///    different passes at the same time (register, the reject stages, check_consistency after its
///    prepass);
///  - split(): the stage accumulates across passes (fusion) but separates the costly per-pass
///    part, compute() (const, any thread, reads the pass as it is at the stage's place in the
///    chain), from apply(), which updates the stage's state and runs in pass order;
///  - neither: process() runs in pass order on one thread.
class Stage {
 public:
  virtual ~Stage() = default;
  virtual bool concurrent() const { return false; }
  /// For the line streaming API (stream.hpp): how many scan lines before and after a line this
  /// stage's result for it depends on; -1 if it cannot run on a window of lines (it needs every
  /// line of the pass, or every pass).
  virtual int stream_reach() const { return -1; }
  virtual bool split() const { return false; }
  /// split() stages: the per-pass part; must not change the stage. It may divide its work into
  /// tasks for `share` (threads with no pass to take run some of them).
  virtual std::unique_ptr<StageWork> compute(const Pass& /*pass*/, StageReport& /*report*/, WorkShare& /*share*/) const {
    return nullptr;
  }
  /// split() stages: folds one pass's work into the stage's state, in pass order.
  virtual void apply(std::unique_ptr<StageWork> /*work*/, StageReport& /*report*/) {}
  /// Processes one pass in place: may set labels, points, ranges. Must not change which
  /// returns exist (every input return is kept exactly once, docs/data_contract.md).
  virtual void process(Pass& pass, StageReport& report) = 0;
  /// After the last pass: write products, add run-level metrics.
  virtual void finish(OutputSink& /*sink*/, StageReport& /*report*/) {}
  /// The file names finish() writes into the output folder (checked before the run: two stages
  /// must not write the same product).
  virtual std::vector<std::string> products() const { return {}; }
  /// Stages whose products can be written independently split finish() into parts; with
  /// threads, the pipeline runs the parts of every stage at once, each with its own report,
  /// merged in order. Parts of one stage may run concurrently: they must not change shared
  /// state. A part may divide its work into tasks for `share` (threads with no part left run
  /// some of them). By default one part, finish() itself.
  virtual std::size_t finish_parts() const { return 1; }
  virtual void finish_part(std::size_t /*part*/, OutputSink& sink, StageReport& report, WorkShare& /*share*/) {
    finish(sink, report);
  }
  /// Stages that need evidence from every pass before labelling any (check_consistency) return
  /// true; the pipeline then first streams every pass through the stages before them and hands it
  /// to prepass(), then runs the whole chain as usual.
  virtual bool wants_prepass() const { return false; }
  virtual void prepass(const Pass& /*pass*/) {}
  /// Prepass stages may split it like split(): prepass_compute (const, any thread) and
  /// prepass_apply (in pass order). prepass_split() says they do.
  virtual bool prepass_split() const { return false; }
  virtual std::unique_ptr<StageWork> prepass_compute(const Pass& /*pass*/) const { return nullptr; }
  virtual void prepass_apply(std::unique_ptr<StageWork> /*work*/) {}
  /// After the prepass has seen every pass, before the first process(): may use up to `threads`
  /// threads; its result must not depend on how many.
  virtual void prepass_finish(unsigned /*threads*/) {}
};

/// Shared, read-only resources of a run, loaded in the prepare phase.
struct RunContext {
  const PipelineConfig* config = nullptr;
  /// T_M_V(t); empty when the pipeline has no pose file (T_M_V = identity).
  std::shared_ptr<const PoseTrack> poses;
  /// The map origin (pcdp/core/georef.hpp): `poses` and so every registered coordinate are relative to
  /// it; products that state map metres (the GeoTIFF) add it back. Zero unless the poses are
  /// georeferenced.
  Eigen::Vector3d map_origin = Eigen::Vector3d::Zero();
};

struct StageInfo {
  std::string type;
  std::string summary;  ///< one line, for `pcd_pipeline stages`
  OptionSchema schema;
  /// Builds a configured instance; may throw ConfigError for rules across options.
  std::function<std::unique_ptr<Stage>(const StageConfig&, const RunContext&)> create;
};

/// All built-in stages, in one explicit list (registry.cpp). No static self-registration: it
/// silently loses stages in static builds.
const std::vector<StageInfo>& builtin_stages();
/// nullptr when unknown.
const StageInfo* find_stage(const std::string& type);
std::vector<std::string> stage_type_names();

}  // namespace pcdp
