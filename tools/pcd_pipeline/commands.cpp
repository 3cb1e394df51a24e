#include "commands.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <thread>

#include "pcdp/pipeline/work_share.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/models/calibration.hpp"
#include "pcdp/io/range_samples.hpp"
#include "pcdp/sim/evaluate.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/core/uncertainty.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/import/3dtk.hpp"
#include "pcdp/import/carmen.hpp"
#include "pcdp/import/rplidar.hpp"
#include "pcdp/import/scans.hpp"
#include "pcdp/io/las.hpp"
#include "pcdp/io/paths.hpp"
#include "pcdp/models/nod_plan.hpp"
#include "pcdp/io/svg_plot.hpp"
#include "pcdp/models/occlusion_model.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/core/cloud_pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace pcdp::cli {

namespace {
/// A --threads value: 0 means one per core.
unsigned threads_or_cores(unsigned threads) {
  return threads ? threads : std::max(1u, std::thread::hardware_concurrency());
}
LoadOptions load_options(const RunArgs& a) {
  LoadOptions o;
  for (const auto& s : a.sets) o.overrides.push_back(parse_override(s));
  o.output_dir = a.output_dir;
  return o;
}

/// An output file named on the command line must not be one of `others` (the command's inputs, or
/// another of its outputs), the same file by path or by inode: writing it would destroy that one.
/// ConfigError (exit 2) before any work.
void check_not_input(const std::string& option, const std::string& path, const std::vector<std::string>& others,
                     const std::string& role = "an input of the command") {
  for (const auto& in : others) {
    std::error_code ec;
    const bool same_inode = std::filesystem::equivalent(path, in, ec) && !ec;
    const auto a = io::resolved_path(path), b = io::resolved_path(in);
    if (same_inode || (!a.empty() && a == b))
      throw ConfigError(option + " '" + path + "' is " + role + " ('" + in + "'): it would be overwritten");
  }
}

/// An output file named on the command line: its extension must be one the command writes
/// (case-insensitive), and it must not be one of the command's inputs (the same file by path or
/// by inode), which writing would destroy. ConfigError (exit 2) before any work.
void check_output_file(const std::string& option, const std::string& path, const std::vector<std::string>& extensions,
                       const std::vector<std::string>& inputs = {}) {
  std::string low = path;
  for (auto& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  bool ok = false;
  std::string list;
  for (const auto& e : extensions) {
    ok = ok || (low.size() > e.size() && low.compare(low.size() - e.size(), e.size(), e) == 0);
    list += (list.empty() ? "" : ", ") + e;
  }
  if (!ok) throw ConfigError(option + " '" + path + "': the file must end in " + list);
  check_not_input(option, path, inputs);
}
/// An import (or simulate) owns the pass files and the pose file of its output folder, and `more`
/// (simulate's truth/), an input among them is refused (the commit would replace it): an earlier
/// import's pass_*.pcd (more of them, or another format's) and poses.csv do not stay beside the
/// new set, where a run's `pass_*.pcd` would read them as passes of this import.
void own_pass_products(io::StagedOutputs& staged, const std::string& out_dir, const std::vector<std::string>& inputs,
                         const std::vector<std::string>& more = {}) {
  staged.protect_inputs(inputs);  // an input named like a product of the folder would be replaced
  std::vector<std::string> names = {"poses.csv"};
  names.insert(names.end(), more.begin(), more.end());
  std::error_code ec;
  for (std::filesystem::directory_iterator it(out_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string n = it->path().filename().string();
    if (n.size() > 9 && n.compare(0, 5, "pass_") == 0 && n.compare(n.size() - 4, 4, ".pcd") == 0) names.push_back(n);
  }
  staged.owns(std::move(names));
}

}  // namespace

int cmd_validate(const RunArgs& a) {
  Pipeline p = Pipeline::prepare(load_pipeline(a.pipeline, load_options(a)));
  const PipelineConfig& c = p.config();
  if (!a.quiet) {
    std::cout << a.pipeline << ": valid: " << c.stages.size() << " stage(s) (";
    for (std::size_t i = 0; i < c.stages.size(); ++i) std::cout << (i ? " -> " : "") << c.stages[i].name;
    std::cout << "), " << c.scans.size() << " pass file(s), "
              << (c.poses.empty() ? std::string("no pose file (T_M_V = identity)") : "poses " + c.poses)
              << ", output_dir " << c.output_dir << "\n";
  }
  return 0;
}

int cmd_run(const RunArgs& a) {
  Pipeline p = Pipeline::prepare(load_pipeline(a.pipeline, load_options(a)));
  const bool tty = !a.quiet && ::isatty(STDERR_FILENO);
  ProgressFn progress;
  if (tty) {
    progress = [](const ProgressEvent& e) {
      std::fprintf(stderr, "\r\033[K[pass %zu/%zu] %s: %s", e.pass + 1, e.passes, e.file.c_str(), e.step.c_str());
      std::fflush(stderr);
    };
  }
  // Not capped at the number of passes: threads with no pass to take share the last passes'
  // ray casts (work_share.hpp) and write the products at the end.
  const RunSummary s = p.run(progress, threads_or_cores(a.threads));
  if (tty) std::fprintf(stderr, "\r\033[K");
  for (const auto& w : s.warnings) std::cerr << "warning: " << w << "\n";  // also in report.json, even with --quiet
  if (!a.quiet) {
    std::cout << "pcd_pipeline: " << s.passes.size() << " pass(es), " << s.input_returns << " returns, "
              << s.labels[0] << " kept, in " << s.seconds << " s on " << s.threads << " thread(s)\n";
    std::cout << "labels:";
    for (std::size_t l = 0; l < kLabelCount; ++l)
      if (s.labels[l]) std::cout << " " << label_name(static_cast<Label>(l)) << "=" << s.labels[l];
    std::cout << "\n";
    for (const auto& st : s.stages)
      std::cout << "  " << st.name << " (" << st.type << "): " << st.in << " -> " << st.out << " kept, "
                << st.seconds << " s\n";
    std::cout << "outputs in " << std::filesystem::absolute(s.output_dir).lexically_normal().string() << ":";
    for (const auto& o : s.outputs) std::cout << " " << o.substr(o.find_last_of('/') + 1);
    std::cout << "\n";
  }
  return 0;
}

int cmd_stages() {
  for (const auto& s : builtin_stages()) std::cout << s.type << "\t" << s.summary << "\n";
  return 0;
}

int cmd_simulate(const std::string& scene, const std::string& output_dir, bool quiet) {
  std::string scene_text;  // kept: the scene may be the copy in the output's truth/, which the commit replaces
  const sim::SimConfig cfg = load_scene(scene, &scene_text);
  io::StagedOutputs staged(output_dir);  // locked and checked before the work; committed as a set
  own_pass_products(staged, output_dir, {}, {"truth"});
  const sim::SimResult r = sim::simulate(cfg);
  {  // a data set without a single return is no data set: say why before writing it
    std::size_t beams = 0, none = 0;
    for (const auto& p : r.passes)
      for (Label l : p.truth) {
        ++beams;
        none += l == Label::kNoReturn;
      }
    if (beams > 0 && none == beams)
      throw InputError(scene + ": every one of the " + std::to_string(beams) +
                       " simulated beams returned nothing: the scanner sees no surface within range_max (check "
                       "the mount's height and pitch, nod_min and nod_max, and the scene's objects)");
  }
  const auto files = sim::write_run(r, cfg, staged.staging_dir());
  sim::write_truth(r, cfg, staged.staging_dir());
  // The scene travels with its truth, so `evaluate` knows the noise it should expect.
  io::write_file_atomic((std::filesystem::path(staged.staging_dir()) / "truth" / "scene.yaml").string(), scene_text);
  staged.commit();
  if (!quiet) {
    std::size_t n = 0;
    LabelHistogram truth{};
    for (const auto& p : r.passes) {
      n += p.pass.size();
      for (Label l : p.truth) ++truth[static_cast<std::size_t>(l)];
    }
    std::cout << "simulated " << files.size() << " pass(es), " << n << " returns, " << r.poses.size() << " poses -> "
              << output_dir << " (pass_*.pcd, poses.csv, truth/)\ntruth:";
    for (std::size_t l = 0; l < kLabelCount; ++l)
      if (truth[l]) std::cout << " " << label_name(static_cast<Label>(l)) << "=" << truth[l];
    std::cout << "\n";
  }
  return 0;
}

int cmd_evaluate(const std::string& truth, const std::string& run, const std::string& json, bool quiet) {
  if (!std::filesystem::is_directory(run))
    throw InputError("evaluate --run '" + run + "': no such folder (give the output folder of a run, with its returns.pcd)");
  NoiseModel noise;
  const std::string scene = (std::filesystem::path(truth) / "truth" / "scene.yaml").string();
  if (std::filesystem::exists(scene)) {
    const sim::SimConfig c = load_scene(scene);
    noise = {c.scanner.range_sigma, c.scanner.encoder_resolution, c.motion.position_sigma, c.motion.rpy_sigma, true};
  }
  const std::string out = json.empty() ? (std::filesystem::path(run) / "evaluation.json").string() : json;
  check_output_file("evaluate --json", out, {".json"});
  io::StagedFiles staged;  // checked and locked before the work
  const std::string tmp = staged.add("evaluate --json", out);
  const Evaluation e = evaluate_run(truth, run, noise);
  {
    const std::string js = evaluation_json(e);
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    const bool ok = f && std::fwrite(js.data(), 1, js.size(), f) == js.size();
    if (!f || std::fclose(f) != 0 || !ok) throw OutputError(out + ": cannot write (" + std::strerror(errno) + ")");
  }
  staged.commit();
  if (!quiet) std::cout << evaluation_table(e) << "written: " << out << "\n";
  return 0;
}

int cmd_plan_nod(const NodPlanParams& p, const std::string& csv) {
  // Written so that NaN fails every test (a comparison with NaN is false); infinities are refused too.
  const auto finite = [](double v) { return std::isfinite(v); };
  if (!(p.height > 0) || !(p.sample_distance > 0) || !(p.sweep_period > 0) || !(p.max_rate > 0) ||
      !(p.encoder_resolution >= 0) || !(p.speed >= 0) || !(p.dead_zone_time >= 0) ||
      !(finite(p.height) && finite(p.sample_distance) && finite(p.sweep_period) && finite(p.max_rate) &&
        finite(p.encoder_resolution) && finite(p.speed) && finite(p.dead_zone_time)))
    throw ConfigError("plan-nod: height, sample distance, sweep period and maximum rate must be positive; speed, "
                      "dead-zone time and encoder resolution must not be negative; all must be finite numbers");
  const NodPlan plan = plan_nod(p);
  constexpr double kDeg = 57.29577951308232;
  if (!csv.empty()) io::write_file_atomic(csv, nod_plan_csv(plan, p));
  std::printf("%8s %10s %14s %14s  %s\n", "depr.deg", "ground m", "down deg/s", "up deg/s", "uniform sample distance");
  for (const auto& r : plan.rows) {
    std::string why = r.achievable ? "achievable" : "";
    if (r.in_dead_zone) why += "dead zone ";
    if (r.resolution_limited) why += "below encoder resolution ";
    if (r.rate_limited) why += "above maximum rate ";
    if (!r.achievable && why.empty()) why = "vehicle outruns the sample distance";
    std::printf("%8.1f %10.3f %14.2f %14.2f  %s\n", r.angle * kDeg, r.ground_distance,
                r.step_down / p.sweep_period * kDeg, r.step_up / p.sweep_period * kDeg, why.c_str());
  }
  if (plan.achievable_to > plan.achievable_from)
    std::printf("uniform sample distance %.3f m achievable from %.1f to %.1f deg below the horizon", p.sample_distance,
                plan.achievable_from * kDeg, plan.achievable_to * kDeg);
  else
    std::printf("uniform sample distance %.3f m is achievable at no tabulated angle", p.sample_distance);
  if (plan.dead_zone_angle < 1.5707) std::printf("; dead zone beyond %.1f deg", plan.dead_zone_angle * kDeg);
  std::printf("\n");
  if (!csv.empty()) std::printf("written: %s\n", csv.c_str());
  return 0;
}

int cmd_amplitude_model(const EdgeParams& e, const AmplitudeModelArgs& a) {
  if (!(e.d1 > 0) || !(e.d2 > e.d1))
    throw ConfigError("amplitude-model: need 0 < d1 < d2 (got d1 = " + format_value(e.d1) + ", d2 = " + format_value(e.d2) + ")");
  if (!(e.p1 >= 0) || !(e.p2 >= 0) || !(e.alpha > 0) || !(e.separation >= 0) || a.points < 2 || a.points > 1000000 ||
      !std::isfinite(e.d2) || !std::isfinite(e.p1) || !std::isfinite(e.p2) || !std::isfinite(e.alpha) ||
      !std::isfinite(e.separation) || !std::isfinite(e.theta) || !std::isfinite(a.min_amplitude))
    throw ConfigError("amplitude-model: need finite numbers with p1, p2, separation >= 0, alpha > 0 and 2 <= --points <= 1000000");
  if (!a.profile_csv.empty() && !a.theta_csv.empty()) check_not_input("amplitude-model --theta-csv", a.theta_csv, {a.profile_csv}, "another output of the command");
  constexpr double kDeg = 57.29577951308232;
  const ProfileMinimum m = profile_minimum(e);
  std::printf("Liu et al. 2005 amplitude model: d1 = %g m, d2 = %g m, P1 = %g, P2 = %g, alpha = %g rad, s - q = %g m, theta = %g deg\n",
              e.d1, e.d2, e.p1, e.p2, e.alpha, e.separation, e.theta * kDeg);
  std::printf("X1 = %.3f mm (eq. 4), 2 r1 = %.3f mm, X2 = %.3f mm (eq. 12)\n", x1(e) * 1000, e.d1 * e.alpha * 1000, x2(e) * 1000);
  std::printf("minimum %.2f at x = %.3f mm: %s the minimum detectable amplitude %g\n", m.amplitude, m.x * 1000,
              m.amplitude < a.min_amplitude ? "BELOW" : "above", a.min_amplitude);
  const auto prof = amplitude_profile(e, a.points);
  EdgeParams coax = e;
  coax.separation = 0.0;
  std::vector<std::pair<double, double>> prof_coax;  // at the same x
  for (const auto& [x, v] : prof) prof_coax.emplace_back(x, amplitude_at(coax, x));
  const auto theta = minimum_vs_theta(e, 361);
  double lo = 0, hi = 0;
  for (const auto& [th, mm] : theta)
    if (th >= 0 && mm >= a.min_amplitude) {
      if (lo == 0) lo = th;
      hi = th;
    }
  if (hi > 0) std::printf("no dip below %g for %.1f <= |theta| <= %.1f deg (Fig. 18)\n", a.min_amplitude, lo * kDeg, hi * kDeg);
  if (!a.profile_csv.empty()) {
    std::ostringstream os;
    os << "x_m,amplitude,amplitude_coaxial\n";
    for (std::size_t i = 0; i < prof.size(); ++i) os << prof[i].first << ',' << prof[i].second << ',' << prof_coax[i].second << '\n';
    io::write_file_atomic(a.profile_csv, os.str());
    std::printf("written: %s\n", a.profile_csv.c_str());
  }
  if (!a.theta_csv.empty()) {
    std::ostringstream os;
    os << "theta_deg,minimum_amplitude\n";
    for (const auto& [th, mm] : theta) os << th * kDeg << ',' << mm << '\n';
    io::write_file_atomic(a.theta_csv, os.str());
    std::printf("written: %s\n", a.theta_csv.c_str());
  }
  if (!a.svg_prefix.empty()) {
    io::PlotSpec p1;
    p1.title = "Received amplitude past a range edge (Liu et al. 2005, Fig. 13)";
    p1.xlabel = "footprint displacement x past the edge (mm)";
    p1.ylabel = "amplitude";
    io::PlotSeries sep{"s-q = " + format_value(e.separation * 1000) + " mm", {}, "#1f77b4", false};
    io::PlotSeries cx{"coaxial", {}, "#2ca02c", true};
    for (std::size_t i = 0; i < prof.size(); ++i) {
      sep.points.emplace_back(prof[i].first * 1000, prof[i].second);
      cx.points.emplace_back(prof_coax[i].first * 1000, prof_coax[i].second);
    }
    p1.series = {sep, cx};
    p1.hline = a.min_amplitude;
    p1.hline_label = "min detectable";
    io::write_file_atomic(a.svg_prefix + "_profile.svg", io::svg_line_plot(p1));
    io::PlotSpec p2;
    p2.title = "Minimum amplitude against transceiver angle (Fig. 18)";
    p2.xlabel = "transceiver separation angle theta (deg)";
    p2.ylabel = "minimum amplitude";
    io::PlotSeries t{"minimum over x", {}, "#1f77b4", false};
    for (const auto& [th, mm] : theta) t.points.emplace_back(th * kDeg, mm);
    p2.series = {t};
    p2.hline = a.min_amplitude;
    p2.hline_label = "min detectable";
    io::write_file_atomic(a.svg_prefix + "_theta.svg", io::svg_line_plot(p2));
    std::printf("written: %s_profile.svg, %s_theta.svg\n", a.svg_prefix.c_str(), a.svg_prefix.c_str());
  }
  return 0;
}

namespace {
/// clean-cloud looks for mixed pixels along the rays from one viewpoint. A cloud that carries its
/// measured `range` (pcd_pipeline's returns.pcd and cloud.pcd) says where it was seen from: when
/// the distance to the viewpoint differs from `range` by more than max(0.1 m, 2 %) for more than
/// half of the points, the cloud was not measured from there (a cloud merged from a moving scanner
/// was measured from many places) and is refused instead of being cut along wrong rays.
void check_clean_cloud_viewpoint(const CleanCloudArgs& a, const io::PcdTable& t, const std::vector<Eigen::Vector3d>& pts,
                                 const Eigen::Vector3d& vp) {
  const int ir = t.header.field_index("range");
  if (ir < 0) return;
  const auto& f = t.header.fields[static_cast<std::size_t>(ir)];
  std::size_t used = 0, off = 0;
  std::vector<double> diff;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double r = io::field_value(f, t.columns[static_cast<std::size_t>(ir)].data() + i * f.bytes());
    if (!std::isfinite(r) || r <= 0 || !pts[i].allFinite()) continue;
    ++used;
    const double d = std::abs((pts[i] - vp).norm() - r);
    diff.push_back(d);
    if (d > std::max(0.1, 0.02 * r)) ++off;
  }
  if (used == 0 || 2 * off <= used) return;
  std::nth_element(diff.begin(), diff.begin() + static_cast<long>(diff.size() / 2), diff.end());
  char med[32];
  std::snprintf(med, sizeof med, "%.3g", diff[diff.size() / 2]);
  throw ConfigError(a.input + ": the points were not measured from the viewpoint " + std::to_string(vp.x()) + "," +
                    std::to_string(vp.y()) + "," + std::to_string(vp.z()) + (a.viewpoint.empty() ? " (the PCD VIEWPOINT)" : " (--viewpoint)") +
                    ": for " + std::to_string(off) + " of " + std::to_string(used) +
                    " points the distance to it differs from their field 'range' by more than max(0.1 m, 2 %) (median " + med +
                    " m). clean-cloud needs the one position every point was measured from; a cloud merged from a moving "
                    "scanner (pcd_pipeline's cloud.pcd and returns.pcd) has none: remove mixed pixels in the pipeline "
                    "(stage reject_mixed_pixels), or pass --viewpoint where a static scanner stood");
}

/// `--orientation` as a rotation, or none when not given (ConfigError, exit 2, when malformed:
/// checked before any file is read).
std::optional<Eigen::Quaterniond> clean_cloud_orientation_option(const CleanCloudArgs& a) {
  if (a.orientation.empty()) return std::nullopt;
  std::vector<double> v;
  const auto err = parse_number_list(a.orientation, 4, v);
  double norm = 0;
  const auto rot = err ? std::nullopt : unit_quaternion(v[0], v[1], v[2], v[3], &norm);
  if (!rot)
    throw ConfigError("clean-cloud: --orientation '" + a.orientation + "' must be a quaternion qw,qx,qy,qz of finite numbers "
                      "whose norm is at least 1e-9 (it " + (err ? *err : "has norm " + format_value(norm)) + ")");
  return *rot;
}

/// The scanner's frame in the cloud's (x forward, y left, z up, the scan plane x-y at nod 0):
/// `--orientation`, else the PCD VIEWPOINT's rotation (qw qx qy qz). It gives each point its
/// bearing and nod (organized) or its azimuth and elevation in the range image (unorganized).
/// 1 0 0 0, the PCD default, is a scanner whose z is the cloud's z.
Eigen::Quaterniond clean_cloud_orientation(const CleanCloudArgs& a, const io::PcdHeader& h,
                                           const std::optional<Eigen::Quaterniond>& option) {
  if (option) return *option;
  const double* q = h.viewpoint;
  double norm = 0;
  const auto rot = unit_quaternion(q[3], q[4], q[5], q[6], &norm);
  if (!rot)
    throw InputError(a.input + ": VIEWPOINT's rotation (qw qx qy qz = " + format_value(q[3]) + " " + format_value(q[4]) + " " +
                     format_value(q[5]) + " " + format_value(q[6]) + ", norm " + format_value(norm) +
                     ") is not a rotation (a norm of zero, below 1e-9 or not finite gives no direction): it must be the "
                     "scanner's orientation in the cloud's frame (1 0 0 0 for the same), or pass --orientation qw,qx,qy,qz");
  return *rot;
}

/// An organized PCD (HEIGHT > 1) is a scan in order: row k is scan line k, column b beam b (a
/// nodding 2-D scanner stores one line per row), as the PCL filter MixedPixelRemoval reads it
/// (pcdp/core/cloud_pass.hpp). The stage then runs as in a pipeline, along the lines and across
/// them. The sensor is unknown: transceiver separation 0 (the amplitude test both ways), the
/// default divergence (4 mrad) and a SICK's range sigma, as the PCL filter. The points enter
/// relative to the viewpoint, so float32 keeps their ranges exact in georeferenced coordinates.
std::vector<char> mixed_pixels_in_organized_pcd(const io::PcdHeader& h, const std::vector<Eigen::Vector3d>& pts,
                                                const std::vector<float>& amp, const Eigen::Vector3d& vp,
                                                const Eigen::Quaterniond& rot) {
  CartesianCloud c;
  c.width = static_cast<std::size_t>(h.width);
  c.height = static_cast<std::size_t>(h.height);
  c.points.resize(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) c.points[i] = (pts[i] - vp).cast<float>();
  c.intensity = amp;
  c.origin = Eigen::Vector3d::Zero();
  c.orientation = rot;
  Pass pass = pass_from_cloud(c);
  SensorParams s;
  s.range_sigma = 0.0053;
  s.transceiver_separation = 0.0;
  reject_mixed_pixels(pass, MixedPixelParams{}, s);
  std::vector<char> mixed(pts.size(), 0);
  for (std::size_t i = 0; i < pts.size(); ++i) mixed[i] = pass.label[i] == Label::kMixedPixel;
  return mixed;
}
}  // namespace

int cmd_clean_cloud(const CleanCloudArgs& a) {
  if (a.output.empty()) throw ConfigError("clean-cloud: --output is required");
  if (!(a.resolution > 0.0 && a.resolution < 0.5)) throw ConfigError("clean-cloud: --resolution must be in (0, 0.5) rad");
  // The options' numbers are checked before any file is read (exit 2).
  const std::optional<Eigen::Quaterniond> orientation_option = clean_cloud_orientation_option(a);
  std::optional<Eigen::Vector3d> viewpoint_option;
  if (!a.viewpoint.empty()) {
    std::vector<double> v;
    if (const auto err = parse_number_list(a.viewpoint, 3, v))
      throw ConfigError("clean-cloud: --viewpoint '" + a.viewpoint + "' must be x,y,z in metres (it " + *err + ")");
    viewpoint_option = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  const io::CloudFormat out_fmt = io::cloud_format_of(a.output, "clean-cloud --output");
  const io::CloudFormat removed_fmt = a.removed.empty() ? out_fmt : io::cloud_format_of(a.removed, "clean-cloud --removed");
  check_not_input("clean-cloud --output", a.output, {a.input});
  if (!a.removed.empty()) check_not_input("clean-cloud --removed", a.removed, {a.input});
  io::StagedFiles staged;  // checked and locked before the work
  const std::string kept_tmp = staged.add("clean-cloud --output", a.output);
  const std::string removed_tmp = a.removed.empty() ? std::string() : staged.add("clean-cloud --removed", a.removed);
  io::PcdTable t = io::read_pcd(a.input);
  const int ix = t.header.field_index("x"), iy = t.header.field_index("y"), iz = t.header.field_index("z");
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(a.input + ": needs fields x, y, z");
  Eigen::Vector3d vp(t.header.viewpoint[0], t.header.viewpoint[1], t.header.viewpoint[2]);
  if (viewpoint_option) vp = *viewpoint_option;
  const std::size_t n = t.header.points;
  const auto col = [&](int k, std::size_t i) {
    const auto& f = t.header.fields[static_cast<std::size_t>(k)];
    return io::field_value(f, t.columns[static_cast<std::size_t>(k)].data() + i * f.bytes());
  };
  std::vector<Eigen::Vector3d> pts(n);
  for (std::size_t i = 0; i < n; ++i) pts[i] = {col(ix, i), col(iy, i), col(iz, i)};
  std::vector<float> amp;
  for (const char* name : {"intensity", "amplitude"}) {
    const int k = t.header.field_index(name);
    if (k < 0 || !amp.empty()) continue;
    amp.resize(n);
    for (std::size_t i = 0; i < n; ++i) amp[i] = static_cast<float>(col(k, i));
  }
  check_clean_cloud_viewpoint(a, t, pts, vp);
  const Eigen::Quaterniond rot = clean_cloud_orientation(a, t.header, orientation_option);
  const bool organized = !a.unorganized && t.header.height > 1 && t.header.width > 1 && t.header.width * t.header.height == n;
  const std::vector<char> mixed =
      organized ? mixed_pixels_in_organized_pcd(t.header, pts, amp, vp, rot)
                : mixed_pixels_in_cloud(pts, vp, amp, a.resolution, MixedPixelParams{}, 0.0053, CloudAngles::kSpherical, rot);
  // Write kept (and removed) points, committed as a set: a PCD with every field of the input; PLY
  // and LAS with map coordinates (x y z + map_origin), the amplitude and the label when present.
  const int il = t.header.field_index("label");
  std::uint64_t not_in_las = 0;  // points write_las could not store (a non-finite coordinate)
  const auto write = [&](const std::string& tmp, bool want_mixed, io::CloudFormat fmt) {
    std::uint64_t count = 0;
    if (fmt != io::CloudFormat::kPcd) {
      io::CloudOut c;
      std::vector<std::size_t> source;  // the input point of each written one, to name it
      const Eigen::Vector3d origin(t.header.map_origin[0], t.header.map_origin[1], t.header.map_origin[2]);
      for (std::size_t i = 0; i < n; ++i) {
        if ((mixed[i] != 0) != want_mixed) continue;
        c.xyz.push_back(pts[i] + origin);
        source.push_back(i);
        if (!amp.empty()) c.intensity.push_back(amp[i]);
        if (il >= 0) c.label.push_back(static_cast<std::uint8_t>(std::clamp(col(il, i), 0.0, 255.0)));
      }
      if (fmt != io::CloudFormat::kLas) {
        io::write_ply(tmp, c);
      } else {
        try {
          not_in_las += c.xyz.size() - io::write_las(tmp, c);
        } catch (const io::LasSpanError& e) {  // a cloud wider than LAS holds: the input's stray points
          throw InputError(a.input + ": points " + std::to_string(source[e.first]) + " and " +
                           std::to_string(source[e.second]) + " lie " + format_value(e.span) + " m apart along " +
                           "xyz"[e.axis] + ": a LAS file (millimetres as 32-bit integers) spans at most 4,294 km; "
                           "remove the stray points or write PCD or PLY");
        }
      }
      return static_cast<std::uint64_t>(c.xyz.size());
    }
    {
      io::PcdWriter w(tmp, t.header.fields);
      w.set_map_origin(t.header.map_origin[0], t.header.map_origin[1], t.header.map_origin[2]);  // x y z stay relative to it
      w.set_viewpoint({vp.x(), vp.y(), vp.z(), rot.w(), rot.x(), rot.y(), rot.z()});  // the pose the cloud was cleaned with
      std::vector<std::uint8_t> row(w.point_bytes());
      for (std::size_t i = 0; i < n; ++i) {
        if ((mixed[i] != 0) != want_mixed) continue;
        std::size_t off = 0;
        for (std::size_t f = 0; f < t.header.fields.size(); ++f) {
          const std::size_t b = t.header.fields[f].bytes();
          std::memcpy(row.data() + off, t.columns[f].data() + i * b, b);
          off += b;
        }
        w.append(row.data(), 1);
        ++count;
      }
      w.close();
    }
    return count;
  };
  const std::uint64_t kept = write(kept_tmp, false, out_fmt);
  const std::uint64_t removed = a.removed.empty() ? n - kept : write(removed_tmp, true, removed_fmt);
  staged.commit();
  if (not_in_las > 0)
    std::fprintf(stderr, "note: %llu point(s) with a non-finite coordinate are not in the LAS output (LAS has no \"no point\")\n",
                 static_cast<unsigned long long>(not_in_las));
  if (!a.quiet) {
    char how[96];
    if (organized)
      std::snprintf(how, sizeof how, "organized, %llu lines of %llu beams%s", static_cast<unsigned long long>(t.header.height),
                    static_cast<unsigned long long>(t.header.width), a.resolution_given ? "; --resolution not used" : "");
    else
      std::snprintf(how, sizeof how, "resolution %g rad", a.resolution);
    std::printf("%s: %zu points, %llu mixed pixels removed (viewpoint %g %g %g, orientation %g %g %g %g, %s) -> %s\n",
                a.input.c_str(), n, static_cast<unsigned long long>(removed), vp.x(), vp.y(), vp.z(), rot.w(), rot.x(), rot.y(),
                rot.z(), how, a.output.c_str());
  }
  return 0;
}

int cmd_calibrate_range(const std::string& csv) {
  std::vector<double> y, z;
  io::read_range_samples_csv(csv, y, z);
  RangeCalibration c;
  try {
    c = fit_range_calibration(y, z);
  } catch (const InputError& e) {
    throw InputError(csv + ": " + e.what());
  }
  // What is printed must be pasteable: the sensor block's bounds (config_blocks.cpp) hold k and b.
  if (!(c.k > 0.5 && c.k <= 2.0) || !(c.b >= -1.0 && c.b <= 1.0))
    throw InputError(csv + ": the samples give k = " + format_value(c.k) + ", b = " + format_value(c.b) +
                     " m, outside the sensor block's range_calibration bounds (0.5 < k <= 2, -1 <= b <= 1 m): are the "
                     "columns 'true' and 'measured' right, in metres, and from one scanner?");
  std::printf("range calibration (Ye & Borenstein eqs. 1-3): true = k * measured + b\n");
  std::printf("  k = %.6f  (standard error %.6f)\n  b = %.5f m  (standard error %.5f m)\n", c.k, c.se_k, c.b, c.se_b);
  std::printf("  %zu samples at %zu distances; residuals of the per-distance means: rms %.2f mm, max %.2f mm\n", c.samples,
              c.distances, c.rms * 1000, c.max_abs * 1000);
  std::printf("\npaste into the sensor block:\n  range_calibration: {k: %.6f, b: %.5f}\n", c.k, c.b);
  return 0;
}

int cmd_calibrate_mount(const RunArgs& a, const std::vector<std::string>& scans) {
  LoadOptions o;
  for (const auto& s : a.sets) o.overrides.push_back(parse_override(s));
  const PipelineConfig cfg = load_pipeline(a.pipeline, o);
  const std::vector<std::string> files = scans.empty() ? cfg.scans : scans;
  // Points in the nod frame: register with an identity mount and no pose (skew correction,
  // range calibration and range limits as configured).
  std::vector<Eigen::Vector3d> pts;
  RegisterParams rp;
  rp.covariance = false;
  for (std::size_t k = 0; k < files.size(); ++k) {
    Pass p = read_pass(files[k], k);
    register_pass(p, rp, cfg.sensor, Eigen::Isometry3d::Identity(), nullptr);
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p.is_kept(i)) pts.emplace_back(p.x[i], p.y[i], p.z[i]);
  }
  const Eigen::Vector3d up_N = rpy_to_matrix(cfg.mount.rpy, cfg.rpy_order).transpose() * Eigen::Vector3d::UnitZ();
  const MountCalibration m = calibrate_mount(pts, cfg.mount.rpy.yaw, cfg.rpy_order, up_N);
  constexpr double kDeg = 57.29577951308232;
  std::printf("mount calibration from a flat floor (Broten & Collier 7.4), rpy_order %s:\n", rpy_order_name(cfg.rpy_order));
  std::printf("  pitch %.5f rad (%.3f deg), roll %.5f rad (%.3f deg), height %.4f m (yaw kept at %.5f rad)\n", m.rpy.pitch,
              m.rpy.pitch * kDeg, m.rpy.roll, m.rpy.roll * kDeg, m.height, m.rpy.yaw);
  std::printf("  floor plane: %zu of %zu returns within 3 cm, rms %.1f mm\n", m.inliers, m.points, m.rms * 1000);
  std::printf("\npaste into the pipeline (x, y and yaw are not observable from a floor; kept from %s):\n", a.pipeline.c_str());
  std::printf("mount: {x: %g, y: %g, z: %.4f, roll: %.5f, pitch: %.5f, yaw: %g}\n", cfg.mount.translation.x(),
              cfg.mount.translation.y(), m.height, m.rpy.roll, m.rpy.pitch, m.rpy.yaw);
  return 0;
}

int cmd_error_budget(const RunArgs& a, const std::string& svg, const std::string& csv) {
  LoadOptions o;
  o.check_inputs = false;  // the budget needs the sensor, mount and pose_sigma blocks only
  if (!svg.empty()) check_output_file("error-budget --svg", svg, {".svg"}, {a.pipeline});
  if (!csv.empty()) check_output_file("error-budget --csv", csv, {".csv"}, {a.pipeline});
  for (const auto& s : a.sets) o.overrides.push_back(parse_override(s));
  const PipelineConfig cfg = load_pipeline(a.pipeline, o);
  const SensorParams& sn = cfg.sensor;
  const Eigen::Isometry3d T_V_N = make_transform(cfg.mount.translation, cfg.mount.rpy, cfg.rpy_order);
  constexpr double kRad = 0.017453292519943295;
  const double ranges[] = {1, 5, 10, 15, 20, 25, 30};
  std::ostringstream table;
  std::printf("3-D position error from an orientation error d_eps in roll, pitch and yaw: sqrt(2) r d_eps (m)\n");
  std::printf("(Broten & Collier 6.3.3, Fig. 22; their Table 1 lists sqrt(2 r d_eps) instead, e.g. 0.19 m at 1 m, 1 deg)\n");
  std::printf("%8s", "range m");
  for (int d = 1; d <= 6; ++d) std::printf("%9d deg", d);
  std::printf("\n");
  table << "range_m";
  for (int d = 1; d <= 6; ++d) table << ",bc_" << d << "deg_m";
  table << ",range_sigma_m,bearing_m,encoder_m,pose_position_m,pose_rpy_m,total_m\n";
  for (double r : ranges) {
    std::printf("%8.0f", r);
    for (int d = 1; d <= 6; ++d) std::printf("%13.3f", broten_collier_orientation_error(r, d * kRad));
    std::printf("\n");
  }
  // The user's sensor: each source alone and together, for a beam straight ahead at nod 0.
  PointSigmas all;
  all.range = sn.range_k * sn.range_sigma;
  all.bearing = quantization_sigma(sn.bearing_resolution);
  all.nod = quantization_sigma(sn.encoder_resolution);
  all.position = Eigen::Vector3d::Constant(cfg.pose_sigma.position);
  all.rpy = Eigen::Vector3d::Constant(cfg.pose_sigma.rpy);
  const auto only = [&](int which) {
    PointSigmas s;
    if (which == 0) s.range = all.range;
    if (which == 1) s.bearing = all.bearing;
    if (which == 2) s.nod = all.nod;
    if (which == 3) s.position = all.position;
    if (which == 4) s.rpy = all.rpy;
    return which == 5 ? all : s;
  };
  std::printf("\nyour sensor (%s): 1-sigma 3-D error of a point straight ahead, by source (mm)\n", a.pipeline.c_str());
  std::printf("%8s %10s %10s %10s %12s %10s %10s\n", "range m", "range", "bearing", "encoder", "position", "rpy", "total");
  // The user's curve: drawn last (on top), solid black and thicker than the formula's, with its
  // value at 30 m beside its end; the log axis keeps millimetres readable beside metres.
  io::PlotSeries user{"your sensor (1 sigma)", {}, "#000000", false};
  user.width = 3.5;
  for (double r : ranges) {
    double e[6];
    for (int k = 0; k < 6; ++k)
      e[k] = std::sqrt(point_covariance(r, 0.0, 0.0, T_V_N, {}, cfg.rpy_order, only(k)).trace());
    std::printf("%8.0f %10.1f %10.1f %10.1f %12.1f %10.1f %10.1f\n", r, e[0] * 1000, e[1] * 1000, e[2] * 1000, e[3] * 1000,
                e[4] * 1000, e[5] * 1000);
    table << r;
    for (int d = 1; d <= 6; ++d) table << ',' << broten_collier_orientation_error(r, d * kRad);
    for (int k = 0; k < 6; ++k) table << ',' << e[k];
    table << '\n';
  }
  if (!csv.empty()) {
    io::write_file_atomic(csv, table.str());
    std::printf("written: %s\n", csv.c_str());
  }
  if (!svg.empty()) {
    io::PlotSpec spec;
    spec.title = "Position error against range: orientation error (Broten & Collier Fig. 22) and your sensor";
    spec.xlabel = "range (m)";
    spec.ylabel = "3-D position error (m, log scale)";
    spec.log_y = true;
    const char* colors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"};
    for (int d = 1; d <= 6; ++d) {
      io::PlotSeries s{std::to_string(d) + " deg", {}, colors[d - 1], false};
      for (double r = 0.5; r <= 30.0; r += 0.5) s.points.emplace_back(r, broten_collier_orientation_error(r, d * kRad));
      spec.series.push_back(s);
    }
    for (double r = 0.5; r <= 30.0; r += 0.5)
      user.points.emplace_back(r, std::sqrt(point_covariance(r, 0.0, 0.0, T_V_N, {}, cfg.rpy_order, all).trace()));
    char note[64];
    std::snprintf(note, sizeof note, "%.0f mm at %.0f m", user.points.back().second * 1000, user.points.back().first);
    user.end_note = note;
    spec.series.push_back(user);
    io::write_file_atomic(svg, io::svg_line_plot(spec));
    std::printf("written: %s\n", svg.c_str());
  }
  return 0;
}

int cmd_merge(const std::vector<std::string>& inputs, const std::string& output, const std::string& png, unsigned threads) {
  if (inputs.size() < 2) throw ConfigError("merge: give two or more elevation grids to merge");
  {  // -o honours its extension: merge writes a GeoTIFF only
    const std::string ext = std::filesystem::path(output).extension().string();
    std::string low = ext;
    for (auto& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (low != ".tif" && low != ".tiff")
      throw ConfigError("merge --output '" + output + "': " + (ext.empty() ? "no extension" : "extension '" + ext + "'") +
                        "; merge writes a GeoTIFF: use .tif or .tiff");
  }
  {  // neither output may overwrite an input grid or its merge state
    std::vector<std::string> read = inputs;
    for (const auto& in : inputs) read.push_back(io::elevation_state_path(in));
    check_output_file("merge --output", output, {".tif", ".tiff"}, read);
    if (output.size() >= 10 && output.compare(output.size() - 10, 10, ".state.tif") == 0)
      throw ConfigError("merge --output '" + output + "': a .state.tif name is the merge state beside a grid, not a grid");
    if (!png.empty()) check_output_file("merge --png", png, {".png"}, read);
  }
  io::check_distinct_grids(inputs);  // the same grid twice would count its passes twice
  io::StagedFiles staged;  // checked and locked before the work; the .tif and the PNG committed as a set
  const std::string tif_tmp = staged.add("merge --output", output);
  const std::string state_tmp = staged.add("merge --output (its merge state)", io::elevation_state_path(output));
  const std::string png_tmp = png.empty() ? std::string() : staged.add("merge --png", png);
  // One CRS for all (checked before any cell is read); the merged grid keeps it.
  const std::string crs = io::elevation_geotiff_crs(inputs[0]);
  for (std::size_t k = 1; k < inputs.size(); ++k)
    if (const std::string other = io::elevation_geotiff_crs(inputs[k]); other != crs)
      throw InputError("merge: '" + inputs[0] + "' is in " + (crs.empty() ? "no CRS" : crs) + " and '" + inputs[k] +
                       "' in " + (other.empty() ? "no CRS" : other) + ": grids merge only in the same CRS");
  // The first grid sets the grid; the others are read into it a strip of rows at a time.
  ElevationGrid grid = io::read_elevation_geotiff(inputs[0]);
  for (std::size_t k = 1; k < inputs.size(); ++k) io::merge_elevation_geotiff(grid, inputs[k], inputs[0]);
  // The GeoTIFF's bands are compressed on `threads` threads; the file is the same whatever the count.
  const auto share = WorkShare::threads(threads_or_cores(threads));
  io::write_elevation_geotiff(grid, tif_tmp, 1, *share, crs, state_tmp);
  if (!png.empty()) io::write_elevation_png(grid, png_tmp);
  staged.commit();
  std::printf("merged %zu grids -> %s (%zu cells)\n", inputs.size(), output.c_str(), grid.size());
  return 0;
}

int cmd_docs() {
  std::cout << "# Stage and block reference\n\n"
               "Generated from the option schemas by `pcd_pipeline docs > docs/stages.md`; a test fails when\n"
               "this file and the code disagree. The same schemas validate pipelines and drive\n"
               "`pcd_pipeline describe`.\n\n## Stages\n\n";
  for (const auto& s : builtin_stages())
    std::cout << "### `" << s.type << "`\n\n" << s.summary << "\n\n" << schema_markdown(s.schema) << "\n";
  std::cout << "## Pipeline blocks\n\n";
  const std::pair<const char*, const OptionSchema*> blocks[] = {
      {"sensor", &sensor_schema()}, {"mount", &mount_schema()}, {"pose_sigma", &pose_sigma_schema()},
      {"top_level", &top_level_schema()}};
  for (const auto& [name, sch] : blocks) std::cout << "### `" << name << "`\n\n" << schema_markdown(*sch) << "\n";
  std::cout << "## Scene blocks (`pcd_pipeline simulate`)\n\n";
  const std::pair<const char*, const OptionSchema*> scene[] = {
      {"scanner", &scanner_schema()}, {"motion", &motion_schema()}, {"terrain", &terrain_schema()}};
  for (const auto& [name, sch] : scene) std::cout << "### `" << name << "`\n\n" << schema_markdown(*sch) << "\n";
  return 0;
}

namespace {
/// Writes imported passes as OUT/pass_NNN.pcd (each atomically); returns the number of returns.
std::size_t write_passes(const std::vector<Pass>& passes, const std::string& out_dir) {
  std::size_t n = 0;
  for (std::size_t k = 0; k < passes.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "pass_%03zu.pcd", k);
    sim::write_pass_pcd(passes[k], (std::filesystem::path(out_dir) / name).string());
    n += passes[k].size();
  }
  return n;
}
}  // namespace

int cmd_import(const std::string& format, const std::vector<std::string>& inputs, const std::string& out_dir,
               const std::string& poses, const std::string& viewpoint, double max_residual, const std::string& nod_origin,
               std::size_t beams_per_line, double max_range, double unit_scale) {
  if (beams_per_line != 0 && format != "3dtk")
    throw ConfigError("import " + format + ": --beams-per-line is for 3dtk scans");
  if (format == "octomap" || format == "cloud") {
    const auto xyz = [&](const std::string& opt, const std::string& text) {
      Eigen::Vector3d v;
      char c1 = 0, c2 = 0;
      std::istringstream is(text);
      if (!(is >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !v.allFinite() || !(is >> std::ws).eof())
        throw ConfigError("import " + format + ": " + opt + " '" + text + "' must be x,y,z in metres");
      return v;
    };
    Eigen::Vector3d vp;
    const bool have_vp = !viewpoint.empty();
    if (have_vp) {
      if (format != "cloud") throw ConfigError("import octomap: --viewpoint is for clouds (scan poses come from the file)");
      vp = xyz("--viewpoint", viewpoint);
    }
    io::ImportOptions opt;
    opt.max_residual = max_residual;
    opt.auto_nod_origin = nod_origin == "auto";
    opt.max_range = max_range;
    opt.unit_scale = unit_scale;
    if (!nod_origin.empty() && !opt.auto_nod_origin) opt.nod_origin = xyz("--nod-origin", nod_origin);
    io::StagedOutputs staged(out_dir);  // locked and checked before the work; committed as a set
    own_pass_products(staged, out_dir, inputs);
    const io::ImportedScans r = format == "octomap" ? io::import_octomap(inputs, opt)
                                                    : io::import_cloud(inputs, have_vp ? &vp : nullptr, opt);
    const std::size_t n = write_passes(r.passes, staged.staging_dir());
    sim::write_pose_csv(r.poses, RpyOrder::kXyz, (std::filesystem::path(staged.staging_dir()) / "poses.csv").string());
    staged.commit();
    std::printf("imported %zu scan(s), %zu returns -> %s (pass_*.pcd, poses.csv; rpy_order xyz, mount identity, "
                "skew_correction: false)\n",
                r.passes.size(), n, out_dir.c_str());
    for (const auto& note : r.notes) std::printf("  %s\n", note.c_str());
    for (std::size_t k = 0; k < r.passes.size(); ++k) {
      const pcdp::LineRecovery& rec = r.recovery[k];
      std::printf("  %s: nod origin %.3f,%.3f,%.3f; %zu scan line(s)%s, rebuild error median %.2g m, largest %.2g m",
                  r.passes[k].source.c_str(), rec.nod_origin.x(), rec.nod_origin.y(), rec.nod_origin.z(), rec.lines,
                  rec.organized ? " on one beam grid (organized)" : "", rec.median_residual, rec.max_residual);
      if (rec.loose_points)
        std::printf("; %zu point(s) of %zu line(s) did not fit their line within %.3g m and were imported as lines of "
                    "their own%s",
                    rec.loose_points, rec.split_lines, max_residual,
                    2 * rec.loose_points > r.passes[k].size()
                        ? " (no scan-line order, as in airborne or map-frame clouds: each point is its own line, exact, "
                          "without scan-line neighbours)"
                    : rec.nod_origin.isZero() && nod_origin.empty() ? " (is the scan's origin on the nod axis? try --nod-origin auto)"
                                                                    : "");
      std::printf("\n");
    }
    return 0;
  }
  if (format == "rplidar" || format == "rosbag2") return cmd_import_tilt(format, inputs, out_dir, {});
  if (format != "3dtk")
    throw ConfigError("import: unknown format '" + format + "'" + did_you_mean(format, {"3dtk", "rplidar", "rosbag2", "octomap", "cloud", "carmen"}) +
                      "; formats: 3dtk, rplidar, rosbag2, octomap, cloud, carmen");
  if (poses != "odometry" && poses != "frames")
    throw ConfigError("import 3dtk: --poses must be odometry or frames, not '" + poses + "'");
  io::StagedOutputs staged(out_dir);
  own_pass_products(staged, out_dir, inputs);
  const io::Imported3dtk r = io::import_3dtk(inputs, poses == "frames", beams_per_line);
  const std::size_t n = write_passes(r.passes, staged.staging_dir());
  sim::write_pose_csv(r.poses, RpyOrder::kXyz, (std::filesystem::path(staged.staging_dir()) / "poses.csv").string());
  staged.commit();
  std::printf("imported %zu 3DTK scan(s), %zu returns, %s poses -> %s (pass_*.pcd, poses.csv; rpy_order xyz)\n",
              r.passes.size(), n, poses.c_str(), out_dir.c_str());
  return 0;
}

int cmd_import_tilt(const std::string& format, const std::vector<std::string>& inputs, const std::string& out_dir,
                    const io::Rosbag2ImportParams& p) {
  if (inputs.size() != 1)
    throw ConfigError("import " + format + ": expected one " +
                      (format == "rplidar" ? "folder (with scans.csv, beams.csv, servo.csv)"
                                           : "bag (a folder with metadata.yaml and .db3 files, or a .db3 file)") +
                      ", got " + std::to_string(inputs.size()) + " inputs");
  if (format == "rplidar" && !(p.scan_topic.empty() && p.tilt_topic.empty() && p.odom_topic.empty() && p.tf_frames.empty()))
    throw ConfigError("import rplidar: --scan-topic, --tilt-topic, --odom-topic and --tf-frames are for rosbag2");
  io::StagedOutputs staged(out_dir);
  own_pass_products(staged, out_dir, inputs);
  io::ImportedRosbag2 b;
  if (format == "rplidar")
    b.passes = io::import_rplidar(inputs[0], p.passes);
  else
    b = io::import_rosbag2(inputs[0], p);
  const io::ImportedRplidar& r = b.passes;
  write_passes(r.passes, staged.staging_dir());
  if (!b.poses.empty())
    sim::write_pose_csv(b.poses, RpyOrder::kXyz, (std::filesystem::path(staged.staging_dir()) / "poses.csv").string());
  staged.commit();
  if (format == "rosbag2") {
    std::string poses = "none";
    if (!b.odom_topic.empty()) poses = b.odom_topic + " (" + std::to_string(b.poses.size()) + ")";
    if (!b.tf_frames.empty())
      poses = "tf " + b.tf_frames + " (" + std::to_string(b.poses.size()) + "; " + b.tf_chain + ")";
    std::printf("topics: scans %s, tilt %s (%s, %zu readings), poses %s\n", b.scan_topic.c_str(), b.tilt_topic.c_str(),
                b.tilt_type.c_str(), b.tilt_messages, poses.c_str());
  }
  std::printf("imported %zu LaserScan(s) (%zu dropped: empty or outside the tilt stream), %zu returns in %zu pass(es) "
              "-> %s (pass_*.pcd; %s)\n",
              r.scans, r.dropped_scans, r.beams, r.passes.size(), out_dir.c_str(),
              b.poses.empty() ? "no pose file: T_M_V = identity" : "poses.csv, rpy_order xyz");
  const io::TiltGeometry& g = p.passes.geometry;
  std::printf("tilt: nod = %g * %g deg * (reading - %g); the laser is %g m above the tilt axis: put mount z: %g in the "
              "pipeline\n",
              -g.sign, g.scale, g.zero, g.axis_offset, g.axis_offset);
  return 0;
}

int cmd_import_carmen(const std::vector<std::string>& inputs, const std::string& out_dir) {
  if (inputs.size() != 1)
    throw ConfigError("import carmen: expected one log (.log or .log.gz), got " + std::to_string(inputs.size()) + " inputs");
  io::StagedOutputs staged(out_dir);
  own_pass_products(staged, out_dir, inputs);
  const io::ImportedCarmen r = io::import_carmen(inputs[0]);
  // One pass per message: enough digits that the files sort in time order.
  const std::size_t digits = std::max<std::size_t>(3, std::to_string(r.passes.size() - 1).size());
  std::size_t n = 0;
  for (std::size_t k = 0; k < r.passes.size(); ++k) {
    const std::string num = std::to_string(k);
    const std::string name = "pass_" + std::string(digits - num.size(), '0') + num + ".pcd";
    sim::write_pass_pcd(r.passes[k], (std::filesystem::path(staged.staging_dir()) / name).string());
    n += r.passes[k].size();
  }
  sim::write_pose_csv(r.poses, RpyOrder::kXyz, (std::filesystem::path(staged.staging_dir()) / "poses.csv").string());
  staged.commit();
  std::printf("imported %zu %s message(s) as planar passes, %zu returns (%zu at or beyond the maximum range: no return) "
              "-> %s (pass_*.pcd, poses.csv: the laser poses; rpy_order xyz, mount identity)\n",
              r.passes.size(), r.message.c_str(), n, r.max_range_readings, out_dir.c_str());
  if (r.message == "FLASER") std::printf("  FLASER maximum range %.2f m\n", r.max_range);
  if (r.skipped_flaser)
    std::printf("  %zu FLASER message(s) skipped: the log has ROBOTLASER1 messages of the same scans\n", r.skipped_flaser);
  if (r.reordered) std::printf("  %zu message(s) earlier than the one before them: passes are in time order\n", r.reordered);
  return 0;
}

int cmd_describe(const std::string& what) {
  const std::vector<std::pair<std::string, const OptionSchema*>> blocks = {
      {"sensor", &sensor_schema()},   {"mount", &mount_schema()},   {"pose_sigma", &pose_sigma_schema()},
      {"scanner", &scanner_schema()}, {"motion", &motion_schema()}, {"terrain", &terrain_schema()},
      {"top_level", &top_level_schema()}};
  for (const auto& [name, sch] : blocks)
    if (what == name) {
      std::cout << what << " block\n\n" << describe_schema(*sch);
      return 0;
    }
  const StageInfo* info = find_stage(what);
  if (!info) {
    auto names = stage_type_names();
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    for (const auto& b : blocks) names.push_back(b.first);
    throw ConfigError("describe: unknown stage '" + what + "'" + did_you_mean(what, names) + "; stages: " + list +
                      "; blocks: sensor, mount, pose_sigma, top_level (pipelines), scanner, motion, terrain (scenes)");
  }
  std::cout << info->type << ": " << info->summary << "\n\n" << describe_schema(info->schema);
  return 0;
}

}  // namespace pcdp::cli
