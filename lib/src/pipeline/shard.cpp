#include "pcdp/pipeline/shard.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/file_digest.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/pipeline/partial_io.hpp"
#include "pcdp/pipeline/work_share.hpp"
#include "pipeline/scheduler.hpp"

namespace pcdp {

namespace fs = std::filesystem;
namespace pio = partial_io;

namespace {

constexpr const char* kMagic = "pcdp.shard.1";

std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') o += '\\', o += c;
    else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      o += b;
    } else o += c;
  }
  return o + "\"";
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot read it (" + std::strerror(errno) + ")");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// FNV-1a 64 over the pieces, each followed by a NUL.
std::string fnv_hash(const std::vector<std::string>& pieces) {
  std::uint64_t h = 1469598103934665603ull;
  for (const auto& p : pieces) {
    for (const char c : p) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    h = (h ^ 0u) * 1099511628211ull;
  }
  char b[20];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(h));
  return b;
}

LoadOptions options_of(const ShardPlan& p) {
  LoadOptions o;
  for (const auto& s : p.sets) o.overrides.push_back(parse_override(s));
  o.output_dir = p.output_dir;
  return o;
}

/// The configured stages, as Pipeline::prepare builds them.
struct Prepared {
  PipelineConfig cfg;
  RunContext context;
  std::vector<std::unique_ptr<Stage>> stages;
  std::size_t two_phase = std::numeric_limits<std::size_t>::max();  ///< the two-phase stage, if any
};

std::unique_ptr<Prepared> prepare(const ShardPlan& plan) {
  // --set paths are relative to the working directory of `shard`.
  const fs::path here = fs::current_path();
  if (!plan.cwd.empty()) fs::current_path(plan.cwd);
  auto p = std::make_unique<Prepared>();
  try {
    p->cfg = load_pipeline(plan.pipeline, options_of(plan));
  } catch (...) {
    fs::current_path(here);
    throw;
  }
  fs::current_path(here);
  check_stage_order(p->cfg);
  p->context.config = &p->cfg;
  if (!p->cfg.poses.empty()) {
    PoseTrack poses = io::read_pose_csv(p->cfg.poses, p->cfg.rpy_order);
    p->context.map_origin = choose_map_origin(poses);
    if (!p->context.map_origin.isZero()) poses = shift_poses(poses, p->context.map_origin);
    p->context.poses = std::make_shared<const PoseTrack>(std::move(poses));
  }
  for (const auto& sc : p->cfg.stages) p->stages.push_back(find_stage(sc.type)->create(sc, p->context));
  for (std::size_t s = 0; s < p->stages.size(); ++s)
    if (p->stages[s]->kind() == StageKind::kTwoPhase) {
      if (p->two_phase != std::numeric_limits<std::size_t>::max())
        throw ConfigError(p->cfg.source + ": shard: stages '" + p->cfg.stages[p->two_phase].name + "' and '" +
                          p->cfg.stages[s].name + "' both gather evidence first; a sharded run takes one such stage");
      p->two_phase = s;
    }
  return p;
}

std::string hash_of(const ShardPlan& plan, const PipelineConfig& cfg) {
  std::vector<std::string> pieces = {read_text(plan.pipeline), plan.output_dir, cfg.output_dir};
  for (const auto& s : plan.sets) pieces.push_back("set " + s);
  for (const auto& s : cfg.scans) pieces.push_back("scan " + s);
  pieces.push_back("poses " + cfg.poses);
  return fnv_hash(pieces);
}

void put_report(std::ostream& o, const StageReport& r) {
  pio::put<std::uint64_t>(o, r.in);
  pio::put<std::uint64_t>(o, r.out);
  pio::put(o, r.rejected);
  pio::put(o, r.seconds);
  pio::put<std::uint64_t>(o, r.metrics.size());
  for (const auto& [k, v] : r.metrics) {
    pio::put_str(o, k);
    pio::put(o, v);
  }
  pio::put<std::uint64_t>(o, r.warnings.size());
  for (const auto& w : r.warnings) pio::put_str(o, w);
}
void get_report(std::istream& i, StageReport& r) {
  r.in = pio::get<std::uint64_t>(i);
  r.out = pio::get<std::uint64_t>(i);
  pio::get(i, r.rejected);
  pio::get(i, r.seconds);
  const auto nm = pio::get<std::uint64_t>(i);
  if (nm > 4096) throw InputError("the partial is corrupt (metrics)");
  for (std::uint64_t k = 0; k < nm; ++k) {
    std::string key = pio::get_str(i);
    r.metrics[key] = pio::get<double>(i);
  }
  const auto nw = pio::get<std::uint64_t>(i);
  if (nw > 1u << 20) throw InputError("the partial is corrupt (warnings)");
  for (std::uint64_t k = 0; k < nw; ++k) r.warnings.push_back(pio::get_str(i));
}

std::string task_name(std::size_t t) {
  char b[32];
  std::snprintf(b, sizeof b, "task-%04zu", t);
  return b;
}
std::string part_path(const std::string& w, const std::string& phase, std::size_t t) {
  return (fs::path(w) / phase / (task_name(t) + ".part")).string();
}

/// An empty partial of stage `s`'s type: collect() of a pass with no returns (the merge identity).
std::unique_ptr<Partial> empty_partial(const Stage& stage) {
  Pass none;
  none.index = 1;
  none.source = "(empty)";
  StageReport scratch;
  auto p = stage.collect(none, scratch, WorkShare::serial());
  if (!p) throw std::logic_error("shard: a stage's collect() gave no partial");
  return p;
}

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

void put_header(std::ostream& o, const ShardPlan& plan, const std::string& phase, std::size_t t) {
  pio::put_str(o, kMagic);
  pio::put_str(o, plan.hash);
  pio::put_str(o, phase);
  pio::put<std::uint64_t>(o, t);
  pio::put<std::uint64_t>(o, plan.ranges[t].first);
  pio::put<std::uint64_t>(o, plan.ranges[t].second);
}
/// Empty when the header is what task `t` of `phase` in `plan` writes; else why not.
std::string check_header(std::istream& i, const ShardPlan& plan, const std::string& phase, std::size_t t) {
  pio::expect(i, kMagic);
  const std::string hash = pio::get_str(i), ph = pio::get_str(i);
  const auto task = pio::get<std::uint64_t>(i), a = pio::get<std::uint64_t>(i), b = pio::get<std::uint64_t>(i);
  if (hash != plan.hash) return "it belongs to another pipeline (hash " + hash + ", the plan's " + plan.hash + ")";
  if (ph != phase) return "it is of phase " + ph;
  if (task != t) return "it holds task " + std::to_string(task) + " (a duplicate)";
  if (a != plan.ranges[t].first || b != plan.ranges[t].second)
    return "it holds passes " + std::to_string(a) + " to " + std::to_string(b) + ", the plan gives " +
           std::to_string(plan.ranges[t].first) + " to " + std::to_string(plan.ranges[t].second);
  return {};
}

/// Opens every partial of `phase`, checked; InputError naming the tasks to rerun.
std::vector<std::unique_ptr<std::ifstream>> open_all(const std::string& w, const ShardPlan& plan, const std::string& phase) {
  std::vector<std::unique_ptr<std::ifstream>> in;
  std::string why;
  std::vector<std::size_t> bad;
  for (std::size_t t = 0; t < plan.shards; ++t) {
    const std::string path = part_path(w, phase, t);
    auto f = std::make_unique<std::ifstream>(path, std::ios::binary);
    std::string e;
    if (!*f) e = "missing";
    else {
      try {
        e = check_header(*f, plan, phase, t);
      } catch (const InputError& x) {
        e = x.what();
      }
    }
    if (!e.empty()) {
      bad.push_back(t);
      why += "\n  " + path + ": " + e;
    }
    in.push_back(std::move(f));
  }
  if (!bad.empty()) {
    std::string rerun;
    for (const auto t : bad) rerun += "\n  pcd_pipeline shard-task " + w + " " + phase + " " + std::to_string(t);
    throw InputError(w + ": " + std::to_string(bad.size()) + " partial(s) of phase '" + phase +
                     "' missing, duplicated or foreign:" + why + "\nrerun these tasks:" + rerun);
  }
  return in;
}

template <class F>
void named(const std::string& path, F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

void label_counted(const Stage& st, Pass& pass, StageReport& rep) {
  const LabelHistogram before = detail::histogram(pass);
  const auto t0 = std::chrono::steady_clock::now();
  st.label(pass, rep);
  rep.seconds += detail::seconds_since(t0);
  const LabelHistogram after = detail::histogram(pass);
  rep.in += before[0];
  rep.out += after[0];
  for (std::size_t l = 1; l < kLabelCount; ++l)
    if (after[l] > before[l]) rep.rejected[l] += after[l] - before[l];
}

/// The PCD file's header (up to "DATA binary\n") and where its body starts.
std::pair<std::string, std::size_t> pcd_header(const std::string& text, const std::string& path) {
  const std::string end = "DATA binary\n";
  const auto at = text.find(end);
  if (at == std::string::npos) throw InputError(path + ": not a binary PCD written by a shard task");
  return {text.substr(0, at + end.size()), at + end.size()};
}
/// The header with WIDTH and POINTS set to n.
std::string with_points(const std::string& header, std::uint64_t n) {
  std::istringstream in(header);
  std::string line, out;
  while (std::getline(in, line)) {
    if (line.rfind("WIDTH ", 0) == 0) line = "WIDTH " + std::to_string(n);
    else if (line.rfind("POINTS ", 0) == 0) line = "POINTS " + std::to_string(n);
    out += line + "\n";
  }
  return out;
}
std::uint64_t header_points(const std::string& header) {
  const auto at = header.find("\nPOINTS ");
  return at == std::string::npos ? 0 : std::stoull(header.substr(at + 8));
}

/// Concatenates the bodies of the tasks' PCD files behind one header.
void concat_pcd(const std::vector<std::string>& parts, const std::string& to, std::uint64_t& points) {
  std::string header;
  std::vector<std::string> bodies;
  points = 0;
  for (const auto& p : parts) {
    const std::string text = read_text(p);
    if (text.empty()) continue;
    auto [h, at] = pcd_header(text, p);
    const std::uint64_t n = header_points(h);
    if (header.empty()) header = h;
    else if (with_points(h, 0) != with_points(header, 0))
      throw InputError(p + ": its fields differ from those of the tasks before it");
    points += n;
    bodies.push_back(text.substr(at));
  }
  std::ofstream out(to, std::ios::binary | std::ios::trunc);
  const std::string h = with_points(header, points);
  out.write(h.data(), static_cast<std::streamsize>(h.size()));
  for (const auto& b : bodies) out.write(b.data(), static_cast<std::streamsize>(b.size()));
  out.flush();
  if (!out) throw OutputError(to + ": cannot write it (" + std::strerror(errno) + ")");
}

}  // namespace

ShardPlan make_shard_plan(const std::string& pipeline, const std::vector<std::string>& sets, const std::string& output_dir,
                          std::size_t shards) {
  ShardPlan plan;
  plan.pipeline = fs::absolute(pipeline).lexically_normal().string();
  plan.sets = sets;
  plan.output_dir = output_dir.empty() ? "" : fs::absolute(output_dir).lexically_normal().string();
  plan.cwd = fs::current_path().string();
  auto p = prepare(plan);
  plan.passes = p->cfg.scans.size();
  if (shards == 0) throw ConfigError("shard: --shards must be at least 1");
  if (shards > plan.passes)
    throw ConfigError(p->cfg.source + ": shard: --shards " + std::to_string(shards) + " is more than the " +
                      std::to_string(plan.passes) + " pass(es) of the pipeline: each task takes at least one pass");
  plan.shards = shards;
  for (std::size_t t = 0; t < shards; ++t) plan.ranges.emplace_back(t * plan.passes / shards, (t + 1) * plan.passes / shards);
  if (p->two_phase != std::numeric_limits<std::size_t>::max()) plan.phases.push_back("evidence");
  plan.phases.push_back("passes");
  plan.phases.push_back("reduce");
  plan.hash = hash_of(plan, p->cfg);
  return plan;
}

void write_shard_plan(const std::string& w, const ShardPlan& plan) {
  const fs::path bin = fs::path(w) / "plan.bin";
  if (fs::exists(bin)) {
    const ShardPlan old = read_shard_plan(w);
    if (old.hash != plan.hash || old.shards != plan.shards)
      throw ConfigError(w + ": the work dir holds the plan of another run (" + old.pipeline + ", " +
                        std::to_string(old.shards) + " shard(s), hash " + old.hash + "; this one: " + plan.pipeline +
                        ", " + std::to_string(plan.shards) + " shard(s), hash " + plan.hash +
                        "): give another --work-dir or remove that one");
  }
  fs::create_directories(w);
  {
    AtomicOut o(bin.string());
    std::ostream& s = o.stream();
    pio::put_str(s, "pcdp.shard_plan.1");
    pio::put_str(s, plan.pipeline);
    pio::put<std::uint64_t>(s, plan.sets.size());
    for (const auto& x : plan.sets) pio::put_str(s, x);
    pio::put_str(s, plan.output_dir);
    pio::put_str(s, plan.cwd);
    pio::put_str(s, plan.hash);
    pio::put<std::uint64_t>(s, plan.passes);
    pio::put<std::uint64_t>(s, plan.shards);
    pio::put<std::uint64_t>(s, plan.phases.size());
    for (const auto& x : plan.phases) pio::put_str(s, x);
    o.commit();
  }
  AtomicOut o((fs::path(w) / "plan.json").string());
  std::ostream& s = o.stream();
  s << "{\n  \"pipeline\": " << json_string(plan.pipeline) << ",\n  \"set\": [";
  for (std::size_t k = 0; k < plan.sets.size(); ++k) s << (k ? ", " : "") << json_string(plan.sets[k]);
  s << "],\n  \"output_dir\": " << json_string(plan.output_dir) << ",\n  \"cwd\": " << json_string(plan.cwd)
    << ",\n  \"hash\": " << json_string(plan.hash) << ",\n  \"passes\": " << plan.passes << ",\n  \"shards\": " << plan.shards
    << ",\n  \"phases\": [";
  for (std::size_t k = 0; k < plan.phases.size(); ++k) s << (k ? ", " : "") << json_string(plan.phases[k]);
  s << "],\n  \"tasks\": [";
  for (std::size_t t = 0; t < plan.shards; ++t)
    s << (t ? ", " : "") << "{\"task\": " << t << ", \"first_pass\": " << plan.ranges[t].first
      << ", \"end_pass\": " << plan.ranges[t].second << "}";
  s << "]\n}\n";
  o.commit();
}

ShardPlan read_shard_plan(const std::string& w) {
  const std::string path = (fs::path(w) / "plan.bin").string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": no shard plan here (" + std::strerror(errno) + "); run `pcd_pipeline shard` first");
  ShardPlan p;
  named(path, [&] {
    pio::expect(in, "pcdp.shard_plan.1");
    p.pipeline = pio::get_str(in);
    const auto ns = pio::get<std::uint64_t>(in);
    if (ns > 4096) throw InputError("corrupt");
    for (std::uint64_t k = 0; k < ns; ++k) p.sets.push_back(pio::get_str(in));
    p.output_dir = pio::get_str(in);
    p.cwd = pio::get_str(in);
    p.hash = pio::get_str(in);
    p.passes = pio::get<std::uint64_t>(in);
    p.shards = pio::get<std::uint64_t>(in);
    const auto nph = pio::get<std::uint64_t>(in);
    if (nph > 8 || p.shards == 0 || p.shards > p.passes) throw InputError("corrupt");
    for (std::uint64_t k = 0; k < nph; ++k) p.phases.push_back(pio::get_str(in));
  });
  for (std::size_t t = 0; t < p.shards; ++t) p.ranges.emplace_back(t * p.passes / p.shards, (t + 1) * p.passes / p.shards);
  return p;
}

void run_shard_task(const std::string& w, const std::string& phase, std::size_t index) {
  const ShardPlan plan = read_shard_plan(w);
  if (std::find(plan.phases.begin(), plan.phases.end(), phase) == plan.phases.end() || phase == "reduce")
    throw ConfigError("shard-task: phase '" + phase + "' is not a task phase of the plan in " + w);
  if (index >= plan.shards)
    throw ConfigError("shard-task: task " + std::to_string(index) + " is beyond the plan's " + std::to_string(plan.shards) +
                      " task(s)");
  auto p = prepare(plan);
  if (hash_of(plan, p->cfg) != plan.hash)
    throw ConfigError(w + ": the pipeline, its scans or its --set list changed since the plan was made: plan again");
  const auto [first, last] = plan.ranges[index];
  const std::size_t ns = p->stages.size(), ev = p->two_phase;
  AtomicOut out(part_path(w, phase, index));
  std::ostream& o = out.stream();
  put_header(o, plan, phase, index);
  if (phase == "evidence") {
    for (std::size_t k = first; k < last; ++k) {
      Pass pass = read_pass(p->cfg.scans[k], k);
      StageReport scratch, rep;
      for (std::size_t e = 0; e < ev; ++e)
        if (p->stages[e]->kind() != StageKind::kAccumulator) p->stages[e]->label(pass, scratch);
      const auto t0 = std::chrono::steady_clock::now();
      auto part = p->stages[ev]->collect(pass, rep, WorkShare::serial());
      rep.seconds += detail::seconds_since(t0);
      put_report(o, rep);
      part->save(o);
    }
    pio::put_str(o, "end");
    out.commit();
    return;
  }
  // passes: the evidence of every task first, merged in pass order, then this task's passes.
  StageReport ev_rep;
  if (ev < ns) {
    auto in = open_all(w, plan, "evidence");
    std::unique_ptr<Partial> all;
    for (std::size_t t = 0; t < plan.shards; ++t) {
      const std::string path = part_path(w, "evidence", t);
      named(path, [&] {
        for (std::size_t k = plan.ranges[t].first; k < plan.ranges[t].second; ++k) {
          StageReport r;
          get_report(*in[t], r);
          auto part = empty_partial(*p->stages[ev]);
          part->load(*in[t]);
          if (!all) all = std::move(part);
          else p->stages[ev]->merge(*all, std::move(*part));
          r.metrics["prepass_seconds"] += r.seconds;
          detail::merge_report(ev_rep, r);
        }
        pio::expect(*in[t], "end");
      });
    }
    p->stages[ev]->finish(std::move(all), ev_rep, 1);
  }
  put_report(o, ev_rep);
  io::ReturnsWriter returns(part_path(w, phase, index) + ".returns.pcd.tmp", p->context.map_origin);
  io::CloudWriter cloud(part_path(w, phase, index) + ".cloud.pcd.tmp", p->context.map_origin);
  for (std::size_t k = first; k < last; ++k) {
    Pass pass = read_pass(p->cfg.scans[k], k);
    std::vector<StageReport> reps(ns);
    std::vector<std::unique_ptr<Partial>> parts(ns);
    for (std::size_t s = 0; s < ns; ++s) {
      if (p->stages[s]->kind() != StageKind::kAccumulator) {
        label_counted(*p->stages[s], pass, reps[s]);
        continue;
      }
      const auto t0 = std::chrono::steady_clock::now();
      parts[s] = p->stages[s]->collect(pass, reps[s], WorkShare::serial());
      reps[s].seconds += detail::seconds_since(t0);
      reps[s].in += pass.kept();
      reps[s].out += pass.kept();
    }
    returns.append(pass);
    cloud.append(pass);
    const LabelHistogram h = detail::histogram(pass);
    pio::put_str(o, pass.source);
    pio::put<std::uint64_t>(o, pass.size());
    pio::put<std::uint64_t>(o, pass.line_count());
    pio::put(o, h);
    const bool any = pass.size() > 0;
    pio::put<std::uint8_t>(o, any ? 1 : 0);
    pio::put<std::int64_t>(o, any ? static_cast<std::int64_t>(pass.line.front()) : 0);
    pio::put<std::int64_t>(o, any ? static_cast<std::int64_t>(pass.line.back()) : 0);
    pio::put<double>(o, any ? pass.stamp.front() : 0.0);
    pio::put<double>(o, any ? pass.stamp.back() : 0.0);
    for (std::size_t s = 0; s < ns; ++s) {
      put_report(o, reps[s]);
      pio::put<std::uint8_t>(o, parts[s] ? 1 : 0);
      if (parts[s]) parts[s]->save(o);
    }
  }
  returns.close();
  cloud.close();
  pio::put_str(o, "end");
  // The records first, the partial last: a partial on disk means its records are complete.
  fs::rename(part_path(w, phase, index) + ".returns.pcd.tmp", part_path(w, phase, index) + ".returns.pcd");
  fs::rename(part_path(w, phase, index) + ".cloud.pcd.tmp", part_path(w, phase, index) + ".cloud.pcd");
  out.commit();
}

RunSummary run_shard_reduce(const std::string& w) {
  const auto t_run = std::chrono::steady_clock::now();
  const ShardPlan plan = read_shard_plan(w);
  auto p = prepare(plan);
  if (hash_of(plan, p->cfg) != plan.hash)
    throw ConfigError(w + ": the pipeline, its scans or its --set list changed since the plan was made: plan again");
  const PipelineConfig& cfg = p->cfg;
  const std::size_t ns = p->stages.size();
  auto in = open_all(w, plan, "passes");
  RunSummary sum;
  sum.output_dir = cfg.output_dir;
  sum.threads = 1;
  sum.map_origin = p->context.map_origin;
  for (const auto& sc : cfg.stages) {
    StageReport r;
    r.name = sc.name;
    r.type = sc.type;
    sum.stages.push_back(r);
  }
  io::StagedOutputs out(cfg.output_dir);
  {
    std::vector<std::string> products = {"returns.pcd", "cloud.pcd", "report.json"};
    for (const auto& st : p->stages)
      for (const auto& f : st->products()) products.push_back(f);
    out.check_replaceable(products);
  }
  out.owns({"returns.pcd", "cloud.pcd", "report.json", "elevation.tif", "elevation.state.tif", "elevation.png", "map.bt",
            "map.ot"});
  std::vector<std::unique_ptr<Partial>> running(ns);
  std::int64_t last_line = -1;
  std::string last_file;
  double stamp_min = std::numeric_limits<double>::infinity(), stamp_max = -stamp_min;
  for (std::size_t t = 0; t < plan.shards; ++t) {
    const std::string path = part_path(w, "passes", t);
    named(path, [&] {
      StageReport ev_rep;
      get_report(*in[t], ev_rep);
      if (t == 0 && p->two_phase < ns) detail::merge_report(sum.stages[p->two_phase], ev_rep);
      for (std::size_t k = plan.ranges[t].first; k < plan.ranges[t].second; ++k) {
        PassSummary ps;
        ps.file = pio::get_str(*in[t]);
        ps.returns = pio::get<std::uint64_t>(*in[t]);
        ps.lines = pio::get<std::uint64_t>(*in[t]);
        const auto h = pio::get<LabelHistogram>(*in[t]);
        ps.kept = h[0];
        const bool any = pio::get<std::uint8_t>(*in[t]) != 0;
        const auto l0 = pio::get<std::int64_t>(*in[t]), l1 = pio::get<std::int64_t>(*in[t]);
        const double s0 = pio::get<double>(*in[t]), s1 = pio::get<double>(*in[t]);
        if (any) {
          stamp_min = std::min(stamp_min, s0);
          stamp_max = std::max(stamp_max, s1);
          if (l0 <= last_line)
            throw InputError(ps.file + ": field 'line': its first line " + std::to_string(l0) +
                             " is not after the last line " + std::to_string(last_line) + " of " + last_file +
                             " (line indices are unique within a run and increase with time)");
          last_line = l1;
          last_file = ps.file;
        }
        for (std::size_t s = 0; s < ns; ++s) {
          StageReport r;
          get_report(*in[t], r);
          if (pio::get<std::uint8_t>(*in[t])) {
            auto part = empty_partial(*p->stages[s]);
            part->load(*in[t]);
            if (!running[s]) running[s] = std::move(part);
            else p->stages[s]->merge(*running[s], std::move(*part));
          }
          detail::merge_report(sum.stages[s], r);
        }
        for (std::size_t l = 0; l < kLabelCount; ++l) sum.labels[l] += h[l];
        sum.input_returns += ps.returns;
        sum.passes.push_back(ps);
      }
      pio::expect(*in[t], "end");
    });
  }
  // Every label is final: the run-level checks of `run`, before any product is written.
  std::vector<std::string> run_warnings;
  detail::check_what_was_kept(cfg, p->context.poses.get(), sum, stamp_min, stamp_max, run_warnings);
  // The products, in stage order, then returns.pcd and cloud.pcd (the tasks' bodies behind one header).
  for (std::size_t s = 0; s < ns; ++s) {
    if (p->stages[s]->kind() != StageKind::kAccumulator) continue;
    for (auto& wr : p->stages[s]->finish(std::move(running[s]), sum.stages[s], 1)) {
      std::vector<std::string> staged;
      for (const auto& f : wr.files) staged.push_back(out.staged_path(f));
      StageReport rep;
      wr.write(staged, rep, WorkShare::serial());
      detail::merge_report(sum.stages[s], rep);
    }
  }
  std::vector<std::string> rp, cp;
  for (std::size_t t = 0; t < plan.shards; ++t) {
    rp.push_back(part_path(w, "passes", t) + ".returns.pcd");
    cp.push_back(part_path(w, "passes", t) + ".cloud.pcd");
  }
  std::uint64_t nr = 0, nc = 0;
  concat_pcd(rp, out.staged_path("returns.pcd"), nr);
  concat_pcd(cp, out.staged_path("cloud.pcd"), nc);
  if (nr != sum.input_returns)
    throw InputError(w + ": the tasks' returns.pcd records hold " + std::to_string(nr) + " returns, their partials " +
                     std::to_string(sum.input_returns) + ": rerun every task of phase 'passes'");
  const std::string report_tmp = out.staged_path("report.json");
  sum.warnings = run_warnings;
  for (const auto& r : sum.stages)
    for (const auto& wn : r.warnings) sum.warnings.push_back(r.name + ": " + wn);
  if (const double far = p->context.poses ? farthest_pose_offset(*p->context.poses, Eigen::Vector3d::Zero()) : 0.0;
      far > kFloat32MillimetreReach - 1000.0)
    sum.warnings.push_back(cfg.poses + ": poses reach " + format_value(std::round(far)) +
                           " m from the map origin; returns.pcd, cloud.pcd and map.bt (float32) keep 1 mm only within " +
                           format_value(kFloat32MillimetreReach) + " m of it: split the run");
  sum.outputs = out.final_paths();
  for (const auto& f : cfg.scans) sum.input_files.push_back({f, "scan", 0, ""});
  if (!cfg.poses.empty()) sum.input_files.push_back({cfg.poses, "poses", 0, ""});
  std::vector<std::string> names = out.names();
  std::sort(names.begin(), names.end());
  for (const auto& n : names)
    if (n != "report.json") sum.output_files.push_back({n, "", 0, ""});
  for (auto& r : sum.input_files) {
    io::FileDigest d;
    if (const int err = io::digest_file(r.file, d))
      throw InputError(r.file + ": cannot read it to hash it for report.json (" + std::strerror(err) + ")");
    r.bytes = d.bytes;
    r.sha256 = d.sha256;
  }
  for (auto& r : sum.output_files) {
    io::FileDigest d;
    if (io::digest_file((fs::path(out.staging_dir()) / r.file).string(), d)) {
      r.sha256.clear();
      continue;
    }
    r.bytes = d.bytes;
    r.sha256 = d.sha256;
  }
  sum.output_files.erase(std::remove_if(sum.output_files.begin(), sum.output_files.end(),
                                        [](const RunSummary::FileRecord& r) { return r.sha256.empty(); }),
                         sum.output_files.end());
  sum.seconds = detail::seconds_since(t_run);
  std::string js = report_json(cfg, sum);
  // The shard section: the plan the products came from.
  std::string shard = "\n  \"shard\": {\"work_dir\": " + json_string(fs::absolute(w).lexically_normal().string()) +
                      ", \"hash\": " + json_string(plan.hash) + ", \"shards\": " + std::to_string(plan.shards) + ", \"phases\": [";
  for (std::size_t k = 0; k < plan.phases.size(); ++k) shard += (k ? ", " : "") + json_string(plan.phases[k]);
  shard += "]},";
  const auto brace = js.find('{');
  if (brace != std::string::npos) js.insert(brace + 1, shard);
  {
    std::ofstream f(report_tmp, std::ios::binary | std::ios::trunc);
    f.write(js.data(), static_cast<std::streamsize>(js.size()));
    f.flush();
    if (!f) throw OutputError(out.final_path("report.json") + ": cannot write the report (" + std::strerror(errno) + ")");
  }
  out.commit();
  return sum;
}

}  // namespace pcdp
