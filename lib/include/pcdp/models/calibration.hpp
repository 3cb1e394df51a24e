// Calibration of a rig: the linear range calibration (Ye & Borenstein 2002, eqs. 1-3) and the
// mount's pitch, roll and height from a scan of a flat floor (Broten & Collier 2005, section 7.4,
// done there by hand in a loop; here by fitting the floor plane).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "pcdp/core/transforms.hpp"

namespace pcdp {

struct RangeCalibration {
  double k = 1.0, b = 0.0;        ///< true = k * measured + b
  double se_k = 0.0, se_b = 0.0;  ///< standard errors
  std::size_t distances = 0;      ///< distinct true distances
  std::size_t samples = 0;
  double rms = 0.0, max_abs = 0.0;  ///< residuals of the per-distance means, m
};

/// Eqs. 1-3: for each distinct true distance y_i the mean measured range mu_i, then least squares
/// of y on mu. Needs at least 3 distinct distances (2 fit exactly and leave no residual to
/// estimate the errors from). Throws InputError.
RangeCalibration fit_range_calibration(const std::vector<double>& true_distance, const std::vector<double>& measured);

struct MountCalibration {
  Rpy rpy;                    ///< roll and pitch estimated; yaw as given
  double height = 0.0;        ///< m, nod-axis origin above the floor
  Eigen::Vector3d normal_N = Eigen::Vector3d::UnitZ();  ///< floor normal in the nod frame (up)
  std::size_t points = 0, inliers = 0;
  double rms = 0.0;           ///< m, of the inliers about the plane
};

/// The floor plane through points in the nod frame N (RANSAC, then least squares on its inliers),
/// and the mount roll, pitch (in `order`, with the given yaw) and height that make it the plane
/// z = 0 of the vehicle frame. `expected_up_N` is the floor normal the configured mount implies
/// (R_VN^T e_z); the fitted plane may differ from it by at most max_tilt. Throws InputError when no
/// floor is in view (too few points, the largest plane holds less than min_fraction of them, it is
/// not below the sensor, or it is tilted more than max_tilt: a wall).
MountCalibration calibrate_mount(const std::vector<Eigen::Vector3d>& points_N, double yaw, RpyOrder order,
                                 const Eigen::Vector3d& expected_up_N = Eigen::Vector3d::UnitZ(),
                                 double max_tilt = 0.785, double inlier_threshold = 0.03, double min_fraction = 0.3);

}  // namespace pcdp
