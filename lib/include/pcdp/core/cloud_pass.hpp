// A Cartesian cloud that someone already has (a PCL cloud, a PCD/PLY file, a ScanGraph node), seen
// from one sensor pose, as a *registered* pass, so the reject stages can run on it without raw
// ranges. This is the bridge the PCL-native filters (pcdp/pcl/filters.hpp) stand on.
//
// What it assumes:
//  - organized (height > 1): row k is scan line k and column b is beam b (a nodding 2-D scanner
//    stores one line per row); neighbours along a row and down a column are neighbours on the scan;
//  - unorganized (height == 1): one line; use mixed_pixels_in_cloud for neighbours by angle;
//  - the sensor (nod-axis) origin and orientation give each point its range, its bearing
//    atan2(y_s, hypot(x_s, z_s)) and its nod atan2(z_s, x_s) in the sensor frame (x forward,
//    y left, z up, the scan plane being x-y at nod 0); a line's nod is the median of its points';
//  - a non-finite point is a no-return; intensity (if any) is the amplitude, NaN = not measured.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "pcdp/core/pass.hpp"

namespace pcdp {

struct CartesianCloud {
  std::size_t width = 0, height = 1;
  std::vector<Eigen::Vector3f> points;  ///< width * height, row-major; non-finite = no return
  std::vector<float> intensity;         ///< empty, or one per point
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();                     ///< sensor origin in the cloud frame
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();      ///< sensor frame in the cloud frame
};

/// The registered pass of a cloud: x, y, z are the points (cloud frame), the sensor origin is
/// `origin` for every return, range_cal the distance to it, labels kKept or kNoReturn. Throws
/// std::invalid_argument if points.size() != width * height or intensity has another size.
Pass pass_from_cloud(const CartesianCloud& cloud);

}  // namespace pcdp
