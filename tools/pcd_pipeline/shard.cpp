#include "shard.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/shard.hpp"

namespace pcdp::cli {

namespace fs = std::filesystem;

namespace {

std::string quote(const std::string& s) {
  std::string o = "'";
  for (const char c : s) o += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return o + "'";
}

std::string script_path(const std::string& w, const std::string& phase) {
  return (fs::path(w) / "jobs" / (phase + ".sh")).string();
}

/// One job script per phase: `pcd_pipeline shard-task W PHASE INDEX`, INDEX from $1 or
/// $SLURM_ARRAY_TASK_ID. PCDP_SHARD_FAIL_TASK=K makes task K of phase 'passes' fail (fault
/// injection for tests of the rerun path).
void write_scripts(const std::string& w, const ShardPlan& plan) {
  const std::string exe = fs::read_symlink("/proc/self/exe").string();
  fs::create_directories(fs::path(w) / "jobs");
  fs::create_directories(fs::path(w) / "logs");
  for (const auto& phase : plan.phases) {
    const std::string path = script_path(w, phase), tmp = path + ".tmp";
    {
      std::ofstream s(tmp);
      s << "#!/bin/sh\n"
        << "# pcd_pipeline shard: phase '" << phase << "' of the plan in " << w << " (" << plan.tasks(phase)
        << " task(s)); index from $1 or $SLURM_ARRAY_TASK_ID\n"
        << "#SBATCH --job-name=pcdp-" << phase << "\n"
        << "#SBATCH --output=" << (fs::path(w) / "logs" / (phase + "-%a.log")).string() << "\n"
        << "set -eu\n"
        << "INDEX=\"${1:-${SLURM_ARRAY_TASK_ID:-0}}\"\n";
      if (phase == "passes")
        s << "if [ \"${PCDP_SHARD_FAIL_TASK:-}\" = \"$INDEX\" ]; then\n"
          << "  echo \"pcd_pipeline shard: task $INDEX of phase passes fails on request (PCDP_SHARD_FAIL_TASK)\" >&2\n"
          << "  exit 1\nfi\n";
      s << "cd " << quote(plan.cwd) << "\n"
        << "exec " << quote(exe) << " shard-task " << quote(w) << " " << phase << " \"$INDEX\"\n";
      if (!s) throw OutputError(tmp + ": cannot write the job script");
    }
    fs::permissions(tmp, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                              fs::perms::others_exec);
    fs::rename(tmp, path);
  }
}

std::string capture(const std::string& cmd, int& status) {
  std::string out;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) {
    status = -1;
    return out;
  }
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  status = ::pclose(p);
  return out;
}

std::string field(const std::string& line, const std::string& name) {
  const std::string key = name + "=";
  std::size_t at = line.rfind(" " + key) != std::string::npos ? line.find(" " + key) + 1 : line.rfind(key, 0) == 0 ? 0 : std::string::npos;
  if (at == std::string::npos) return {};
  at += key.size();
  return line.substr(at, line.find(' ', at) - at);
}

/// Waits for every task of `jobs` to end (a deadline), printing each task's state; true when all
/// COMPLETED. `scontrol show job`, not `sbatch --wait` (0 for a job cancelled by its dependency).
bool wait_jobs(const std::vector<std::string>& jobs, double timeout) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  for (;;) {
    bool busy = false, ok = true;
    std::vector<std::string> lines;
    for (const auto& id : jobs) {
      int st = 0;
      const std::string out = capture("scontrol show job -o " + id + " 2>&1", st);
      if (st != 0) {
        if (out.find("Invalid job id") != std::string::npos) {
          lines.push_back(id + " UNKNOWN");
          ok = false;
        } else {
          busy = true;
        }
        continue;
      }
      std::size_t a = 0;
      while (a < out.size()) {
        std::size_t b = out.find('\n', a);
        if (b == std::string::npos) b = out.size();
        const std::string line = out.substr(a, b - a);
        a = b + 1;
        if (line.empty()) continue;
        std::string name = field(line, "JobId");
        if (!field(line, "ArrayJobId").empty()) name = field(line, "ArrayJobId") + "_" + field(line, "ArrayTaskId");
        const std::string state = field(line, "JobState");
        lines.push_back(name + " " + state + " reason=" + field(line, "Reason") + " exit=" + field(line, "ExitCode"));
        if (state == "COMPLETED") continue;
        if (state == "PENDING" || state == "RUNNING" || state == "CONFIGURING" || state == "COMPLETING" ||
            state == "SUSPENDED" || state == "REQUEUED")
          busy = true;
        else
          ok = false;
      }
    }
    if (!busy || std::chrono::steady_clock::now() > deadline) {
      for (const auto& l : lines) std::cout << l << "\n";
      if (busy) std::cerr << "pcd_pipeline shard: the jobs did not end within " << timeout << " s\n";
      return ok && !busy;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

int run_local(const std::string& w, const ShardPlan& plan) {
  for (const auto& phase : plan.phases)
    for (std::size_t t = 0; t < plan.tasks(phase); ++t) {
      const std::string cmd = "/bin/sh " + quote(script_path(w, phase)) + " " + std::to_string(t);
      const int st = std::system(cmd.c_str());
      const int rc = WIFEXITED(st) ? WEXITSTATUS(st) : 128;
      if (rc != 0) {
        std::cerr << "pcd_pipeline shard: task " << t << " of phase '" << phase << "' failed (exit " << rc
                  << "); rerun it: pcd_pipeline shard-task " << w << " " << phase << (phase == "reduce" ? "" : " " + std::to_string(t)) << "\n";
        return rc;
      }
    }
  return 0;
}

int submit(const ShardArgs& a, const std::string& w, const ShardPlan& plan) {
  std::string extra;
  for (const auto& s : a.sbatch_args) extra += " " + quote(s);
  std::vector<std::string> jobs;
  std::string prev;
  for (const auto& phase : plan.phases) {
    const std::size_t n = plan.tasks(phase);
    std::string cmd = "sbatch --parsable --kill-on-invalid-dep=yes --array=0-" + std::to_string(n - 1);
    if (!prev.empty()) cmd += " --dependency=afterok:" + prev;
    cmd += extra + " " + quote(script_path(w, phase)) + " 2>&1";
    int st = 0;
    std::string out = capture(cmd, st);
    while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
    if (st != 0 || out.empty()) {
      std::cerr << "error: sbatch failed for phase '" << phase << "': " << out << "\n";
      return 4;
    }
    prev = out.substr(0, out.find(';'));
    jobs.push_back(prev);
    std::cout << "submitted phase " << phase << ": job " << prev << " (" << n << " task(s))\n";
  }
  if (!a.wait) return 0;
  return wait_jobs(jobs, a.wait_timeout) ? 0 : 1;
}

}  // namespace

void add_shard_commands(CLI::App& app, ShardArgs& a) {
  a.shard = app.add_subcommand("shard", "plan a run as tasks over pass ranges; run them here (--local) or on Slurm (--submit)");
  a.shard->add_option("pipeline", a.pipeline, "pipeline YAML file")->required();
  a.shard->add_option("--shards", a.shards, "number of tasks per phase (at most the number of passes)")->required()->check(CLI::Range(1, 1000000));  // before the conversion: -1 is not 2^64 - 1
  a.shard->add_option("--work-dir", a.work_dir, "folder for the plan, the job scripts, the partials and logs")->required();
  a.shard->add_option("--set", a.sets, "override a key (as for run)");
  a.shard->add_option("--output-dir", a.output_dir, "output folder (wins over output_dir in the file)");
  a.shard->add_flag("--local", a.local, "run the job scripts here, task after task");
  a.shard->add_flag("--submit", a.submit, "submit the job scripts with sbatch (arrays, afterok dependencies)");
  a.shard->add_flag("--wait", a.wait, "with --submit: wait for the jobs, print each task's state; non-zero unless all completed");
  a.shard->add_option("--wait-timeout", a.wait_timeout, "seconds --wait waits at most");
  a.shard->add_option("--sbatch-arg", a.sbatch_args, "an extra argument for every sbatch (repeatable)");
  a.task = app.add_subcommand("shard-task", "run one task of a shard plan: evidence I, passes I, or reduce");
  a.task->add_option("work_dir", a.task_work_dir, "the plan's work dir")->required();
  a.task->add_option("phase", a.phase, "evidence, passes or reduce")->required();
  a.task->add_option("index", a.index, "task index (default: $SLURM_ARRAY_TASK_ID)");
}

int run_shard_commands(const ShardArgs& a) {
  if (a.shard && *a.shard) {
    if (a.local && a.submit) throw ConfigError("shard: give --local or --submit, not both");
    if (a.wait && !a.submit) throw ConfigError("shard: --wait goes with --submit");
    const std::string w = fs::absolute(a.work_dir).lexically_normal().string();
    const ShardPlan plan = make_shard_plan(a.pipeline, a.sets, a.output_dir, a.shards);
    write_shard_plan(w, plan);
    write_scripts(w, plan);
    std::cout << "plan: " << plan.passes << " pass(es) in " << plan.shards << " task(s), phases:";
    for (const auto& p : plan.phases) std::cout << " " << p;
    std::cout << "; " << (fs::path(w) / "plan.json").string() << "\n";
    if (a.local) return run_local(w, plan);
    if (a.submit) return submit(a, w, plan);
    return 0;
  }
  if (a.task && *a.task) {
    std::string idx = a.index;
    if (idx.empty())
      if (const char* e = std::getenv("SLURM_ARRAY_TASK_ID")) idx = e;
    if (a.phase == "reduce") {
      const RunSummary s = run_shard_reduce(a.task_work_dir);
      std::cout << "pcd_pipeline shard reduce: " << s.passes.size() << " pass(es), " << s.input_returns << " returns, "
                << s.labels[0] << " kept; outputs in " << s.output_dir << "\n";
      return 0;
    }
    if (idx.empty() || idx.find_first_not_of("0123456789") != std::string::npos)
      throw ConfigError("shard-task: the task index '" + idx + "' is not a number (give it or set SLURM_ARRAY_TASK_ID)");
    if (idx.size() > 9)  // beyond any plan (and beyond what stoul takes)
      throw ConfigError("shard-task: the task index " + idx + " is beyond any plan's tasks");
    run_shard_task(a.task_work_dir, a.phase, std::stoul(idx));
    return 0;
  }
  return -1;
}

}  // namespace pcdp::cli
