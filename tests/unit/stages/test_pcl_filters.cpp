// The PCL-native filters (pcdp/pcl/filters.hpp) against the stages they wrap and against the
// simulator's truth, and their pcl::FilterIndices contract (indices, removed indices, negative,
// keep-organized, setIndices).
#include <gtest/gtest.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "pcdp/pcl/filters.hpp"
#include "sim/bench_scenes.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp/core/transforms.hpp"

using namespace pcdp;

namespace {
struct Scan {
  pcl::PointCloud<pcl::PointXYZI>::Ptr cloud{new pcl::PointCloud<pcl::PointXYZI>};
  Pass pass;                 // the same returns, registered by the library
  std::vector<Label> truth;  // simulator truth
  SensorParams sensor;
};

// One pass of benchmark setting A seen from a standing vehicle, so that one sensor origin and
// orientation describe every return (what a PCL cloud can say).
Scan standing_scan(char setting) {
  bench::Setting s = bench::make_setting(setting, 3);
  s.sim.motion.speed = 0.0;
  s.sim.motion.yaw_rate = 0.0;
  s.sim.motion.follow_terrain = false;
  s.sim.motion.roll_amplitude = s.sim.motion.pitch_amplitude = 0.0;
  s.sim.motion.position_sigma = s.sim.motion.rpy_sigma = 0.0;
  s.sim.passes = 1;
  s.sim.lines_per_pass = 200;  // the whole nod range, down and up again
  const auto run = sim::simulate(s.sim);
  Scan out;
  out.sensor = s.sensor;
  out.pass = run.passes[0].pass;
  out.truth = run.passes[0].truth;
  const PoseTrack poses(run.poses);
  const Eigen::Isometry3d T_V_N = make_transform(s.sim.mount_translation, s.sim.mount_rpy, s.sim.rpy_order);
  register_pass(out.pass, RegisterParams{}, s.sensor, T_V_N, &poses);
  const std::size_t width = out.pass.line_begin[1];
  out.cloud->resize(out.pass.size());
  for (std::size_t i = 0; i < out.pass.size(); ++i) {
    auto& p = (*out.cloud)[i];
    const bool ok = out.pass.is_kept(i);
    p.x = ok ? static_cast<float>(out.pass.x[i]) : NAN;
    p.y = ok ? static_cast<float>(out.pass.y[i]) : NAN;
    p.z = ok ? static_cast<float>(out.pass.z[i]) : NAN;
    p.intensity = out.pass.amplitude[i];
  }
  out.cloud->width = static_cast<std::uint32_t>(width);
  out.cloud->height = static_cast<std::uint32_t>(out.pass.line_count());
  out.cloud->is_dense = false;
  std::size_t hint = 0;
  const Eigen::Isometry3d T_map_nod = poses.at(out.pass.stamp[0], hint) * T_V_N;
  const Eigen::Vector3f o = T_map_nod.translation().cast<float>();
  out.cloud->sensor_origin_ = Eigen::Vector4f(o.x(), o.y(), o.z(), 0.0f);
  out.cloud->sensor_orientation_ = Eigen::Quaternionf(T_map_nod.linear().cast<float>());
  return out;
}

double recall(const std::vector<Label>& truth, const pcl::Indices& removed, Label reason) {
  std::size_t hit = 0, all = 0;
  std::set<int> r(removed.begin(), removed.end());
  for (std::size_t i = 0; i < truth.size(); ++i)
    if (truth[i] == reason) {
      ++all;
      hit += r.count(static_cast<int>(i));
    }
  return all ? static_cast<double>(hit) / static_cast<double>(all) : 0.0;
}
}  // namespace

TEST(PclFilters, MixedPixelRemovalAgreesWithTheStageAndFindsTheVeils) {
  Scan s = standing_scan('A');
  Pass stage = s.pass;
  const std::size_t n_stage = reject_mixed_pixels(stage, MixedPixelParams{}, s.sensor);
  ASSERT_GT(n_stage, 20u);

  MixedPixelRemoval<pcl::PointXYZI> f(true);
  f.setSensor(s.sensor);
  f.setInputCloud(s.cloud);
  pcl::PointCloud<pcl::PointXYZI> out;
  f.filter(out);
  const pcl::Indices removed = *f.getRemovedIndices();
  // Same decisions as the stage up to float rounding of the points.
  std::size_t same = 0, ours = 0;
  for (std::size_t i = 0; i < stage.size(); ++i) {
    const bool a = stage.label[i] == Label::kMixedPixel, b = f.getLabels()[i] == Label::kMixedPixel;
    same += a == b;
    ours += b;
  }
  EXPECT_GE(static_cast<double>(same), 0.999 * static_cast<double>(stage.size()));
  EXPECT_NEAR(static_cast<double>(ours), static_cast<double>(n_stage), 0.05 * static_cast<double>(n_stage) + 1);
  // Against the truth: most true mixed pixels that returned a point are removed.
  std::size_t truth_mixed_with_point = 0, removed_mixed = 0;
  for (std::size_t i = 0; i < s.truth.size(); ++i)
    if (s.truth[i] == Label::kMixedPixel && std::isfinite((*s.cloud)[i].x)) {
      ++truth_mixed_with_point;
      removed_mixed += f.getLabels()[i] == Label::kMixedPixel;
    }
  ASSERT_GT(truth_mixed_with_point, 30u);
  std::printf("organized: %zu of %zu true mixed pixels removed, stage %zu, filter %zu\n", removed_mixed, truth_mixed_with_point, n_stage, ours);
  EXPECT_GT(static_cast<double>(removed_mixed) / static_cast<double>(truth_mixed_with_point), 0.7);
  EXPECT_GT(recall(s.truth, removed, Label::kMixedPixel), 0.5);
  // Output: every finite point that was not rejected, in order; removed = the rest.
  std::size_t finite = 0;
  for (const auto& p : *s.cloud) finite += std::isfinite(p.x);
  EXPECT_EQ(out.size(), finite - ours);
  EXPECT_EQ(out.size() + removed.size(), s.cloud->size());
  for (const auto& p : out) EXPECT_TRUE(std::isfinite(p.x));
}

TEST(PclFilters, NegativeKeepOrganizedAndIndicesFollowTheFilterIndicesContract) {
  Scan s = standing_scan('A');
  MixedPixelRemoval<pcl::PointXYZI> f(true);
  f.setInputCloud(s.cloud);
  pcl::Indices kept;
  f.filter(kept);
  const std::vector<Label> labels = f.getLabels();
  f.setNegative(true);
  pcl::Indices rejected;
  f.filter(rejected);
  ASSERT_FALSE(rejected.empty());
  for (const int i : rejected) EXPECT_EQ(labels[static_cast<std::size_t>(i)], Label::kMixedPixel);
  for (const int i : kept) EXPECT_EQ(labels[static_cast<std::size_t>(i)], Label::kKept);
  EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));

  // Keep-organized: same size, removed points set to NaN, kept ones untouched.
  f.setNegative(false);
  f.setKeepOrganized(true);
  pcl::PointCloud<pcl::PointXYZI> org;
  f.filter(org);
  ASSERT_EQ(org.size(), s.cloud->size());
  EXPECT_EQ(org.width, s.cloud->width);
  for (const int i : rejected) EXPECT_TRUE(std::isnan(org[static_cast<std::size_t>(i)].x));
  for (const int i : kept) EXPECT_EQ(org[static_cast<std::size_t>(i)].x, (*s.cloud)[static_cast<std::size_t>(i)].x);

  // setIndices: only the first half of the lines is considered; nothing outside it comes back.
  pcl::IndicesPtr half(new pcl::Indices);
  for (std::size_t i = 0; i < s.cloud->size() / 2; ++i) half->push_back(static_cast<int>(i));
  MixedPixelRemoval<pcl::PointXYZI> g;
  g.setInputCloud(s.cloud);
  g.setIndices(half);
  pcl::Indices sub;
  g.filter(sub);
  ASSERT_FALSE(sub.empty());
  EXPECT_LT(static_cast<std::size_t>(sub.back()), s.cloud->size() / 2);
}

TEST(PclFilters, UnorganizedCloudsAreCleanedByAngle) {
  // A wall at 10 m behind a box face at 6 m, one column of veil points between, seen from a
  // viewpoint off the origin, shuffled: the filter puts the points back in scan order by angle.
  const Eigen::Vector3f vp(1.0f, -2.0f, 0.5f);
  const double step = 0.005;
  pcl::PointCloud<pcl::PointXYZ> ordered;
  std::vector<char> veil;
  for (int row = -20; row <= 20; ++row)
    for (int col = -60; col <= 60; ++col) {
      const double az = col * step, el = row * step;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const double range = (col == 0 ? 8.0 : col < 0 ? 6.0 : 10.0) / d.x();
      const Eigen::Vector3f p = vp + (range * d).cast<float>();
      ordered.push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
      veil.push_back(col == 0);
    }
  std::vector<std::size_t> order(ordered.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = (i * 7919) % order.size();  // a permutation (7919 prime)
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<char> truth;
  for (const std::size_t i : order) {
    cloud->push_back(ordered[i]);
    truth.push_back(veil[i]);
  }
  cloud->sensor_origin_ = Eigen::Vector4f(vp.x(), vp.y(), vp.z(), 0.0f);
  for (const CloudAngles angles : {CloudAngles::kSpherical, CloudAngles::kNodding}) {
    MixedPixelRemoval<pcl::PointXYZ> f(true);
    f.setAngularResolution(step);
    f.setCloudAngles(angles);
    f.setInputCloud(cloud);
    pcl::PointCloud<pcl::PointXYZ> out;
    f.filter(out);
    std::size_t tp = 0, fp = 0, pos = 0;
    for (const int i : *f.getRemovedIndices()) {
      tp += truth[static_cast<std::size_t>(i)];
      fp += !truth[static_cast<std::size_t>(i)];
    }
    for (const char t : truth) pos += t;
    EXPECT_EQ(tp, pos) << static_cast<int>(angles);
    EXPECT_EQ(fp, 0u) << static_cast<int>(angles);
    EXPECT_EQ(out.size(), cloud->size() - pos);
  }
}

TEST(PclFilters, OcclusionRemovalAgreesWithTheStage) {
  Scan s = standing_scan('A');
  Pass stage = s.pass;
  const OcclusionCounts c = reject_occlusion(stage, OcclusionParams{}, s.sensor);
  ASSERT_GT(c.occlusion + c.low_amplitude, 10u);
  OcclusionRemoval<pcl::PointXYZI> f;
  f.setSensor(s.sensor);
  f.setInputCloud(s.cloud);
  pcl::Indices kept;
  f.filter(kept);
  std::size_t same = 0, occl = 0;
  for (std::size_t i = 0; i < stage.size(); ++i) {
    same += stage.label[i] == f.getLabels()[i] || (stage.label[i] == Label::kNoReturn);
    occl += f.getLabels()[i] == Label::kOcclusion;
  }
  EXPECT_GE(static_cast<double>(same), 0.999 * static_cast<double>(stage.size()));
  EXPECT_NEAR(static_cast<double>(occl), static_cast<double>(c.occlusion), 0.1 * static_cast<double>(c.occlusion) + 2);
  // Without intensities nothing can be judged, and nothing is removed.
  pcl::PointCloud<pcl::PointXYZ>::Ptr xyz(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::copyPointCloud(*s.cloud, *xyz);
  OcclusionRemoval<pcl::PointXYZ> g(true);
  g.setInputCloud(xyz);
  pcl::Indices all;
  g.filter(all);
  for (const Label l : g.getLabels()) EXPECT_TRUE(l == Label::kKept || l == Label::kNoReturn);
}
