#include "pcdp/pipeline/pipeline.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <optional>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/file_digest.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pipeline/ordered_parallel.hpp"

namespace pcdp {

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Times one phase of a run into RunSummary::phases: wall and process CPU time (all threads).
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

std::string utc_now_iso8601() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

LabelHistogram histogram(const Pass& p) {
  LabelHistogram h{};
  for (Label l : p.label) ++h[static_cast<std::size_t>(l)];
  return h;
}
}  // namespace

Pipeline Pipeline::prepare(PipelineConfig config) {
  Pipeline p;
  p.config_ = std::make_shared<PipelineConfig>(std::move(config));
  const PipelineConfig& cfg = *p.config_;
  if (cfg.stages.empty()) throw ConfigError(cfg.source + ": the pipeline is empty: 'stages' lists no stage");
  if (cfg.stages.front().type != "register")
    throw ConfigError(cfg.stages.front().where + ": stage '" + cfg.stages.front().name + "' (" +
                      cfg.stages.front().type +
                      "): the first stage must be 'register' (every other stage works on registered returns)");
  for (std::size_t i = 1; i < cfg.stages.size(); ++i)
    if (cfg.stages[i].type == "register")
      throw ConfigError(cfg.stages[i].where + ": stage '" + cfg.stages[i].name +
                        "' (register): 'register' may appear only once, as the first stage");
  p.context_.config = p.config_.get();
  if (!cfg.poses.empty()) {
    // Georeferenced poses: the run works relative to a local map origin (pcdp/core/georef.hpp).
    PoseTrack poses = io::read_pose_csv(cfg.poses, cfg.rpy_order);
    p.context_.map_origin = choose_map_origin(poses);
    if (!p.context_.map_origin.isZero()) poses = shift_poses(poses, p.context_.map_origin);
    p.context_.poses = std::make_shared<const PoseTrack>(std::move(poses));
  }
  for (const auto& sc : cfg.stages) p.stages_.push_back(find_stage(sc.type)->create(sc, p.context_));
  // Every product has one writer: a stage list that writes a file twice is refused before the run.
  std::map<std::string, std::string> writer = {{"returns.pcd", "the pipeline"}, {"cloud.pcd", "the pipeline"},
                                               {"report.json", "the pipeline"}};
  for (std::size_t s = 0; s < cfg.stages.size(); ++s)
    for (const auto& f : p.stages_[s]->products()) {
      const std::string me = "stage '" + cfg.stages[s].name + "' (" + cfg.stages[s].type + ")";
      const auto [it, fresh] = writer.emplace(f, me);
      if (!fresh)
        throw ConfigError(cfg.stages[s].where + ": " + me + " writes " + f + ", which " + it->second +
                          " writes too: a run writes each output once (keep one of the stages)");
    }
  return p;
}

namespace {
std::string percent(std::uint64_t part, std::uint64_t whole) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f %%", whole ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0);
  return b;
}
std::string seconds_text(double t) {
  char b[32];
  std::snprintf(b, sizeof b, "%.15g", t);
  return b;
}

/// The run-level checks of what the passes kept (docs/robustness.md, "silent success"): a run
/// that keeps nothing, or leaves more than half of its in-range returns without a pose, is an
/// InputError (exit 3) naming the cause and the fix, unless `allow_empty_output`; then, and
/// for shares above kWarnShare, warnings. Called before any product is written or committed.
void check_what_was_kept(const PipelineConfig& cfg, const PoseTrack* poses, const RunSummary& sum, double stamp_min,
                         double stamp_max, std::vector<std::string>& warnings) {
  constexpr double kWarnShare = 0.05;
  const auto n = sum.input_returns;
  const auto no_return = sum.labels[static_cast<std::size_t>(Label::kNoReturn)];
  const auto oor = sum.labels[static_cast<std::size_t>(Label::kOutOfRange)];
  const auto no_pose = sum.labels[static_cast<std::size_t>(Label::kNoPose)];
  const auto kept = sum.labels[static_cast<std::size_t>(Label::kKept)];
  const std::uint64_t returned = n - no_return;  // returns with a range
  const std::uint64_t in_range = returned - oor;  // returns register could place, given a pose
  const std::string allow = "; set allow_empty_output: true to write such a run anyway";
  std::vector<std::string> errors;

  if (no_pose > 0 && in_range > 0) {
    std::string why = std::to_string(no_pose) + " of " + std::to_string(in_range) + " in-range returns (" +
                      percent(no_pose, in_range) + ") have no pose";
    if (poses && poses->size() > 0) {
      why += ": the pose file " + cfg.poses + " spans " + seconds_text(poses->begin_stamp()) + " to " +
             seconds_text(poses->end_stamp()) + " s, the scans' stamps run " + seconds_text(stamp_min) + " to " +
             seconds_text(stamp_max) + " s";
      if (stamp_max < poses->begin_stamp() || stamp_min > poses->end_stamp())
        why += "; no return falls within the pose file's span: a time-base mismatch (seconds vs. nanoseconds, "
               "GPS vs. Unix time)? Give poses and scans one clock";
      else
        why += "; the poses cover part of the run, or have gaps longer than the register stage's max_pose_gap";
    }
    if (no_pose * 2 > in_range) errors.push_back(why);
    else if (static_cast<double>(no_pose) > kWarnShare * static_cast<double>(in_range)) warnings.push_back("run: " + why);
  }
  if (kept == 0 && errors.empty()) {
    std::string why;
    if (n == 0) {
      why = "the " + std::to_string(sum.passes.size()) + " pass file(s) hold no return";
    } else if (in_range == 0) {
      why = "no return of " + std::to_string(n) + " is in range: " + std::to_string(no_return) + " have no return and " +
            std::to_string(oor) + " fall outside sensor.range_min to range_max (" + format_value(cfg.sensor.range_min) +
            " to " + format_value(cfg.sensor.range_max) + " m after the range calibration k = " +
            format_value(cfg.sensor.range_k) + ", b = " + format_value(cfg.sensor.range_b) +
            " m): check those keys and the unit of the ranges (metres)";
    } else {
      why = "no return of " + std::to_string(n) + " is kept; labels:";
      for (std::size_t l = 1; l < kLabelCount; ++l)
        if (sum.labels[l]) why += " " + std::string(label_name(static_cast<Label>(l))) + "=" + std::to_string(sum.labels[l]);
      why += ": check the options of the stages that rejected them";
    }
    errors.push_back("the run keeps nothing: " + why);
  } else if (returned > 0 && static_cast<double>(oor) > kWarnShare * static_cast<double>(returned)) {
    warnings.push_back("run: " + std::to_string(oor) + " of " + std::to_string(returned) + " returns (" +
                       percent(oor, returned) + ") fall outside sensor.range_min to range_max (" +
                       format_value(cfg.sensor.range_min) + " to " + format_value(cfg.sensor.range_max) + " m)");
  }
  for (const auto& e : errors) {
    if (!cfg.allow_empty_output) throw InputError(cfg.source + ": " + e + allow);
    warnings.push_back("run: " + e);
  }
}

/// One pass after the part of the chain a worker thread may run (see Stage::concurrent/split).
struct Processed {
  Pass pass;
  std::vector<StageReport> reports;  ///< this pass's share of each stage's report
  std::vector<std::unique_ptr<StageWork>> works;
  std::size_t stop = 0;  ///< the first stage the worker did not run
};

void merge_report(StageReport& into, const StageReport& r) {
  into.in += r.in;
  into.out += r.out;
  for (std::size_t l = 0; l < kLabelCount; ++l) into.rejected[l] += r.rejected[l];
  into.seconds += r.seconds;
  for (const auto& [k, v] : r.metrics) into.metrics[k] += v;
  into.warnings.insert(into.warnings.end(), r.warnings.begin(), r.warnings.end());
}

/// An OutputSink that may be called from several threads.
class LockedSink final : public OutputSink {
 public:
  explicit LockedSink(OutputSink& s) : s_(s) {}
  std::string staged_path(const std::string& filename) override {
    std::lock_guard<std::mutex> lock(m_);
    return s_.staged_path(filename);
  }

 private:
  OutputSink& s_;
  std::mutex m_;
};

/// process() with the accounting of what it changed.
void run_stage(Stage& stage, Pass& pass, StageReport& rep) {
  const LabelHistogram before = histogram(pass);
  const auto t0 = std::chrono::steady_clock::now();
  stage.process(pass, rep);
  rep.seconds += seconds_since(t0);
  const LabelHistogram after = histogram(pass);
  rep.in += before[0];
  rep.out += after[0];
  for (std::size_t l = 1; l < kLabelCount; ++l)
    if (after[l] > before[l]) rep.rejected[l] += after[l] - before[l];
}
}  // namespace

RunSummary Pipeline::run(const ProgressFn& progress, unsigned threads) {
  const auto t_run = std::chrono::steady_clock::now();
  const PipelineConfig& cfg = *config_;
  RunSummary sum;
  sum.started_at = utc_now_iso8601();
  sum.output_dir = cfg.output_dir;
  sum.threads = std::max(1u, threads);
  sum.map_origin = context_.map_origin;
  for (const auto& sc : cfg.stages) {
    StageReport r;
    r.name = sc.name;
    r.type = sc.type;
    sum.stages.push_back(r);
  }

  // What can be checked cheaply is checked before the heavy work (a prepass reads every pass):
  // each pass file is a regular readable file whose header parses with the required fields.
  for (const auto& f : cfg.scans) check_pass_header(f);
  io::StagedOutputs out(cfg.output_dir);
  {
    std::vector<std::string> products = {"returns.pcd", "cloud.pcd", "report.json"};
    for (const auto& st : stages_)
      for (const auto& f : st->products()) products.push_back(f);
    out.check_replaceable(products);  // before the work, not at the end
  }
  // Every file a pipeline run may write: an earlier run's product that this run does not write
  // (map.ot after write_ot: false, say) does not stay beside the new set.
  out.owns({"returns.pcd", "cloud.pcd", "report.json", "elevation.tif", "elevation.state.tif", "elevation.png", "map.bt",
            "map.ot"});
  io::ReturnsWriter returns(out.staged_path("returns.pcd"), context_.map_origin);
  io::CloudWriter cloud(out.staged_path("cloud.pcd"), context_.map_origin);
  const std::string report_tmp = out.staged_path("report.json");

  const std::size_t np = cfg.scans.size();
  const std::size_t window = sum.threads + 1;  // passes in memory at once: bounded, whatever np
  // Prepass: stages that need every pass's evidence first (passes are streamed, never all held).
  // Only the stages that change the pass run before it; split (fusion) stages do not.
  //
  // The first passes the last prepass stage reads are kept, as the stages before it left them
  // (with their reports), when those stages are all concurrent: the main loop then takes them as
  // they are instead of reading and processing them a second time. At most `window` of them, so
  // memory stays bounded by a few passes (a worker's pass in flight plus the kept ones).
  std::size_t last_pre = stages_.size();
  for (std::size_t s = 0; s < stages_.size(); ++s)
    if (stages_[s]->wants_prepass()) last_pre = s;
  bool keep_passes = last_pre < stages_.size() && stages_[last_pre]->prepass_split();
  for (std::size_t e = 0; keep_passes && e < last_pre; ++e) keep_passes = stages_[e]->concurrent();
  struct Kept {
    Pass pass;
    std::vector<StageReport> reports;  // of the stages before last_pre
  };
  std::vector<std::optional<Kept>> kept(keep_passes ? std::min(np, window) : 0);
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    if (!stages_[s]->wants_prepass()) continue;
    const PhaseTimer phase(sum, "prepass " + cfg.stages[s].name);
    std::size_t par = 0;  // the prefix a worker may run
    while (par < s && (stages_[par]->concurrent() || stages_[par]->split())) ++par;
    // The worker also computes the stage's evidence when it ran the whole prefix.
    const bool early = par == s && stages_[s]->prepass_split();
    struct Pre {
      Pass pass;
      std::unique_ptr<StageWork> work;
      double seconds;
    };
    // When only the evidence travels, more may wait for the in-order part: the stage keeps every
    // pass's evidence anyway, and a worker then need not wait for the calling thread to wake.
    detail::ordered_parallel<Pre>(
        np, sum.threads, early ? 4 * window : window,
        [&](std::size_t k) {
          Pre r{read_pass(cfg.scans[k], k), nullptr, 0.0};
          const bool keep = s == last_pre && k < kept.size();
          StageReport scratch;
          std::vector<StageReport> reports(keep ? s : 0);
          for (std::size_t e = 0; e < par; ++e) {
            if (!stages_[e]->concurrent()) continue;
            if (keep)
              run_stage(*stages_[e], r.pass, reports[e]);  // its share of the run's report, as in the main loop
            else
              stages_[e]->process(r.pass, scratch);
          }
          if (early) {
            const auto t0 = std::chrono::steady_clock::now();
            r.work = stages_[s]->prepass_compute(r.pass);
            r.seconds = seconds_since(t0);
            if (keep) kept[k] = Kept{std::move(r.pass), std::move(reports)};  // slot k: this worker's alone
            r.pass = Pass{};  // only the evidence travels on
          }
          return r;
        },
        [&](std::size_t k, Pre&& r) {
          if (progress) progress({k, np, cfg.scans[k], "prepass " + cfg.stages[s].name});
          StageReport& rep = sum.stages[s];
          const auto t0 = std::chrono::steady_clock::now();
          if (early) {
            stages_[s]->prepass_apply(std::move(r.work));
          } else {
            StageReport scratch;
            for (std::size_t e = par; e < s; ++e)
              if (!stages_[e]->split()) stages_[e]->process(r.pass, scratch);
            stages_[s]->prepass(r.pass);
          }
          // The stage's own prepass work counts in its time (the stages before it, run again for
          // the prepass, are not counted anywhere: they are the price of streaming passes).
          const double dt = r.seconds + seconds_since(t0);
          rep.seconds += dt;
          rep.metrics["prepass_seconds"] += dt;
        });
    const auto t0 = std::chrono::steady_clock::now();
    stages_[s]->prepass_finish(sum.threads);
    const double dt = seconds_since(t0);
    sum.stages[s].seconds += dt;
    sum.stages[s].metrics["prepass_seconds"] += dt;
  }
  std::int64_t last_line = -1;
  std::string last_file;
  double stamp_min = std::numeric_limits<double>::infinity(), stamp_max = -stamp_min;
  std::optional<PhaseTimer> phase;
  phase.emplace(sum, "passes");
  detail::ordered_parallel<Processed>(
      np, sum.threads, window,
      [&](std::size_t k, WorkShare& share) {
        Processed r;
        r.reports.resize(stages_.size());
        r.works.resize(stages_.size());
        std::size_t first = 0;  // the first stage to run here
        if (k < kept.size() && kept[k]) {
          r.pass = std::move(kept[k]->pass);
          for (std::size_t e = 0; e < last_pre; ++e) r.reports[e] = std::move(kept[k]->reports[e]);
          kept[k].reset();
          first = last_pre;
        } else {
          r.pass = read_pass(cfg.scans[k], k);
        }
        for (r.stop = first; r.stop < stages_.size(); ++r.stop) {
          Stage& st = *stages_[r.stop];
          StageReport& rep = r.reports[r.stop];
          if (st.concurrent()) {
            run_stage(st, r.pass, rep);
          } else if (st.split()) {
            const auto t0 = std::chrono::steady_clock::now();
            r.works[r.stop] = st.compute(r.pass, rep, share);
            rep.seconds += seconds_since(t0);
            rep.in += r.pass.kept();
            rep.out += r.pass.kept();
          } else {
            break;
          }
        }
        return r;
      },
      [&](std::size_t k, Processed&& r) {
        const auto emit = [&](const std::string& step) {
          if (progress) progress({k, np, cfg.scans[k], step});
        };
        Pass& pass = r.pass;
        if (pass.size() > 0) {
          if (static_cast<std::int64_t>(pass.line.front()) <= last_line)
            throw InputError(pass.source + ": field 'line': its first line " + std::to_string(pass.line.front()) +
                             " is not after the last line " + std::to_string(last_line) + " of " + last_file +
                             " (line indices are unique within a run and increase with time)");
          last_line = pass.line.back();
          last_file = pass.source;
          stamp_min = std::min(stamp_min, pass.stamp.front());  // stamps increase along a pass
          stamp_max = std::max(stamp_max, pass.stamp.back());
        }
        for (std::size_t s = 0; s < stages_.size(); ++s) {
          emit(cfg.stages[s].name);
          StageReport& rep = sum.stages[s];
          if (s < r.stop) {
            if (stages_[s]->split()) {
              const auto t0 = std::chrono::steady_clock::now();
              stages_[s]->apply(std::move(r.works[s]), rep);
              const double dt = seconds_since(t0);
              rep.seconds += dt;
              rep.metrics["in_order_seconds"] += dt;  // the part threads cannot share
            }
            merge_report(rep, r.reports[s]);
          } else {
            run_stage(*stages_[s], pass, rep);
          }
        }
        emit("write");
        returns.append(pass);
        cloud.append(pass);
        const LabelHistogram h = histogram(pass);
        for (std::size_t l = 0; l < kLabelCount; ++l) sum.labels[l] += h[l];
        sum.input_returns += pass.size();
        sum.passes.push_back({pass.source, pass.size(), pass.line_count(), h[0]});
      });
  // finish() touches only its own stage (and the sink, guarded here), so with threads the stages
  // write their products at the same time, and the parts of a stage that writes several (see
  // Stage::finish_parts); errors are reported in stage order. Closing returns.pcd and cloud.pcd
  // (each copies its body behind the header) are two more parts, last: on 2 threads they run
  // beside elevation.tif, the longest part, instead of after it. A part may hand tasks to the
  // WorkShare (elevation.tif compresses one group of bands per task): a thread with no part left helps.
  // Every label is final now: a run that kept nothing stops here, before any product is written.
  std::vector<std::string> run_warnings;
  check_what_was_kept(cfg, context_.poses.get(), sum, stamp_min, stamp_max, run_warnings);
  phase.emplace(sum, "finish");  // (the passes' timer records as it is replaced)
  LockedSink sink(out);
  std::vector<std::pair<std::size_t, std::size_t>> parts;  // (stage, part); stage == size: a writer
  for (std::size_t s = 0; s < stages_.size(); ++s)
    for (std::size_t p = 0; p < stages_[s]->finish_parts(); ++p) parts.emplace_back(s, p);
  parts.emplace_back(stages_.size(), 0);
  parts.emplace_back(stages_.size(), 1);
  detail::ordered_parallel<StageReport>(
      parts.size(), sum.threads, parts.size(),
      [&](std::size_t t, WorkShare& share) {
        StageReport rep;
        const auto [s, p] = parts[t];
        if (s == stages_.size()) {
          if (p == 0) returns.close();
          else cloud.close();
          return rep;
        }
        const auto t0 = std::chrono::steady_clock::now();
        stages_[s]->finish_part(p, sink, rep, share);
        const double dt = seconds_since(t0);
        rep.seconds += dt;
        if (dt > 1e-4) rep.metrics["finish_seconds"] += dt;  // products written at the end
        return rep;
      },
      [&](std::size_t t, StageReport&& rep) {
        if (parts[t].first < stages_.size()) merge_report(sum.stages[parts[t].first], rep);
      });
  phase.reset();
  if (returns.points() != sum.input_returns)
    throw std::logic_error("returns.pcd holds " + std::to_string(returns.points()) + " returns, input had " +
                           std::to_string(sum.input_returns));
  sum.warnings = run_warnings;
  for (const auto& r : sum.stages)
    for (const auto& w : r.warnings) sum.warnings.push_back(r.name + ": " + w);
  // The poses (relative to the map origin) so far from it that the float32 products lose 1 mm.
  if (const double far = context_.poses ? farthest_pose_offset(*context_.poses, Eigen::Vector3d::Zero()) : 0.0;
      far > kFloat32MillimetreReach - 1000.0)
    sum.warnings.push_back(cfg.poses + ": poses reach " + format_value(std::round(far)) +
                           " m from the map origin; returns.pcd, cloud.pcd and map.bt (float32) keep 1 mm only within " +
                           format_value(kFloat32MillimetreReach) + " m of it: split the run");
  sum.outputs = out.final_paths();
  {
    // report.json lists every input and every other product with its size and SHA-256: the
    // products as staged (complete, committed as they are), hashed on the run's threads.
    const PhaseTimer digest(sum, "digest");
    for (const auto& f : cfg.scans) sum.input_files.push_back({f, "scan", 0, ""});
    if (!cfg.poses.empty()) sum.input_files.push_back({cfg.poses, "poses", 0, ""});
    std::vector<std::string> names = out.names();
    std::sort(names.begin(), names.end());
    for (const auto& n : names)
      if (n != "report.json") sum.output_files.push_back({n, "", 0, ""});
    const std::size_t ni = sum.input_files.size();
    detail::parallel_for(ni + sum.output_files.size(), sum.threads, [&](std::size_t k) {
      const bool input = k < ni;
      RunSummary::FileRecord& r = input ? sum.input_files[k] : sum.output_files[k - ni];
      io::FileDigest d;
      const std::string path = input ? r.file : (std::filesystem::path(out.staging_dir()) / r.file).string();
      if (const int err = io::digest_file(path, d)) {
        if (!input && err == ENOENT) {  // a name staged and never written is no product
          r.sha256.clear();
          return;
        }
        if (input)
          throw InputError(r.file + ": cannot read it again to hash it for report.json (" + std::strerror(err) +
                           "): was it changed or removed during the run?");
        throw OutputError(out.final_path(r.file) + ": cannot read the staged product to hash it for report.json (" +
                          std::strerror(err) + ")");
      }
      r.bytes = d.bytes;
      r.sha256 = std::move(d.sha256);
    });
    sum.output_files.erase(std::remove_if(sum.output_files.begin(), sum.output_files.end(),
                                          [](const RunSummary::FileRecord& r) { return r.sha256.empty(); }),
                           sum.output_files.end());
  }
  sum.seconds = seconds_since(t_run);
  {
    const std::string js = report_json(cfg, sum);
    std::FILE* f = std::fopen(report_tmp.c_str(), "wb");
    int err = f ? 0 : errno;
    if (f && std::fwrite(js.data(), 1, js.size(), f) != js.size()) err = errno ? errno : EIO;
    if (f && std::fclose(f) != 0 && !err) err = errno;  // closed on every path
    if (err) throw OutputError(out.final_path("report.json") + ": cannot write the report (" + std::strerror(err) + ")");
  }
  out.commit();
  return sum;
}

}  // namespace pcdp
