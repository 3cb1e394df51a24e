// `pcd_pipeline bench`: the whole chain on simulated passes, stage by stage, and in the same run
// the peers on the same data (a plain loop as the memory-bound floor, PCL's transformPointCloud and
// StatisticalOutlierRemoval, OctoMap's insertPointCloud with the same rays). One table, ratios.
// `--scaling 1,10,100` runs `pcd_pipeline run` in a child process per size and reports its wall time
// and peak resident memory (wait4's ru_maxrss), so the numbers are those a user's run would have.
#include "bench.hpp"

#include <octomap/OcTree.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <sstream>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/fusion/octomap_fusion.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/register.hpp"

namespace fs = std::filesystem;

namespace pcdp::cli {
namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

template <class F>
double time_median(int reps, F&& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    t.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  return median(t);
}

std::string human(double v) {
  char b[32];
  if (v >= 1e6) std::snprintf(b, sizeof b, "%.2f M", v / 1e6);
  else if (v >= 1e3) std::snprintf(b, sizeof b, "%.1f k", v / 1e3);
  else std::snprintf(b, sizeof b, "%.0f", v);
  return b;
}

std::size_t simulate_to(const BenchArgs& a, int passes, bool geometric, const fs::path& dir) {
  sim::SimConfig cfg = load_scene(a.scene);
  cfg.passes = static_cast<std::size_t>(passes);
  if (geometric) cfg = sim::geometric(cfg);
  const sim::SimResult r = sim::simulate(cfg);
  sim::write_run(r, cfg, dir.string());
  std::size_t n = 0;
  for (const auto& p : r.passes) n += p.pass.size();
  return n;
}

LoadOptions options_for(const fs::path& data, const fs::path& out) {
  LoadOptions o;
  o.overrides = {{"input.scans", (data / "pass_*.pcd").string()}, {"input.poses", (data / "poses.csv").string()}};
  o.output_dir = out.string();
  return o;
}

struct Row {
  std::string what;
  double items = 0, seconds = 0, target = 0;  ///< target in items/s (0: none)
};

void print_row(const Row& r, double floor_rate) {
  const double rate = r.seconds > 0 ? r.items / r.seconds : 0.0;
  std::printf("  %-44s %10.0f %9.4f %11s/s", r.what.c_str(), r.items, r.seconds, human(rate).c_str());
  if (floor_rate > 0) std::printf("  %6.3f", rate / floor_rate);
  else std::printf("  %6s", "");
  if (r.target > 0) std::printf("  %9s/s %s", human(r.target).c_str(), rate >= r.target ? "met" : "NOT met");
  std::printf("\n");
}

/// The registered returns of every pass, with their sensor origins, as the pipeline's register stage
/// produces them (same configuration), plus the labels of the finished run from returns.pcd.
struct Registered {
  std::vector<float> x, y, z, ox, oy, oz;   ///< every return with a point
  std::vector<std::size_t> line_start;      ///< per scan line, into the arrays above
  std::vector<char> kept;                   ///< kept by the whole chain (label 0 in returns.pcd)
  std::size_t returns = 0;
};

Registered register_all(const PipelineConfig& c, const fs::path& returns_pcd) {
  // Relative to the run's map origin, as the pipeline registers (pcdp/core/georef.hpp).
  const PoseTrack read = io::read_pose_csv(c.poses, c.rpy_order);
  const PoseTrack poses = shift_poses(read, choose_map_origin(read));
  const Eigen::Isometry3d T_V_N = make_transform(c.mount.translation, c.mount.rpy, c.rpy_order);
  const io::PcdTable t = io::read_pcd(returns_pcd.string());
  const auto col = [&](const char* name) {
    const int k = t.header.field_index(name);
    if (k < 0) throw InputError(returns_pcd.string() + ": no field '" + name + "'");
    return io::column_values(t, static_cast<std::size_t>(k));
  };
  const std::vector<double> label = col("label"), tline = col("line"), tbeam = col("beam");
  Registered out;
  std::size_t row = 0;
  for (std::size_t k = 0; k < c.scans.size(); ++k) {
    Pass p = read_pass(c.scans[k], k);
    register_pass(p, RegisterParams{}, c.sensor, T_V_N, &poses);
    for (std::size_t l = 0; l + 1 < p.line_begin.size(); ++l) {
      out.line_start.push_back(out.x.size());
      for (std::size_t i = p.line_begin[l]; i < p.line_begin[l + 1]; ++i, ++row) {
        if (row >= label.size() || tline[row] != p.line[i] || tbeam[row] != p.beam[i])
          throw InputError(returns_pcd.string() + ": row " + std::to_string(row) + " is not pass " + std::to_string(k) +
                           " line " + std::to_string(p.line[i]) + " beam " + std::to_string(p.beam[i]));
        ++out.returns;
        if (!std::isfinite(p.x[i])) continue;
        out.x.push_back(static_cast<float>(p.x[i]));
        out.y.push_back(static_cast<float>(p.y[i]));
        out.z.push_back(static_cast<float>(p.z[i]));
        out.ox.push_back(static_cast<float>(p.ox[i]));
        out.oy.push_back(static_cast<float>(p.oy[i]));
        out.oz.push_back(static_cast<float>(p.oz[i]));
        out.kept.push_back(label[row] == 0);
      }
    }
  }
  out.line_start.push_back(out.x.size());
  return out;
}

/// --scaling's sizes, checked (ConfigError) before any work.
std::vector<int> scaling_sizes(const BenchArgs& a) {
  std::vector<int> sizes;
  std::stringstream ss(a.scaling);
  for (std::string s; std::getline(ss, s, ',');) {
    int v = 0;
    std::size_t used = 0;
    try {
      v = std::stoi(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != s.size())  // "4x" is not 4
      throw ConfigError("--scaling: '" + s + "' is not a number of passes");
    if (v < 1 || v > 1000) throw ConfigError("--scaling: " + s + " passes is outside 1 .. 1000");
    sizes.push_back(v);
  }
  if (!a.scaling.empty() && sizes.empty()) throw ConfigError("--scaling: '" + a.scaling + "' names no number of passes");
  return sizes;
}

int run_scaling(const BenchArgs& a, const fs::path& scratch) {
  const std::vector<int> sizes = scaling_sizes(a);
  std::printf("\nScaling (geometric simulator, `pcd_pipeline run` in a child process per size):\n");
  std::printf("  %8s %12s %10s %12s %14s %16s\n", "passes", "returns", "seconds", "returns/s", "peak RSS MB",
              "s per 1M returns");
  for (int n : sizes) {
    const fs::path data = scratch / ("scale-" + std::to_string(n));
    const std::size_t returns = simulate_to(a, n, true, data);
    const std::string self = fs::read_symlink("/proc/self/exe").string();
    std::vector<std::string> args = {self,
                                     "run",
                                     a.pipeline,
                                     "--set",
                                     "input.scans=" + (data / "pass_*.pcd").string(),
                                     "--set",
                                     "input.poses=" + (data / "poses.csv").string(),
                                     "--output-dir",
                                     (data / "out").string(),
                                     "--quiet"};
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    const auto t0 = Clock::now();
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid == 0) {
      // The run ends with bench: a SIGTERM to bench alone (whose signal cleanup removes the scratch
      // folder the run writes in) reaches the run too, and its own cleanup removes its staging.
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != parent) ::_exit(128 + SIGTERM);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    if (pid < 0) throw std::runtime_error("bench: fork failed");
    int status = 0;
    rusage ru{};
    ::wait4(pid, &status, 0, &ru);
    const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
      throw std::runtime_error("bench: the run with " + std::to_string(n) + " passes failed (status " +
                               std::to_string(status) + ")");
    std::printf("  %8d %12zu %10.3f %12s %14.1f %16.3f\n", n, returns, secs,
                human(static_cast<double>(returns) / secs).c_str(), static_cast<double>(ru.ru_maxrss) / 1024.0,
                secs / (static_cast<double>(returns) / 1e6));
    std::fflush(stdout);
    fs::remove_all(data);
  }
  return 0;
}

}  // namespace

std::string bench_data_root() {
  const char* want = "sample_scans/scene.yaml";
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path installed = ec ? fs::path() : exe.parent_path().parent_path() / "share" / "pcd_pipeline";
  if (!installed.empty() && fs::is_regular_file(installed / want, ec)) return installed.string();
#ifdef PCDP_BUILD_SOURCE_DIR
  const fs::path source = PCDP_BUILD_SOURCE_DIR;
  if (fs::is_regular_file(source / want, ec)) return source.string();
#else
  const fs::path source;
#endif
  throw ConfigError("bench: no sample data for the default --scene and --pipeline: neither " +
                    (installed.empty() ? std::string("<prefix>/share/pcd_pipeline") : installed.string()) +
                    (source.empty() ? std::string() : " nor " + source.string()) + " has " + want +
                    " (install pcd_pipeline with cmake --install, or give --scene and --pipeline)");
}

int cmd_bench(BenchArgs a) {
  if (a.scene.empty() || a.pipeline.empty()) {
    const fs::path root = bench_data_root();
    if (a.scene.empty()) a.scene = (root / "sample_scans" / "scene.yaml").string();
    if (a.pipeline.empty()) a.pipeline = (root / "pipelines" / "nodding_terrain.yaml").string();
  }
  // The --scaling runs are child processes: the pipeline by an absolute path, whatever they inherit.
  a.pipeline = fs::absolute(a.pipeline).string();
  if (a.passes < 1 || a.passes > 1000) throw ConfigError("--passes " + std::to_string(a.passes) + " is outside 1 .. 1000");
  if (a.reps < 1 || a.reps > 100) throw ConfigError("--reps " + std::to_string(a.reps) + " is outside 1 .. 100");
  (void)scaling_sizes(a);  // checked before the benchmark, not after it
  // Prepare first: a bad pipeline or scene fails before anything is simulated.
  (void)load_pipeline(a.pipeline, LoadOptions{{}, "", false});
  (void)load_scene(a.scene);
  // Removed on every exit path, a SIGINT, SIGTERM or SIGHUP included.
  const io::ScratchFolder scratch((fs::temp_directory_path() / ("pcdp-bench-" + std::to_string(::getpid()))).string());
  const fs::path root = scratch.path(), data = root / "data", out = root / "out";
  const std::size_t returns = simulate_to(a, a.passes, a.geometric, data);

  // Our chain: the real pipeline, median of reps; per-stage times from the run's own report. The
  // same chain on 2 worker threads, into another folder: time, and whether every output is
  // byte-identical (report.json aside: it holds timings). The two alternate, run by run, so both
  // see the same machine (a shared machine's speed drifts over seconds).
  const fs::path out2 = root / "out-2threads";
  std::vector<RunSummary> runs, runs2;
  std::vector<double> totals2;
  for (int r = 0; r < a.reps; ++r) {
    runs.push_back(Pipeline::prepare(load_pipeline(a.pipeline, options_for(data, out))).run());
    runs2.push_back(Pipeline::prepare(load_pipeline(a.pipeline, options_for(data, out2))).run({}, 2));
    totals2.push_back(runs2.back().seconds);
  }
  std::size_t compared = 0, differ = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    if (name == "report.json") continue;
    ++compared;
    std::ifstream f1(e.path(), std::ios::binary), f2(out2 / name, std::ios::binary);
    const std::string b1((std::istreambuf_iterator<char>(f1)), {}), b2((std::istreambuf_iterator<char>(f2)), {});
    differ += !f2 || b1 != b2;
  }
  const PipelineConfig cfg = load_pipeline(a.pipeline, options_for(data, out));
  const Registered reg = register_all(cfg, out / "returns.pcd");
  const std::size_t npts = reg.x.size();

  // Floor: read every point and write it transformed (what any registration must at least do).
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.3f, Eigen::Vector3f(0.2f, 0.3f, 0.9f).normalized()).toRotationMatrix();
  const Eigen::Vector3f tr(1.f, 2.f, 3.f);
  std::vector<float> fx(npts), fy(npts), fz(npts);
  const int floor_reps = std::max(a.reps, 5);
  const double t_floor = time_median(floor_reps, [&] {
    for (std::size_t i = 0; i < npts; ++i) {
      const Eigen::Vector3f q = R * Eigen::Vector3f(reg.x[i], reg.y[i], reg.z[i]) + tr;
      fx[i] = q.x();
      fy[i] = q.y();
      fz[i] = q.z();
    }
  });
  volatile float sink = npts ? fx[npts / 2] + fy[npts - 1] + fz[0] : 0.0f;  // keep the stores alive
  (void)sink;
  const double floor_rate = static_cast<double>(npts) / t_floor;

  const PeerTimes pcl = pcl_peers(reg.x, reg.y, reg.z, reg.kept, a.reps);

  // OctoMap insertPointCloud with the same rays as fuse_octomap: the kept points, one call per scan
  // line with that line's sensor origin (the origin moves by millimetres within a line).
  octomap::OcTree ours(0.1);
  const fs::path bt = out / "map.bt";
  const bool have_map = fs::exists(bt) && ours.readBinary(bt.string());
  const double res = have_map ? ours.getResolution() : 0.1;
  std::size_t rays = 0;
  for (char k : reg.kept) rays += static_cast<std::size_t>(k);
  std::vector<double> t_oct;
  std::size_t occ_theirs = 0, common = 0, occ_ours = 0;
  for (int rep = 0; rep < std::min(a.reps, 3); ++rep) {
    octomap::OcTree theirs(res);
    const auto t0 = Clock::now();
    for (std::size_t l = 0; l + 1 < reg.line_start.size(); ++l) {
      octomap::Pointcloud pc;
      std::size_t first = SIZE_MAX;
      for (std::size_t i = reg.line_start[l]; i < reg.line_start[l + 1]; ++i) {
        if (!reg.kept[i]) continue;
        if (first == SIZE_MAX) first = i;
        pc.push_back(reg.x[i], reg.y[i], reg.z[i]);
      }
      if (first == SIZE_MAX) continue;
      theirs.insertPointCloud(pc, octomap::point3d(reg.ox[first], reg.oy[first], reg.oz[first]), cfg.sensor.range_max);
    }
    t_oct.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    if (rep == 0 && have_map) {
      // Finest keys on both sides: pruned leaves are expanded, so the counts compare cell for cell.
      const auto mine = occupied_keys(ours), their_keys = occupied_keys(theirs);
      occ_ours = mine.size();
      occ_theirs = their_keys.size();
      for (const auto& k : their_keys) common += mine.count(k);
    }
  }
  const double t_octomap = median(t_oct);

  std::printf("pcd_pipeline bench: %d pass(es) of %s%s, %zu returns (%zu with a point), median of %d run(s), 1 thread\n",
              a.passes, a.scene.c_str(), a.geometric ? " (geometric)" : "", returns, npts, a.reps);
  std::printf("  %-44s %10s %9s %13s  %6s  %s\n", "step", "items", "seconds", "rate", "/floor", "target (per core)");
  double stages_total = 0;
  std::vector<double> totals;
  for (const auto& r : runs) totals.push_back(r.seconds);
  const auto& names = runs.front().stages;
  double octomap_stage = 0;
  for (std::size_t s = 0; s < names.size(); ++s) {
    // A stage's work, without writing its products at the end (GeoTIFF, PNG, map.bt): that is a
    // per-run cost, shown on its own row. (Building the OctoMap at the end is work: it counts.)
    std::vector<double> t, tw;
    for (const auto& r : runs) {
      const auto f = r.stages[s].metrics.find("write_seconds");
      const double w = f == r.stages[s].metrics.end() ? 0.0 : f->second;
      t.push_back(r.stages[s].seconds - w);
      tw.push_back(w);
    }
    const double sec = median(t), write_sec = median(tw);
    stages_total += sec;
    const std::string& type = names[s].type;
    double target = 0;
    if (type == "register") target = 20e6;
    else if (type.rfind("reject_", 0) == 0 || type == "check_consistency") target = 10e6;
    else if (type == "fuse_elevation") target = 10e6;
    if (type == "fuse_octomap") octomap_stage = sec;
    const double items = type == "register" ? static_cast<double>(returns) : static_cast<double>(names[s].in);
    print_row({names[s].name + " (" + type + ")", items, sec, target}, floor_rate);
    if (write_sec > 0) print_row({"  + writing its files (once per run)", items, write_sec, 0}, floor_rate);
  }
  print_row({"whole run (read, stages, write)", static_cast<double>(returns), median(totals), 0}, floor_rate);
  std::printf("  peers, same data, same run:\n");
  print_row({"floor: plain loop, read + transform + write", static_cast<double>(npts), t_floor, 0}, floor_rate);
  print_row({"pcl::transformPointCloud (PointXYZ)", static_cast<double>(npts), pcl.transform, 0}, floor_rate);
  print_row({"pcl::StatisticalOutlierRemoval (k 8, 1 sd)", static_cast<double>(pcl.sor_points), pcl.sor, 0},
            floor_rate);
  print_row({"octomap insertPointCloud (per line, same rays)", static_cast<double>(rays), t_octomap, 0}, floor_rate);
  std::printf("  ratios (ours over peer, >1 is faster):\n");
  for (const auto& st : names) {
    std::vector<double> t;
    for (const auto& r : runs)
      for (const auto& x : r.stages)
        if (x.name == st.name) t.push_back(x.seconds);
    const double sec = median(t);
    if (st.type == "register")
      std::printf("    register vs pcl::transformPointCloud (per item): %.3f\n",
                  (static_cast<double>(returns) / sec) / (static_cast<double>(npts) / pcl.transform));
    if (st.type == "reject_mixed_pixels")
      std::printf("    reject_mixed_pixels vs StatisticalOutlierRemoval (per item): %.2f\n",
                  (static_cast<double>(st.in) / sec) / (static_cast<double>(pcl.sor_points) / pcl.sor));
  }
  if (octomap_stage > 0) {
    std::printf("    fuse_octomap vs insertPointCloud (same rays): %.2f  (target >= 10)\n",
                (static_cast<double>(rays) / octomap_stage) / (static_cast<double>(rays) / t_octomap));
    if (have_map && occ_theirs > 0)
      std::printf("    occupied cells: ours %zu, insertPointCloud %zu, common %zu = %.2f %% of theirs (target >= 99 %%)\n",
                  occ_ours, occ_theirs, common, 100.0 * static_cast<double>(common) / static_cast<double>(occ_theirs));
  }
  const double t1 = median(totals), t2 = median(totals2);
  std::vector<double> paired;  // each 2-thread run against the 1-thread run just before it
  for (std::size_t r = 0; r < totals.size(); ++r) paired.push_back(totals[r] / totals2[r]);
  const auto [lo, hi] = std::minmax_element(paired.begin(), paired.end());
  std::printf("  whole run on 2 threads: %.3f s against %.3f s on 1: %.2fx (target >= 1.7; run by run %.2f-%.2fx); "
              "%zu output file(s) compared, %s\n",
              t2, t1, t1 / t2, *lo, *hi, compared, differ ? "SOME DIFFER" : "all byte-identical");
  // Where the 2-thread run loses time: each phase's median wall time on 1 and 2 threads, and the
  // core time the 2-thread run left idle in it (2 x wall - the process's CPU time).
  std::printf("  phases, ms on 1 / 2 threads (2-thread idle core ms):");
  for (std::size_t ph = 0; ph < runs.front().phases.size(); ++ph) {
    std::vector<double> w1, w2, idle;
    for (const auto& r : runs) w1.push_back(r.phases[ph].seconds);
    for (const auto& r : runs2) {
      w2.push_back(r.phases[ph].seconds);
      idle.push_back(std::max(0.0, 2.0 * r.phases[ph].seconds - r.phases[ph].cpu_seconds));
    }
    std::printf("%s %s %.1f / %.1f (%.1f)", ph ? "," : "", runs.front().phases[ph].name.c_str(), 1e3 * median(w1),
                1e3 * median(w2), 1e3 * median(idle));
  }
  std::printf("\n");
  std::fflush(stdout);
  if (!a.scaling.empty()) return run_scaling(a, root);
  return 0;
}

}  // namespace pcdp::cli
