// `pcd_pipeline bench`: our chain and the peers (PCL, OctoMap, a plain loop) on the same simulated
// passes in one run. The PCL peers live in their own translation unit (bench_pcl.cpp) so only it
// compiles PCL templates.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace pcdp::cli {

struct BenchArgs {
  /// Empty: sample_scans/scene.yaml and pipelines/nodding_terrain.yaml of the installed data
  /// (<prefix>/share/pcd_pipeline, beside <prefix>/bin) or, for a binary in its build tree, of the
  /// source tree it was built from (bench_data_root); never of the working directory.
  std::string scene;
  std::string pipeline;
  int passes = 4;
  int reps = 3;
  bool geometric = false;
  std::string scaling;  ///< "1,10,100": also run the scaling table
};

int cmd_bench(BenchArgs a);

/// The folder that holds sample_scans/ and pipelines/ for bench's defaults: <exe>/../share/pcd_pipeline
/// when it has them (an installed binary), else the source tree the binary was built from. Throws
/// ConfigError naming both places when neither has them.
std::string bench_data_root();

struct PeerTimes {
  double transform = 0;  ///< pcl::transformPointCloud over all points, median seconds
  double sor = 0;        ///< pcl::StatisticalOutlierRemoval over the kept points, median seconds
  std::size_t sor_points = 0;
};

/// Times PCL's transformPointCloud (all points) and StatisticalOutlierRemoval (the kept ones).
PeerTimes pcl_peers(const std::vector<float>& x, const std::vector<float>& y, const std::vector<float>& z,
                    const std::vector<char>& kept, int reps);

}  // namespace pcdp::cli
