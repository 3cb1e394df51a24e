// Cleans a cloud the way a mapping stack would embed the library, built against the *installed*
// package: a simulated nodding scan is registered through the library API, handed over as an
// organized pcl::PointCloud (one scan line per row, the scanner at sensor_origin_), and cleaned
// with the PCL-native filters composed like any pcl::FilterIndices. Prints what it did.
#include <pcl/point_types.h>

#include <cmath>
#include <cstdio>

#include "pcdp/core/pass.hpp"
#include "pcdp/pcl/filters.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/register.hpp"

int main() {
  pcdp::sim::SimConfig c;
  c.scene.boxes.push_back({{6.0, -1.0, -1.0}, {7.0, 1.0, 1.5}, 0.5});
  c.scanner.beam_divergence = 0.008;
  c.scanner.subrays = 7;
  c.lines_per_pass = 60;
  c.motion.speed = 0.0;  // a standing robot: one sensor pose for the whole cloud
  const auto run = pcdp::sim::simulate(c);
  const pcdp::PoseTrack poses(run.poses);
  pcdp::Pass pass = run.passes[0].pass;
  pcdp::SensorParams sensor;
  sensor.transceiver_separation = c.scanner.transceiver_separation;
  sensor.min_amplitude = c.scanner.min_amplitude;
  const Eigen::Isometry3d T_V_N = pcdp::make_transform(c.mount_translation, c.mount_rpy, c.rpy_order);
  pcdp::register_pass(pass, {}, sensor, T_V_N, &poses);

  // What a PCL-based stack would have: an organized XYZI cloud with the scanner's pose.
  pcl::PointCloud<pcl::PointXYZI>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZI>);
  cloud->resize(pass.size());
  for (std::size_t i = 0; i < pass.size(); ++i) {
    const bool ok = pass.is_kept(i);
    (*cloud)[i].x = ok ? static_cast<float>(pass.x[i]) : NAN;
    (*cloud)[i].y = ok ? static_cast<float>(pass.y[i]) : NAN;
    (*cloud)[i].z = ok ? static_cast<float>(pass.z[i]) : NAN;
    (*cloud)[i].intensity = pass.amplitude[i];
  }
  cloud->width = static_cast<std::uint32_t>(pass.line_begin[1]);
  cloud->height = static_cast<std::uint32_t>(pass.line_count());
  cloud->is_dense = false;
  std::size_t hint = 0;
  const Eigen::Isometry3d T_map_nod = poses.at(pass.stamp[0], hint) * T_V_N;
  const Eigen::Vector3f o = T_map_nod.translation().cast<float>();
  cloud->sensor_origin_ = Eigen::Vector4f(o.x(), o.y(), o.z(), 0.0f);
  cloud->sensor_orientation_ = Eigen::Quaternionf(T_map_nod.linear().cast<float>());

  // Occlusion artefacts first, keeping the cloud organized for the next filter, then mixed pixels.
  pcdp::OcclusionRemoval<pcl::PointXYZI> occlusion(true);
  occlusion.setSensor(sensor);
  occlusion.setInputCloud(cloud);
  occlusion.setKeepOrganized(true);
  pcl::PointCloud<pcl::PointXYZI>::Ptr step1(new pcl::PointCloud<pcl::PointXYZI>);
  occlusion.filter(*step1);

  pcdp::MixedPixelRemoval<pcl::PointXYZI> mixed(true);
  mixed.setSensor(sensor);
  mixed.setInputCloud(step1);
  pcl::PointCloud<pcl::PointXYZI> clean;
  mixed.filter(clean);

  std::size_t finite = 0;
  for (const auto& p : *cloud) finite += std::isfinite(p.x);
  const std::size_t occluded = occlusion.getRemovedIndices()->size() - (cloud->size() - finite);
  std::printf("consumer: %zu returns, %zu points, %zu occlusion/low-amplitude removed, %zu mixed pixels removed, %zu kept\n",
              cloud->size(), finite, occluded, finite - occluded - clean.size(), clean.size());
  return clean.size() > 0 && clean.size() < finite ? 0 : 1;
}
