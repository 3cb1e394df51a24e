// pcd_pipeline's rejection stages as PCL filters, for code that composes PCL filters:
//
//   pcdp::MixedPixelRemoval<pcl::PointXYZI> f;
//   f.setInputCloud(cloud);           // cloud->sensor_origin_ / sensor_orientation_ = the scanner
//   f.setKeepOrganized(true);         // optional, as for any pcl::FilterIndices
//   f.filter(*clean);                 // or f.filter(indices); getRemovedIndices(); getLabels()
//
// Header-only templates over pcl::FilterIndices<PointT>; the algorithms live in the pcdp library
// (which has no PCL in its interface). Link pcdp::pcl (find_package(pcd_pipeline COMPONENTS pcl)).
//
// Input: a cloud as the scanner saw it, with the scanner at sensor_origin_ (pcdp/core/cloud_pass.hpp
// says what is assumed). Organized clouds (height > 1: one scan line per row) give neighbours along
// and across lines; MixedPixelRemoval also takes unorganized clouds (neighbours by angle,
// setAngularResolution). A point field `intensity`, if PointT has one, is the amplitude; without
// it the amplitude tests are skipped (MixedPixelRemoval) or the filter removes nothing
// (OcclusionRemoval needs amplitudes). Only indices_ (setIndices) are considered; the others are
// treated as absent. Non-finite points are removed (reported with label no_return), as PCL's
// own filters do. setNegative(true) returns the rejected points instead.
#pragma once

#include <pcl/filters/filter_indices.h>
#include <pcl/filters/impl/filter_indices.hpp>  // FilterIndices<PointT>::applyFilter(PointCloud&) for any PointT

#include <type_traits>
#include <utility>
#include <vector>

#include "pcdp/core/cloud_pass.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "pcdp/stages/reject_occlusion.hpp"

namespace pcdp {

namespace detail {
template <typename T, typename = void>
struct has_intensity : std::false_type {};
template <typename T>
struct has_intensity<T, std::void_t<decltype(std::declval<T>().intensity)>> : std::true_type {};

/// The considered points of a PCL cloud as a CartesianCloud (others become no-returns).
template <typename PointT>
CartesianCloud to_cartesian(const pcl::PointCloud<PointT>& in, const pcl::Indices& considered) {
  CartesianCloud c;
  c.width = in.width;
  c.height = in.height;
  if (c.width * c.height != in.size()) {  // a cloud whose header disagrees with its size: unorganized
    c.width = in.size();
    c.height = 1;
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  c.points.assign(in.size(), Eigen::Vector3f(nan, nan, nan));
  if constexpr (has_intensity<PointT>::value) c.intensity.assign(in.size(), nan);
  for (const auto i : considered) {
    const PointT& p = in[static_cast<std::size_t>(i)];
    c.points[static_cast<std::size_t>(i)] = Eigen::Vector3f(p.x, p.y, p.z);
    if constexpr (has_intensity<PointT>::value) c.intensity[static_cast<std::size_t>(i)] = p.intensity;
  }
  c.origin = in.sensor_origin_.template head<3>().template cast<double>();
  c.orientation = in.sensor_orientation_.template cast<double>();
  return c;
}
}  // namespace detail

/// Common part: classify every point, then split the considered indices into kept and removed.
template <typename PointT>
class LabelFilterBase : public pcl::FilterIndices<PointT> {
 public:
  using pcl::FilterIndices<PointT>::FilterIndices;
  /// The label of every input point after filter(): kept, no_return or the filter's reason.
  const std::vector<Label>& getLabels() const { return labels_; }
  void setSensor(const SensorParams& s) { sensor_ = s; }
  const SensorParams& getSensor() const { return sensor_; }

 protected:
  using pcl::FilterIndices<PointT>::input_;
  using pcl::FilterIndices<PointT>::indices_;
  using pcl::FilterIndices<PointT>::negative_;
  using pcl::FilterIndices<PointT>::removed_indices_;
  using pcl::FilterIndices<PointT>::extract_removed_indices_;

  virtual std::vector<Label> classify(const CartesianCloud& cloud) = 0;

  void applyFilter(pcl::Indices& indices) override {
    labels_ = classify(detail::to_cartesian(*input_, *indices_));
    indices.clear();
    indices.reserve(indices_->size());
    if (extract_removed_indices_) removed_indices_->clear();
    for (const auto i : *indices_) {
      const Label l = labels_[static_cast<std::size_t>(i)];
      const bool rejected_by_us = l != Label::kKept && l != Label::kNoReturn;
      const bool keep = negative_ ? rejected_by_us : l == Label::kKept;
      if (keep)
        indices.push_back(i);
      else if (extract_removed_indices_)
        removed_indices_->push_back(i);
    }
  }

  SensorParams sensor_{};
  std::vector<Label> labels_;
};

/// reject_mixed_pixels as a PCL filter (label mixed_pixel).
template <typename PointT>
class MixedPixelRemoval : public LabelFilterBase<PointT> {
 public:
  explicit MixedPixelRemoval(bool extract_removed_indices = false) : LabelFilterBase<PointT>(extract_removed_indices) {
    this->filter_name_ = "pcdp::MixedPixelRemoval";
    this->sensor_.transceiver_separation = 0.0;  // unknown: do not assume the light can only drop
  }
  void setParams(const MixedPixelParams& p) { params_ = p; }
  const MixedPixelParams& getParams() const { return params_; }
  /// Unorganized clouds: width of the angular bands that stand for scan lines, rad.
  void setAngularResolution(double rad) { resolution_ = rad; }
  /// Unorganized clouds: how scan order is recovered (kSpherical by default).
  void setCloudAngles(CloudAngles a) { angles_ = a; }

 protected:
  std::vector<Label> classify(const CartesianCloud& c) override {
    Pass pass = pass_from_cloud(c);
    if (c.height > 1) {
      reject_mixed_pixels(pass, params_, this->sensor_);
      return pass.label;
    }
    std::vector<Eigen::Vector3d> pts(c.points.size());
    for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = c.points[i].template cast<double>();
    const auto mixed = mixed_pixels_in_cloud(pts, c.origin, c.intensity, resolution_, params_, this->sensor_.range_sigma,
                                             angles_, c.orientation);
    for (std::size_t i = 0; i < mixed.size(); ++i)
      if (mixed[i] && pass.label[i] == Label::kKept) pass.label[i] = Label::kMixedPixel;
    return pass.label;
  }

 private:
  MixedPixelParams params_{};
  double resolution_ = 0.0087;  // 0.5 degree
  CloudAngles angles_ = CloudAngles::kSpherical;
};

/// reject_occlusion as a PCL filter (labels occlusion and low_amplitude). Needs an organized
/// cloud with intensities; set the sensor's geometry and min_amplitude with setSensor.
template <typename PointT>
class OcclusionRemoval : public LabelFilterBase<PointT> {
 public:
  explicit OcclusionRemoval(bool extract_removed_indices = false) : LabelFilterBase<PointT>(extract_removed_indices) {
    this->filter_name_ = "pcdp::OcclusionRemoval";
  }
  void setParams(const OcclusionParams& p) { params_ = p; }
  const OcclusionParams& getParams() const { return params_; }

 protected:
  std::vector<Label> classify(const CartesianCloud& c) override {
    Pass pass = pass_from_cloud(c);
    if (c.intensity.empty())
      PCL_WARN("[%s] the point type has no intensity field: nothing is rejected\n", this->filter_name_.c_str());
    else if (c.height < 2)
      PCL_WARN("[%s] the cloud is not organized: rejecting along its one line only\n", this->filter_name_.c_str());
    if (!c.intensity.empty()) reject_occlusion(pass, params_, this->sensor_);
    return pass.label;
  }

 private:
  OcclusionParams params_{};
};

}  // namespace pcdp
