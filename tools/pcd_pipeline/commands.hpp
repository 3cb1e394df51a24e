// The CLI's commands. Each returns an exit code; errors propagate as exceptions and are mapped to
// exit codes in main.cpp (0 ok, 1 internal, 2 configuration, 3 input data).
#pragma once

#include <string>
#include <vector>

#include "pcdp/import/rosbag2.hpp"

namespace pcdp {
struct NodPlanParams;
struct EdgeParams;
}

namespace pcdp::cli {

struct RunArgs {
  std::string pipeline;
  std::vector<std::string> sets;
  std::string output_dir;
  bool quiet = false;
  unsigned threads = 0;  ///< 0: one per core
};

int cmd_run(const RunArgs& a);
int cmd_validate(const RunArgs& a);
int cmd_stages();
int cmd_describe(const std::string& what);
int cmd_evaluate(const std::string& truth, const std::string& run, const std::string& json, bool quiet);
int cmd_plan_nod(const NodPlanParams& p, const std::string& csv);
struct AmplitudeModelArgs {
  double min_amplitude = 18.0;
  int points = 400;
  std::string profile_csv, theta_csv, svg_prefix;
};
int cmd_amplitude_model(const EdgeParams& e, const AmplitudeModelArgs& a);
struct CleanCloudArgs {
  std::string input, output, removed, viewpoint;
  std::string orientation;     ///< "qw,qx,qy,qz": the scanner's frame in the cloud's (default: the PCD VIEWPOINT's)
  double resolution = 0.0087;  ///< rad, about the scan's angular step
  bool resolution_given = false;
  bool unorganized = false;    ///< read an organized PCD as an unorganized cloud (a range camera, a spinning lidar)
  bool quiet = false;
};
int cmd_clean_cloud(const CleanCloudArgs& a);
int cmd_calibrate_range(const std::string& csv);
int cmd_calibrate_mount(const RunArgs& a, const std::vector<std::string>& scans);
int cmd_error_budget(const RunArgs& a, const std::string& svg, const std::string& csv);
int cmd_merge(const std::vector<std::string>& inputs, const std::string& output, const std::string& png, unsigned threads);
int cmd_docs();
int cmd_import(const std::string& format, const std::vector<std::string>& inputs, const std::string& out_dir,
               const std::string& poses, const std::string& viewpoint = "", double max_residual = 0.02,
               const std::string& nod_origin = "", std::size_t beams_per_line = 0, double max_range = 1000.0,
               double unit_scale = 0.0);
/// `import rplidar` (CSV export) and `import rosbag2` (ROS 2 bag): LaserScan + tilt stream, with the
/// shared tilt geometry in `p.passes.geometry` (rplidar uses only that).
int cmd_import_tilt(const std::string& format, const std::vector<std::string>& inputs, const std::string& out_dir,
                    const io::Rosbag2ImportParams& p);
/// `import carmen LOG --output-dir DIR`: one planar pass per laser message and the laser poses.
int cmd_import_carmen(const std::vector<std::string>& inputs, const std::string& out_dir);
int cmd_simulate(const std::string& scene, const std::string& output_dir, bool quiet);

}  // namespace pcdp::cli
