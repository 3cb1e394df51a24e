// pcd_pipeline: the command-line edge. Parses arguments, calls a command, maps errors to exit codes
// (0 ok, 1 internal error, 2 invalid configuration, 3 input data error, 4 an output cannot be written).
#include <CLI/CLI.hpp>
#include <iostream>
#include <new>
#include <system_error>

#include "bench.hpp"
#include "commands.hpp"
#include "shard.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/models/nod_plan.hpp"
#include "pcdp/models/occlusion_model.hpp"

namespace {
constexpr const char* kOutOfMemory =
    "error: out of memory: the inputs need more memory than this machine can give "
    "(split the run into fewer passes per run, or use a coarser resolution)\n";
}  // namespace

int main(int argc, char** argv) {
  using namespace pcdp;
  CLI::App app{"pcd_pipeline: nodding-laser scans to clean, registered point clouds and terrain maps"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("pcd_pipeline ") + PCDP_VERSION_STRING);
  // Output paths: not empty, no control character (a newline would name another file).
  const CLI::Validator output_path(
      [](std::string& p) {
        if (p.empty()) return std::string("the output path is empty");
        for (unsigned char c : p)
          if (c < 0x20 || c == 0x7f) return std::string("the output path contains a control character");
        return std::string();
      },
      "PATH");

  cli::RunArgs run_args;
  auto add_run_options = [&](CLI::App* c) {
    c->add_option("pipeline", run_args.pipeline, "pipeline YAML file")->required();
    c->add_option("--set", run_args.sets, "override a key: --set sensor.min_amplitude=20 (repeatable)");
    c->add_option("--output-dir", run_args.output_dir, "output folder (wins over output_dir in the file)")->check(output_path);
    c->add_flag("-q,--quiet", run_args.quiet, "print nothing but errors");
  };
  CLI::App* run = app.add_subcommand("run", "run a pipeline: read passes, run the stages, write the outputs");
  add_run_options(run);
  run->add_option("-j,--threads", run_args.threads,
                   "worker threads (0: one per core); the outputs are identical whatever the count")
      ->check(CLI::Range(0, 256));
  CLI::App* validate = app.add_subcommand("validate", "load and check a pipeline; reads no scan");
  add_run_options(validate);
  CLI::App* stages = app.add_subcommand("stages", "list the built-in stages");
  std::string describe_what;
  CLI::App* describe = app.add_subcommand("describe", "print the option schema of a stage (or of sensor, mount, pose_sigma, top_level)");
  describe->add_option("stage", describe_what, "stage type or block name")->required();

  std::string scene, sim_out;
  bool sim_quiet = false;
  CLI::App* simulate = app.add_subcommand("simulate", "simulate a nodding scanner in a scene: passes, poses and ground truth");
  simulate->add_option("scene", scene, "scene YAML file")->required();
  simulate->add_option("--output-dir", sim_out, "output folder")->required()->check(output_path);
  simulate->add_flag("-q,--quiet", sim_quiet, "print nothing but errors");

  std::string ev_truth, ev_run, ev_json;
  bool ev_quiet = false;
  CLI::App* evaluate = app.add_subcommand("evaluate", "score a run against simulator ground truth");
  evaluate->add_option("--truth", ev_truth, "folder written by `simulate` (holds truth/)")->required();
  evaluate->add_option("--run", ev_run, "output folder of a run (holds returns.pcd)")->required();
  evaluate->add_option("--json", ev_json, "where to write the scores (default: RUN/evaluation.json)")->check(output_path);
  evaluate->add_flag("-q,--quiet", ev_quiet, "print nothing but errors");

  NodPlanParams np;
  std::string np_csv;
  CLI::App* plan = app.add_subcommand("plan-nod", "nodding profile for a mount (Broten & Collier 4-5): where a uniform sample distance is achievable");
  plan->add_option("--height", np.height, "laser height above the ground, m")->capture_default_str();
  plan->add_option("--sample-distance", np.sample_distance, "desired ground distance between lines, m")->capture_default_str();
  plan->add_option("--speed", np.speed, "vehicle speed, m/s")->capture_default_str();
  plan->add_option("--sweep-period", np.sweep_period, "time of one scan line, s")->capture_default_str();
  plan->add_option("--dead-zone-time", np.dead_zone_time, "stopping distance = speed x this, s (0: none)")->capture_default_str();
  plan->add_option("--encoder-resolution", np.encoder_resolution, "rad")->capture_default_str();
  plan->add_option("--max-rate", np.max_rate, "maximum nod rate, rad/s")->capture_default_str();
  plan->add_option("--rate", np.rate, "constant-rate profile: nod rate, rad/s (for its sample-distance column)")->capture_default_str();
  plan->add_option("--csv", np_csv, "also write the table as CSV")->check(output_path);

  EdgeParams edge;  // defaults: Liu et al. Fig. 13
  cli::AmplitudeModelArgs am;
  CLI::App* amp = app.add_subcommand("amplitude-model", "received amplitude past a range edge for a non-coaxial sensor (Liu et al. 2005)");
  amp->add_option("--d1", edge.d1, "near target range, m")->capture_default_str();
  amp->add_option("--d2", edge.d2, "far target range, m")->capture_default_str();
  amp->add_option("--p1", edge.p1, "amplitude of the near target fully lit")->capture_default_str();
  amp->add_option("--p2", edge.p2, "amplitude of the far target fully lit")->capture_default_str();
  amp->add_option("--alpha", edge.alpha, "full beam divergence, rad")->capture_default_str();
  amp->add_option("--separation", edge.separation, "transmitter-receiver separation s - q, m")->capture_default_str();
  amp->add_option("--theta", edge.theta, "transceiver separation angle, rad")->capture_default_str();
  amp->add_option("--min-amplitude", am.min_amplitude, "minimum detectable amplitude")->capture_default_str();
  amp->add_option("--points", am.points, "samples of the profile")->capture_default_str();
  amp->add_option("--profile-csv", am.profile_csv, "write the profile (x, amplitude, coaxial amplitude) as CSV")->check(output_path);
  amp->add_option("--theta-csv", am.theta_csv, "write the minimum against theta as CSV")->check(output_path);
  amp->add_option("--svg", am.svg_prefix, "draw PREFIX_profile.svg and PREFIX_theta.svg")->check(output_path);

  cli::CleanCloudArgs cc;
  CLI::App* clean = app.add_subcommand("clean-cloud", "remove mixed pixels from a Cartesian cloud seen from one viewpoint");
  clean->add_option("input", cc.input, "PCD with x y z (intensity or amplitude used if present)")->required();
  clean->add_option("-o,--output", cc.output, "cleaned cloud (all input fields)")->required()->check(output_path);
  clean->add_option("--removed", cc.removed, "also write the removed points here")->check(output_path);
  clean->add_option("--viewpoint", cc.viewpoint, "sensor position x,y,z in the cloud's frame (default: the PCD VIEWPOINT)");
  clean->add_option("--orientation", cc.orientation,
                    "scanner frame (x forward, y left, z up) in the cloud's, as a quaternion qw,qx,qy,qz (default: the PCD VIEWPOINT's)");
  auto* clean_res = clean->add_option("--resolution", cc.resolution, "angular step of the scan, rad (unorganized clouds; an organized PCD, HEIGHT > 1 and WIDTH > 1, is read as lines of beams unless --unorganized)")->capture_default_str();
  clean->add_flag("--unorganized", cc.unorganized,
                  "read an organized PCD as an unorganized cloud (its rows are not the lines of a 2-D scanner: a range camera, a spinning lidar)");
  clean->add_flag("-q,--quiet", cc.quiet, "print nothing but errors");

  std::string cr_csv;
  CLI::App* calr = app.add_subcommand("calibrate-range", "fit the linear range calibration k, b (Ye & Borenstein eqs. 1-3)");
  calr->add_option("csv", cr_csv, "CSV with columns true,measured (m); many samples per distance allowed")->required();
  cli::RunArgs cm_args;
  std::vector<std::string> cm_scans;
  CLI::App* calm = app.add_subcommand("calibrate-mount", "estimate mount pitch, roll and height from a scan of a flat floor");
  calm->add_option("pipeline", cm_args.pipeline, "pipeline YAML (sensor block, mount x/y/yaw, rpy_order, input.scans)")->required();
  calm->add_option("--scan", cm_scans, "pass files of the floor scan (default: the pipeline's input.scans)");
  calm->add_option("--set", cm_args.sets, "override a key (as for run)");
  cli::RunArgs eb_args;
  std::string eb_svg, eb_csv;
  CLI::App* ebud = app.add_subcommand("error-budget", "positional error against range and orientation error, for a sensor block");
  ebud->add_option("pipeline", eb_args.pipeline, "pipeline YAML (sensor block, mount, pose_sigma)")->required();
  ebud->add_option("--set", eb_args.sets, "override a key (as for run)");
  ebud->add_option("--svg", eb_svg, "draw the picture (Broten & Collier Fig. 22 analogue)")->check(output_path);
  ebud->add_option("--csv", eb_csv, "write the table as CSV")->check(output_path);

  std::vector<std::string> mg_in;
  std::string mg_out, mg_png;
  CLI::App* mrg = app.add_subcommand("merge", "merge elevation grids fused from disjoint sets of passes (exact, any order)");
  mrg->add_option("grids", mg_in, "elevation.tif files written by fuse_elevation or merge (each read from its .state.tif beside it)")->required();
  mrg->add_option("-o,--output", mg_out, "merged GeoTIFF (its merge state goes beside it, NAME.state.tif)")->required()->check(output_path);
  mrg->add_option("--png", mg_png, "also draw the merged picture")->check(output_path);
  unsigned mg_threads = 0;
  mrg->add_option("-j,--threads", mg_threads, "threads compressing the GeoTIFF (0: one per core); the file is the same whatever the count")
      ->check(CLI::Range(0, 256));

  std::string imp_format, imp_out, imp_poses = "odometry";
  std::vector<std::string> imp_in;
  std::string imp_viewpoint, imp_nod_origin;
  double imp_residual = 0.02, imp_max_range = 1000.0, imp_unit_scale = 0.0;
  std::size_t imp_beams = 0;
  io::Rosbag2ImportParams imp_tilt;  // rplidar, rosbag2
  int imp_sign = -1;
  CLI::App* imp = app.add_subcommand("import", "convert scans of other tools to raw passes and a pose file (formats: 3dtk, rplidar, rosbag2, octomap, cloud, carmen)");
  imp->add_option("format", imp_format,
                  "3dtk: 3DTK uos scans (.3d with .pose/.frames beside them); rplidar: a folder of scans/beams/servo CSV; rosbag2: a ROS 2 bag (sqlite3) of LaserScan + tilt; "
                  "octomap: scan.dat (ASCII, NODE lines) or .graph (ScanGraph); cloud: Cartesian .pcd, .ply or .las with a viewpoint; "
                  "carmen: a CARMEN log (.log or .log.gz) of FLASER / ROBOTLASER1 messages, one planar pass per message")
      ->required();
  imp->add_option("inputs", imp_in, "input files")->required();
  imp->add_option("--output-dir", imp_out, "folder for pass_*.pcd and poses.csv")->required()->check(output_path);
  imp->add_option("--poses", imp_poses, "3dtk: odometry (.pose) or frames (slam6D's registered .frames)")->capture_default_str();
  imp->add_option("--viewpoint", imp_viewpoint, "cloud: sensor position x,y,z in the cloud frame, LAS after --unit-scale (default: the PCD VIEWPOINT; PLY, LAS: 0,0,0)");
  imp->add_option("--max-range", imp_max_range,
                  "cloud: the sensor's maximum range, m; a viewpoint farther than this from half of the points is refused")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 1e7));
  imp->add_option("--unit-scale", imp_unit_scale,
                  "cloud: metres per LAS file unit (0.3048 for feet); 0: the unit the file's CRS declares, else 1")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  imp->add_option("--nod-origin", imp_nod_origin,
                  "octomap, cloud: the nod axis origin x,y,z in the scan frame, or 'auto' to estimate it (default 0,0,0)");
  imp->add_option("--max-residual", imp_residual, "octomap, cloud: m; a scan line whose points do not rebuild within this is imported point by point")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 1.0));
  imp->add_option("--scan-topic", imp_tilt.scan_topic, "rosbag2: the LaserScan topic (default: the bag's only one)");
  imp->add_option("--tilt-topic", imp_tilt.tilt_topic,
                  "rosbag2: the tilt topic, a std_msgs number or TOPIC:JOINT of a JointState (default: the only one)");
  imp->add_option("--odom-topic", imp_tilt.odom_topic, "rosbag2: nav_msgs/Odometry topic for poses.csv (default: the only one, if any)");
  imp->add_option("--tf-frames", imp_tilt.tf_frames,
                  "rosbag2: PARENT:CHILD (e.g. odom:base_link, map:base_link) of /tf (+ /tf_static) for poses.csv, composed "
                  "along the tf tree; default: the only /tf pair when there is no Odometry topic (not with --odom-topic)");
  imp->add_option("--tilt-zero", imp_tilt.passes.geometry.zero, "rplidar, rosbag2: the tilt reading at level (JointState: degrees)")
      ->capture_default_str();
  imp->add_option("--tilt-sign", imp_sign, "rplidar, rosbag2: ROS pitch about y = sign * scale * (reading - zero); nod up = -pitch")
      ->capture_default_str()
      ->check(CLI::IsMember({-1, 1}));
  imp->add_option("--tilt-scale", imp_tilt.passes.geometry.scale, "rplidar, rosbag2: degrees per unit of the reading")
      ->capture_default_str();
  imp->add_option("--axis-offset", imp_tilt.passes.geometry.axis_offset,
                  "rplidar, rosbag2: m, the laser above the tilt axis (printed as the pipeline's mount z)")
      ->capture_default_str();
  imp->add_option("--beams-per-line", imp_beams,
                  "3dtk: beams per scan line when the geometry cannot tell (default: read from the points' bearings)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 24));
  cli::BenchArgs bench;
  CLI::App* bch = app.add_subcommand("bench", "time the chain stage by stage against PCL, OctoMap and a plain loop, same data");
  bch->add_option("--scene", bench.scene, "scene to simulate (default: the installed or source tree's sample_scans/scene.yaml)");
  bch->add_option("--pipeline", bench.pipeline,
                  "pipeline to time, its input replaced (default: the installed or source tree's pipelines/nodding_terrain.yaml)");
  bch->add_option("--passes", bench.passes, "passes to simulate")->capture_default_str();
  bch->add_option("--reps", bench.reps, "repetitions (the median is reported)")->capture_default_str();
  bch->add_flag("--geometric", bench.geometric, "geometric simulator (no beam footprint), faster to generate");
  bch->add_option("--scaling", bench.scaling, "also time `run` on these numbers of passes, e.g. 1,10,100");
  CLI::App* docs = app.add_subcommand("docs", "print the generated stage and block reference (Markdown)");

  cli::ShardArgs shard_args;
  cli::add_shard_commands(app, shard_args);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : static_cast<int>(ExitCode::kConfig);
  }

  // SIGINT/SIGTERM: the temporaries of a commit in progress are removed, exit 128 + signal.
  io::install_signal_cleanup();
  try {
    if (*run) return cli::cmd_run(run_args);
    if (const int rc = cli::run_shard_commands(shard_args); rc >= 0) return rc;
    if (*validate) return cli::cmd_validate(run_args);
    if (*stages) return cli::cmd_stages();
    if (*describe) return cli::cmd_describe(describe_what);
    if (*evaluate) return cli::cmd_evaluate(ev_truth, ev_run, ev_json, ev_quiet);
    if (*docs) return cli::cmd_docs();
    if (*bch) return cli::cmd_bench(bench);
    if (*imp && imp_format != "rplidar" && imp_format != "rosbag2")
      for (const char* o : {"--scan-topic", "--tilt-topic", "--odom-topic", "--tf-frames", "--tilt-zero", "--tilt-sign", "--tilt-scale", "--axis-offset"})
        if (imp->count(o) > 0) throw ConfigError(std::string("import ") + imp_format + ": " + o + " is for rplidar and rosbag2");
    if (*imp && (imp_format == "rplidar" || imp_format == "rosbag2")) {
      imp_tilt.passes.geometry.sign = imp_sign;
      return cli::cmd_import_tilt(imp_format, imp_in, imp_out, imp_tilt);
    }
    if (*imp && imp_format == "carmen" && imp_beams == 0) return cli::cmd_import_carmen(imp_in, imp_out);
    if (*imp) return cli::cmd_import(imp_format, imp_in, imp_out, imp_poses, imp_viewpoint, imp_residual, imp_nod_origin, imp_beams,
                                     imp_max_range, imp_unit_scale);
    if (*mrg) return cli::cmd_merge(mg_in, mg_out, mg_png, mg_threads);
    if (*calr) return cli::cmd_calibrate_range(cr_csv);
    if (*calm) return cli::cmd_calibrate_mount(cm_args, cm_scans);
    if (*ebud) return cli::cmd_error_budget(eb_args, eb_svg, eb_csv);
    if (*clean) {
      cc.resolution_given = clean_res->count() > 0;
      return cli::cmd_clean_cloud(cc);
    }
    if (*amp) return cli::cmd_amplitude_model(edge, am);
    if (*plan) return cli::cmd_plan_nod(np, np_csv);
    if (*simulate) return cli::cmd_simulate(scene, sim_out, sim_quiet);
  } catch (const ConfigError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return static_cast<int>(ExitCode::kConfig);
  } catch (const InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return static_cast<int>(ExitCode::kInput);
  } catch (const OutputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return static_cast<int>(ExitCode::kOutput);
  } catch (const std::bad_alloc&) {
    // Readers and grids bound their memory by what the input holds (docs/robustness.md), so what
    // is left is an input too large for this machine's memory: a data problem, not a bug.
    std::cerr << kOutOfMemory;
    return static_cast<int>(ExitCode::kInput);
  } catch (const std::system_error& e) {
    // A thread that cannot be started for want of memory is the same case.
    if (e.code() == std::errc::resource_unavailable_try_again || e.code() == std::errc::not_enough_memory) {
      std::cerr << kOutOfMemory;
      return static_cast<int>(ExitCode::kInput);
    }
    std::cerr << "internal error: " << e.what() << "\n";
    return static_cast<int>(ExitCode::kInternal);
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << "\n";
    return static_cast<int>(ExitCode::kInternal);
  }
  return static_cast<int>(ExitCode::kInternal);
}
