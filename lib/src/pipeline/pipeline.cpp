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

#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/file_digest.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pipeline/ordered_parallel.hpp"
#include "pipeline/scheduler.hpp"

namespace pcdp {

namespace {
using detail::seconds_since;

std::string utc_now_iso8601() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

}  // namespace

void check_stage_order(const PipelineConfig& cfg, const std::vector<StageInfo>& stages) {
  if (cfg.stages.empty()) throw ConfigError(cfg.source + ": the pipeline is empty: 'stages' lists no stage");
  std::map<std::string, std::size_t> provided;  // what the stages so far provide, by the first that does
  for (std::size_t s = 0; s < cfg.stages.size(); ++s) {
    const StageConfig& sc = cfg.stages[s];
    const StageInfo* info = find_stage(sc.type, stages);
    const std::string me = "stage '" + sc.name + "' (" + sc.type + ")";
    if (!info) throw ConfigError(sc.where + ": " + me + ": unknown stage type '" + sc.type + "'");
    for (const auto& need : info->needs)
      if (!provided.count(need)) {
        std::string by;  // the stage types that would provide it
        for (const auto& i : stages)
          if (std::find(i.provides.begin(), i.provides.end(), need) != i.provides.end())
            by += (by.empty() ? "'" : ", '") + i.type + "'";
        throw ConfigError(sc.where + ": " + me + " needs " + need + ", which no stage before it provides" +
                          (by.empty() ? std::string() : " (put " + by + " before it)"));
      }
    for (const auto& give : info->provides) {
      const auto [it, fresh] = provided.emplace(give, s);
      if (!fresh) {
        const StageConfig& o = cfg.stages[it->second];
        throw ConfigError(sc.where + ": " + me + " provides " + give + ", which stage '" + o.name + "' (" + o.type +
                          ") provides already: '" + sc.type + "' may appear only once, before the stages that need " +
                          give);
      }
    }
  }
}

Pipeline Pipeline::prepare(PipelineConfig config, const std::vector<StageInfo>& stages) {
  Pipeline p;
  p.config_ = std::make_shared<PipelineConfig>(std::move(config));
  const PipelineConfig& cfg = *p.config_;
  check_stage_order(cfg, stages);
  p.context_.config = p.config_.get();
  if (!cfg.poses.empty()) {
    // Georeferenced poses: the run works relative to a local map origin (pcdp/core/georef.hpp).
    PoseTrack poses = io::read_pose_csv(cfg.poses, cfg.rpy_order);
    p.context_.map_origin = choose_map_origin(poses);
    if (!p.context_.map_origin.isZero()) poses = shift_poses(poses, p.context_.map_origin);
    p.context_.poses = std::make_shared<const PoseTrack>(std::move(poses));
  }
  for (const auto& sc : cfg.stages) p.stages_.push_back(find_stage(sc.type, stages)->create(sc, p.context_));
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

}  // namespace

/// The run-level checks of what the passes kept (docs/robustness.md, "silent success"): a run
/// that keeps nothing, or leaves more than half of its in-range returns without a pose, is an
/// InputError (exit 3) naming the cause and the fix, unless `allow_empty_output`; then, and
/// for shares above kWarnShare, warnings. Called before any product is written or committed.
void detail::check_what_was_kept(const PipelineConfig& cfg, const PoseTrack* poses, const RunSummary& sum,
                                 double stamp_min, double stamp_max, std::vector<std::string>& warnings) {
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

void detail::collect_warnings(const PipelineConfig& cfg, const PoseTrack* poses,
                              const std::vector<std::string>& run_warnings, RunSummary& sum) {
  sum.warnings = run_warnings;
  for (const auto& r : sum.stages)
    for (const auto& w : r.warnings) sum.warnings.push_back(r.name + ": " + w);
  // The poses (relative to the map origin) so far from it that the float32 products lose 1 mm.
  if (const double far = poses ? farthest_pose_offset(*poses, Eigen::Vector3d::Zero()) : 0.0;
      far > kFloat32MillimetreReach - 1000.0)
    sum.warnings.push_back(cfg.poses + ": poses reach " + format_value(std::round(far)) +
                           " m from the map origin; returns.pcd, cloud.pcd and map.bt (float32) keep 1 mm only within " +
                           format_value(kFloat32MillimetreReach) + " m of it: split the run");
}

/// report.json lists every input and every other product with its size and SHA-256: the
/// products as staged (complete, committed as they are), hashed on the run's threads.
const std::vector<std::string>& detail::run_products() {
  static const std::vector<std::string> names = {"returns.pcd",  "cloud.pcd", "report.json", "elevation.tif",
                                                 "elevation.state.tif", "elevation.png", "map.bt", "map.ot",
                                                 "evaluation.json"};
  return names;
}

std::vector<std::string> detail::run_inputs(const PipelineConfig& cfg) {
  std::vector<std::string> in = cfg.scans;
  if (!cfg.poses.empty()) in.push_back(cfg.poses);
  return in;
}

void detail::digest_files(const PipelineConfig& cfg, io::StagedOutputs& out, RunSummary& sum) {
  const detail::PhaseTimer digest(sum, "digest");
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

  // What can be checked cheaply is checked before the heavy work (an evidence phase reads every pass):
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
  out.protect_inputs(detail::run_inputs(cfg));  // a scan or pose file named like a product would be replaced
  out.owns(detail::run_products());
  io::ReturnsWriter returns(out.staged_path("returns.pcd"), context_.map_origin);
  io::CloudWriter cloud(out.staged_path("cloud.pcd"), context_.map_origin);
  const std::string report_tmp = out.staged_path("report.json");

  detail::Scheduler schedule(stages_, cfg, sum, progress);
  schedule.evidence();
  std::int64_t last_line = -1;
  std::string last_file;
  double stamp_min = std::numeric_limits<double>::infinity(), stamp_max = -stamp_min;
  schedule.passes(
      [&](const Pass& pass) {
        if (pass.size() == 0) return;
        if (static_cast<std::int64_t>(pass.line.front()) <= last_line)
          throw InputError(pass.source + ": field 'line': its first line " + std::to_string(pass.line.front()) +
                           " is not after the last line " + std::to_string(last_line) + " of " + last_file +
                           " (line indices are unique within a run and increase with time)");
        last_line = pass.line.back();
        last_file = pass.source;
        stamp_min = std::min(stamp_min, pass.stamp.front());  // stamps increase along a pass
        stamp_max = std::max(stamp_max, pass.stamp.back());
      },
      [&](Pass& pass) {
        returns.append(pass);
        cloud.append(pass);
        const LabelHistogram h = detail::histogram(pass);
        for (std::size_t l = 0; l < kLabelCount; ++l) sum.labels[l] += h[l];
        sum.input_returns += pass.size();
        sum.passes.push_back({pass.source, pass.size(), pass.line_count(), h[0]});
      });
  // Every label is final now: a run that kept nothing stops here, before any product is written.
  std::vector<std::string> run_warnings;
  detail::check_what_was_kept(cfg, context_.poses.get(), sum, stamp_min, stamp_max, run_warnings);
  {
    const detail::PhaseTimer phase(sum, "finish");
    schedule.products(out, {[&] { returns.close(); }, [&] { cloud.close(); }});
  }
  if (returns.points() != sum.input_returns)
    throw std::logic_error("returns.pcd holds " + std::to_string(returns.points()) + " returns, input had " +
                           std::to_string(sum.input_returns));
  detail::collect_warnings(cfg, context_.poses.get(), run_warnings, sum);
  sum.outputs = out.final_paths();
  detail::digest_files(cfg, out, sum);
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
