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

#include "pipeline/shard_files.hpp"

namespace pcdp {

namespace fs = std::filesystem;
namespace pio = partial_io;
using namespace detail::shard;


namespace {
/// 2: paths made absolute in the plan's folder (the hash sees them), passes partials with their records' digests.
constexpr const char* kPlanTag = "pcdp.shard_plan.2";
/// Whether a plan's tag is another version's.
bool another_versions_tag(const std::string& tag) { return tag.rfind("pcdp.shard_plan.", 0) == 0 && tag != kPlanTag; }
/// Whether `path` is a plan of another version of pcd_pipeline.
bool older_plan(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  try {
    return another_versions_tag(pio::get_str(in));
  } catch (const std::exception&) {
    return false;
  }
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
  // Refused now, not after the passes: the reduce's commit would replace such an input.
  io::check_inputs_not_replaced(p->cfg.output_dir, detail::run_inputs(p->cfg), detail::run_products());
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
  if (fs::exists(bin) && !older_plan(bin.string())) {  // another version's plan is replaced (its partials too are refused)
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
    pio::put_str(s, kPlanTag);
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
    const std::string tag = pio::get_str(in);
    if (another_versions_tag(tag))
      throw InputError("a plan made by another version of pcd_pipeline (" + tag + ", this one reads " + kPlanTag +
                       "): plan again (`pcd_pipeline shard` replaces it)");
    if (tag != kPlanTag) throw InputError("not a shard plan");
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
  const std::string returns_tmp = out.also(part_path(w, phase, index) + ".returns.pcd"),
                    cloud_tmp = out.also(part_path(w, phase, index) + ".cloud.pcd");
  io::ReturnsWriter returns(returns_tmp, p->context.map_origin);
  io::CloudWriter cloud(cloud_tmp, p->context.map_origin);
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
  // The records' SHA-256, so that the reduce takes only the records this partial describes (not
  // a truncated, swapped or overwritten file).
  for (const std::string* f : {&returns_tmp, &cloud_tmp}) {
    io::FileDigest d;
    if (const int e = io::digest_file(*f, d)) throw OutputError(*f + ": cannot read it back (" + std::strerror(e) + ")");
    pio::put_str(o, d.sha256);
  }
  pio::put_str(o, "end");
  out.commit();  // the records first, the partial last: a partial on disk means its records are complete
}


}  // namespace pcdp
