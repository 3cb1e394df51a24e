#include "pipeline/shard_files.hpp"

#include "io/signal_cleanup.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unistd.h>

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


namespace pcdp::detail::shard {

namespace pio = partial_io;

constexpr const char* kMagic = "pcdp.shard.2";  // 2: passes partials end with their records' SHA-256

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


std::unique_ptr<Prepared> prepare(const ShardPlan& plan) {
  // --set paths are relative to the working directory of `shard`; every path is made absolute
  // there, so a task reads the same files from whatever folder it is started in.
  std::error_code ec;
  const fs::path here = fs::current_path(ec);
  if (!plan.cwd.empty()) {
    fs::current_path(plan.cwd, ec);
    if (ec)
      throw InputError("shard: the folder the plan was made in, " + plan.cwd + ", cannot be entered (" + ec.message() +
                       "): the pipeline's relative paths are relative to it; restore it or plan again");
  }
  auto p = std::make_unique<Prepared>();
  try {
    p->cfg = load_pipeline(plan.pipeline, options_of(plan));
    for (auto& s : p->cfg.scans) s = fs::absolute(s).lexically_normal().string();
    if (!p->cfg.poses.empty()) p->cfg.poses = fs::absolute(p->cfg.poses).lexically_normal().string();
    p->cfg.output_dir = fs::absolute(p->cfg.output_dir).lexically_normal().string();
  } catch (...) {
    if (!here.empty()) fs::current_path(here, ec);
    throw;
  }
  if (!here.empty()) fs::current_path(here, ec);
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


AtomicOut::AtomicOut(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp." + std::to_string(::getpid())) {
  std::error_code ec;
  fs::create_directories(fs::path(path_).parent_path(), ec);
  lock_ = std::make_unique<io::OutputLock>(path_);  // OutputError at once if another copy of the task runs
  // Holding the lock, every temporary of this task beside the partial is a killed copy's: removed.
  const std::string prefix = fs::path(path_).filename().string() + ".";
  std::vector<fs::path> stale;
  for (const auto& e : fs::directory_iterator(fs::path(path_).parent_path(), ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix, 0) == 0 && n.find(".tmp.") != std::string::npos) stale.push_back(e.path());
  }
  for (const auto& f : stale) fs::remove(f, ec);
  const io::cleanup::BlockSignals hold;  // registered before a signal can act
  out_.open(tmp_, std::ios::binary | std::ios::trunc);
  if (!out_) throw OutputError(tmp_ + ": cannot write it (" + std::strerror(errno) + ")");
  slots_.push_back(io::cleanup::register_temp(tmp_, 1));  // SIGINT, SIGTERM, SIGHUP remove it
}

AtomicOut::~AtomicOut() {
  for (int s : slots_) io::cleanup::unregister_temp(s);
  if (committed_) return;
  out_.close();
  ::unlink(tmp_.c_str());
  for (const auto& [tmp, final_path] : also_) ::unlink(tmp.c_str());
}

std::string AtomicOut::also(const std::string& final_path) {
  also_.emplace_back(final_path + ".tmp." + std::to_string(::getpid()), final_path);
  slots_.push_back(io::cleanup::register_temp(also_.back().first, 1));  // with the writers' temporaries beside it
  return also_.back().first;
}

void AtomicOut::commit() {
  out_.flush();
  if (!out_) throw OutputError(tmp_ + ": cannot write it (" + std::strerror(errno) + ")");
  out_.close();
  for (const auto& [tmp, final_path] : also_)
    if (std::rename(tmp.c_str(), final_path.c_str()) != 0)
      throw OutputError(final_path + ": cannot rename its temporary into place (" + std::strerror(errno) + ")");
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
    throw OutputError(path_ + ": cannot rename its temporary into place (" + std::strerror(errno) + ")");
  committed_ = true;
}

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

}  // namespace pcdp::detail::shard
