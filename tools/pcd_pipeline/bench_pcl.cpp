// The PCL peers of `pcd_pipeline bench`; the only translation unit of the CLI that includes PCL.
#include <pcl/common/transforms.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>

#include "bench.hpp"

namespace pcdp::cli {

PeerTimes pcl_peers(const std::vector<float>& x, const std::vector<float>& y, const std::vector<float>& z,
                    const std::vector<char>& kept, int reps) {
  using Clock = std::chrono::steady_clock;
  pcl::PointCloud<pcl::PointXYZ>::Ptr all(new pcl::PointCloud<pcl::PointXYZ>), in(new pcl::PointCloud<pcl::PointXYZ>);
  all->reserve(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    all->push_back(pcl::PointXYZ(x[i], y[i], z[i]));
    if (kept[i]) in->push_back(pcl::PointXYZ(x[i], y[i], z[i]));
  }
  const Eigen::Affine3f T = Eigen::Translation3f(1.f, 2.f, 3.f) *
                            Eigen::AngleAxisf(0.3f, Eigen::Vector3f(0.2f, 0.3f, 0.9f).normalized());
  const auto med = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  PeerTimes out;
  std::vector<double> t;
  pcl::PointCloud<pcl::PointXYZ> moved;
  for (int r = 0; r < std::max(reps, 5); ++r) {
    const auto t0 = Clock::now();
    pcl::transformPointCloud(*all, moved, T);
    t.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  out.transform = med(t);
  t.clear();
  pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
  sor.setMeanK(8);
  sor.setStddevMulThresh(1.0);
  // The indices form of filter(): the output is a plain std::vector. A cloud allocated inside the
  // prebuilt libpcl_filters and freed here would cross an Eigen allocation boundary that differs
  // under AddressSanitizer (Eigen stops trusting malloc's alignment there), which ASan reports.
  pcl::Indices kept_indices;
  for (int r = 0; r < reps; ++r) {
    sor.setInputCloud(in);
    const auto t0 = Clock::now();
    sor.filter(kept_indices);
    t.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  out.sor = med(t);
  out.sor_points = in->size();
  return out;
}

}  // namespace pcdp::cli
