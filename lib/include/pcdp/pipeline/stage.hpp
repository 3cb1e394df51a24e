// The stage contract and the explicit registry of built-in stages (docs/adding_a_stage.md).
//
// A stage is one header + one source + one line in registry.cpp + one test file. Stages see one
// pass at a time (passes are streamed); a stage says what it is (StageKind) and the pipeline
// schedules it.
#pragma once

#include <functional>
#include <istream>
#include <ostream>
#include <map>
#include <stdexcept>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/pipeline/partial_io.hpp"
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

/// What an accumulator collects from passes (Stage::collect) and folds (Stage::merge): the stage's
/// own type, downcast by the stage alone.
/// save()/load() carry a partial between processes (shards, docs/scaling.md): load() replaces
/// the contents of a partial of the same type (an empty one comes from collect() of a pass with no
/// returns) with what save() wrote; a short or foreign stream is an InputError.
struct Partial {
  virtual ~Partial() = default;
  virtual void save(std::ostream& /*out*/) const { throw std::logic_error("this partial cannot be saved"); }
  virtual void load(std::istream& /*in*/) { throw std::logic_error("this partial cannot be loaded"); }
};

/// One independent piece of the products of an accumulator: `write` writes `files` (product names
/// the stage declared) to `staged` (their temporary paths, in the same order). The writers of every
/// accumulator run at the same time when the run has threads, each with its own report (merged
/// into the stage's in order); a writer may hand tasks to `share` (threads with no writer left
/// help). Writers of one stage may run concurrently: they only read what finish() handed them.
struct ProductWriter {
  std::vector<std::string> files;
  std::function<void(const std::vector<std::string>& staged, StageReport& report, WorkShare& share)> write;
};

/// What a stage is; the pipeline picks the schedule from it (docs/adding_a_stage.md).
enum class StageKind {
  kLabeller,     ///< label(): a pure function of one pass (or of a window of lines: reach())
  kAccumulator,  ///< collect() per pass, merge() in pass order, finish() -> products
  kTwoPhase,     ///< an accumulator over every pass first (its evidence); finish() readies label()
};

/// The stage contract. Six hooks; the pipeline (lib/src/pipeline/scheduler.cpp) owns threads,
/// ordering, work sharing, streaming and the report's counts:
///  - kLabeller: label() runs on any thread, passes in any order, several at once;
///  - kAccumulator: collect() runs on any thread for each pass (const: it reads the pass as the
///    stages before it left it and must not change the stage); merge() folds the partials in pass
///    order on one thread; finish() gets the partial of every pass and returns the product writers;
///  - kTwoPhase: first an evidence phase (the stages before it label each pass, collect() and
///    merge() as an accumulator), finish() readies the stage, then label() runs like a labeller.
/// Labels only: a stage never removes a return (docs/data_contract.md).
class Stage {
 public:
  /// `products`: the file names the stage writes into the output folder (checked before the run:
  /// two stages must not write the same product).
  explicit Stage(std::vector<std::string> products = {}) : products_(std::move(products)) {}
  virtual ~Stage() = default;
  virtual StageKind kind() const = 0;
  /// Labellers and two-phase stages: how many scan lines before and after a line its labels
  /// depend on (the line streaming API, stream.hpp, runs it on windows of lines); -1: the whole pass.
  virtual int reach() const { return -1; }
  /// Labellers and two-phase stages: labels (and may fill points, ranges of) one pass in place.
  /// Pure (const): any thread, any order. Must not change which returns exist.
  virtual void label(Pass& /*pass*/, StageReport& /*report*/) const {}
  /// Accumulators and two-phase stages: what one pass contributes. const: any thread, several
  /// passes at once; the costly per-pass part belongs here. May divide its work into tasks for
  /// `share` (threads with no pass to take run some).
  virtual std::unique_ptr<Partial> collect(const Pass& /*pass*/, StageReport& /*report*/, WorkShare& /*share*/) const {
    return nullptr;
  }
  /// Folds `later` (the partial of passes after those in `into`) into `into`. Associative:
  /// merge(merge(a, b), c) gives what merge(a, merge(b, c)) gives, so partials of threads, of
  /// streamed blocks or of shards combine to one result (InOrderPartial below helps when the
  /// fold's steps do not commute exactly).
  virtual void merge(Partial& /*into*/, Partial&& /*later*/) const {}
  /// After the last pass, with the partial of every pass (nullptr for a run without passes).
  /// Accumulators return the writers of their products(); two-phase stages ready label() and
  /// return none. May use up to `threads` threads; the result must not depend on how many.
  virtual std::vector<ProductWriter> finish(std::unique_ptr<Partial> /*all*/, StageReport& /*report*/,
                                            unsigned /*threads*/) {
    return {};
  }
  const std::vector<std::string>& products() const { return products_; }

 private:
  std::vector<std::string> products_;
};

/// Exact, associative partials for folds whose steps do not commute bit for bit (floating-point
/// sums, clamped updates, top-k lists): the partial that holds the run's first pass (Pass::index
/// 0) keeps the folded state; any other keeps its passes' items, in pass order, until it is merged
/// into one that holds the first pass. Folding in pass order then does exactly what folding pass
/// by pass does, whatever the grouping; memory stays bounded when partials are merged in pass
/// order (the pipeline does). `fold(State&, Item&&)` folds one pass's item.
template <class State, class Item>
struct InOrderPartial : Partial {
  std::unique_ptr<State> state;  ///< the folded state, once the partial holding the first pass merged
  std::vector<Item> pending;     ///< items of passes not folded yet, in pass order
  bool first = false;            ///< holds the run's first pass
  std::function<std::unique_ptr<State>()> make;  ///< a fresh state (set by of())

  /// The partial of one pass (`first`: the run's first pass). Folding starts at the first merge
  /// into the partial holding the first pass, so a partial of one pass can still be saved.
  template <class MakeState, class Fold>
  static std::unique_ptr<InOrderPartial> of(Item&& item, bool first, MakeState&& make_state, Fold&& /*fold*/) {
    auto p = std::make_unique<InOrderPartial>();
    p->first = first;
    p->make = std::forward<MakeState>(make_state);
    p->pending.push_back(std::move(item));
    return p;
  }
  /// Stage::merge for this partial.
  template <class Fold>
  void absorb(InOrderPartial&& later, Fold&& fold) {
    if (later.first || later.state) throw std::logic_error("InOrderPartial: a later partial holds the first pass");
    if (first) {
      if (!state) state = make();
      for (Item& it : pending) fold(*state, std::move(it));
      pending.clear();
      for (Item& it : later.pending) fold(*state, std::move(it));
    } else {
      for (Item& it : later.pending) pending.push_back(std::move(it));
    }
    later.pending.clear();
  }
  /// For Stage::finish: the state of every pass in the partial (`p` may be null: no pass), folded
  /// from make_state() when the partial does not hold the first pass.
  template <class MakeState, class Fold>
  static std::unique_ptr<State> fold_all(Partial* p, MakeState&& make_state, Fold&& fold) {
    auto* me = static_cast<InOrderPartial*>(p);
    std::unique_ptr<State> s = me && me->state ? std::move(me->state) : make_state();
    if (me)
      for (Item& it : me->pending) fold(*s, std::move(it));
    return s;
  }
  /// The items, unfolded (a partial whose state is folded stays in its process): each item by
  /// save_item(std::ostream&, const Item&) / load_item(std::istream&, Item&), found by ADL.
  void save(std::ostream& out) const override {
    if (state) throw std::logic_error("InOrderPartial: a folded partial cannot be saved");
    partial_io::put_str(out, "pcdp.in_order_partial.1");
    partial_io::put<std::uint8_t>(out, first ? 1 : 0);
    partial_io::put<std::uint64_t>(out, pending.size());
    for (const Item& it : pending) save_item(out, it);
  }
  void load(std::istream& in) override {
    partial_io::expect(in, "pcdp.in_order_partial.1");
    state.reset();
    first = partial_io::get<std::uint8_t>(in) != 0;
    const auto n = partial_io::get<std::uint64_t>(in);
    if (n > (1u << 24)) throw InputError("the partial is corrupt (" + std::to_string(n) + " passes)");
    pending.clear();
    pending.resize(n);
    for (Item& it : pending) load_item(in, it);
  }
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

/// What `register` provides: returns with their map points, sensor origins and labels of what
/// could not be placed (docs/data_contract.md).
inline const char* const kRegisteredPoints = "registered points";

struct StageInfo {
  std::string type;
  std::string summary;  ///< one line, for `pcd_pipeline stages`
  OptionSchema schema;
  /// Builds a configured instance; may throw ConfigError for rules across options.
  std::function<std::unique_ptr<Stage>(const StageConfig&, const RunContext&)> create;
  /// What the stage needs from the stages before it and what it provides to those after it
  /// (e.g. kRegisteredPoints). Pipeline::prepare checks the order: each need provided by an
  /// earlier stage, each thing provided by one stage only.
  std::vector<std::string> needs = {kRegisteredPoints};
  std::vector<std::string> provides = {};
};

/// All built-in stages, in one explicit list (registry.cpp). No static self-registration: it
/// silently loses stages in static builds.
const std::vector<StageInfo>& builtin_stages();
/// nullptr when unknown.
const StageInfo* find_stage(const std::string& type);
/// The stage of `type` in `stages`; nullptr when unknown.
const StageInfo* find_stage(const std::string& type, const std::vector<StageInfo>& stages);
std::vector<std::string> stage_type_names();

}  // namespace pcdp
