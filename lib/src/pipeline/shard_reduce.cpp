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

/// Concatenates the bodies of the tasks' PCD files behind one header; each file must be the one
/// its task's partial describes (`sha256[t]`): a truncated, swapped or overwritten record is an
/// input error naming the task to rerun.
void concat_pcd(const std::vector<std::string>& parts, const std::vector<std::string>& sha256, const std::string& to,
                std::uint64_t& points) {
  std::string header;
  std::vector<std::string> bodies;
  points = 0;
  for (std::size_t t = 0; t < parts.size(); ++t) {
    const std::string& p = parts[t];
    const std::string text = read_text(p);
    if (io::sha256_hex(text.data(), text.size()) != sha256[t])
      throw InputError(p + ": not the record task " + std::to_string(t) +
                       " wrote (its SHA-256 differs from the one in the task's partial: truncated, replaced or "
                       "written by another copy of the task): rerun task " + std::to_string(t) + " of phase 'passes'");
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
  out.protect_inputs(detail::run_inputs(cfg));  // a scan or pose file named like a product would be replaced
  out.owns(detail::run_products());
  std::vector<std::unique_ptr<Partial>> running(ns);
  std::vector<std::string> returns_sha(plan.shards), cloud_sha(plan.shards);  // the records each task wrote
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
      returns_sha[t] = pio::get_str(*in[t]);
      cloud_sha[t] = pio::get_str(*in[t]);
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
  concat_pcd(rp, returns_sha, out.staged_path("returns.pcd"), nr);
  concat_pcd(cp, cloud_sha, out.staged_path("cloud.pcd"), nc);
  if (nr != sum.input_returns)
    throw InputError(w + ": the tasks' returns.pcd records hold " + std::to_string(nr) + " returns, their partials " +
                     std::to_string(sum.input_returns) + ": rerun every task of phase 'passes'");
  const std::string report_tmp = out.staged_path("report.json");
  detail::collect_warnings(cfg, p->context.poses.get(), run_warnings, sum);
  sum.outputs = out.final_paths();
  detail::digest_files(cfg, out, sum);
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
