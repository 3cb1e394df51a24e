// `pcd_pipeline bench`: our chain and the peers (PCL, OctoMap, a plain loop) on the same simulated
// passes in one run. The PCL peers live in their own translation unit (bench_pcl.cpp) so only it
// compiles PCL templates.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace pcdp::cli {

struct BenchArgs {
  std::string scene = "sample_scans/scene.yaml";
  std::string pipeline = "pipelines/nodding_terrain.yaml";
  int passes = 4;
  int reps = 3;
  bool geometric = false;
  std::string scaling;  ///< "1,10,100": also run the scaling table
};

int cmd_bench(const BenchArgs& a);

struct PeerTimes {
  double transform = 0;  ///< pcl::transformPointCloud over all points, median seconds
  double sor = 0;        ///< pcl::StatisticalOutlierRemoval over the kept points, median seconds
  std::size_t sor_points = 0;
};

/// Times PCL's transformPointCloud (all points) and StatisticalOutlierRemoval (the kept ones).
PeerTimes pcl_peers(const std::vector<float>& x, const std::vector<float>& y, const std::vector<float>& z,
                    const std::vector<char>& kept, int reps);

}  // namespace pcdp::cli
