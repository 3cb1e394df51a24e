// Per-point uncertainty: first-order propagation of the measurement and pose errors through the
// transform chain  p_M = R_MV (R_VN p_N(r, nu, eta) + t_VN) + t_MV  to a 3x3 covariance in the
// map frame (Broten & Collier 2005, section 6.3: range, beam orientation, position and
// roll/pitch/yaw errors).
#pragma once

#include <Eigen/Core>
#include <cstddef>

#include "pcdp/core/transforms.hpp"

namespace pcdp {

/// 1-sigma errors of one return.
struct PointSigmas {
  double range = 0.0;     ///< m
  double bearing = 0.0;   ///< rad
  double nod = 0.0;       ///< rad (encoder quantization and latency)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m, of T_M_V (x, y, z)
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();       ///< rad, of T_M_V (roll, pitch, yaw in `order`)
};

/// Jacobian of p_M with respect to (r, nu, eta, x, y, z, roll, pitch, yaw) of T_M_V.
Eigen::Matrix<double, 3, 9> chain_jacobian(double r, double nu, double eta, const Eigen::Isometry3d& T_V_N,
                                           const Rpy& rpy_MV, RpyOrder order);

/// Covariance of p_M: J diag(sigma^2) J^T.
Eigen::Matrix3d point_covariance(double r, double nu, double eta, const Eigen::Isometry3d& T_V_N, const Rpy& rpy_MV,
                                 RpyOrder order, const PointSigmas& s);

/// The same covariance from what register already has: the sines and cosines of the bearing and
/// the nod, and R_MV as a matrix (no roll, pitch, yaw). The pose-angle columns of J use
/// d(R p)/d(angle_k) = a_k x (R p), with a_k the k-th rotation axis expressed in the map frame
/// (xyz: e_x, Rx e_y, R e_z; zyx: R e_x, Rz e_y, e_z), the middle axis found as the unit vector
/// normal to the other two. Equal to point_covariance (a property test checks it to 1e-9),
/// about 4x cheaper. Falls back to it at gimbal lock (pitch within 1e-6 of +-90 degrees).
Eigen::Matrix3d point_covariance_fast(double r, double cos_nu, double sin_nu, double cos_eta, double sin_eta,
                                      const Eigen::Matrix3d& R_MV, const Eigen::Isometry3d& T_V_N, RpyOrder order,
                                      const PointSigmas& s);
/// The same from what register has already computed for the point: R_MN = R_MV R_VN and
/// Rp = R_MV (T_V_N p_N) (the point relative to the vehicle, in map axes). A sum of one rank-1
/// term per error source (the measurement columns of J are orthogonal in the nod frame).
Eigen::Matrix3d point_covariance_fast(double r, double cos_nu, double sin_nu, double cos_eta, double sin_eta,
                                      const Eigen::Matrix3d& R_MV, const Eigen::Isometry3d& T_V_N,
                                      const Eigen::Matrix3d& R_MN, const Eigen::Vector3d& Rp, RpyOrder order,
                                      const PointSigmas& s);

/// The pose axis innermost in the RPY product, as a column of R_MV: yaw's (column 2) for xyz,
/// roll's (column 0) for zyx.
inline int inner_pose_axis(RpyOrder order) { return order == RpyOrder::kXyz ? 2 : 0; }

/// point_covariance_fast for many returns at once, over arrays in single precision (the
/// covariance is stored as float): lane j's inputs are in[k * stride + j] for each Input k (the
/// range, the bearing's and nod's cosines and sines, the nod's variance, R_MN column by column,
/// the inner pose axis R_MV.col(inner_pose_axis(order)) and Rp), and its six entries (xx xy xz yy
/// yz zz, with the position variances) go to res[k * stride + j]. The compiler turns the loop
/// into vector instructions (4 lanes per instruction with SSE2), every lane through the same
/// instructions whatever its place. Equal to point_covariance to a few 1e-7 of the matrix's norm
/// (tests/unit/core/test_uncertainty.cpp). A lane at gimbal lock (middle_norm2 under kGimbalLock)
/// gives no usable result: take point_covariance_fast for that return.
class CovarianceLanes {
 public:
  enum Input { kR, kCn, kSn, kCe, kSe, kVarNod, kR00, kR10, kR20, kR01, kR11, kR21, kR02, kR12, kR22,
               kIx, kIy, kIz, kPx, kPy, kPz, kInputs };
  static constexpr std::size_t kGroup = 16;  ///< compute() runs whole groups of this many lanes
  static constexpr double kGimbalLock = 1e-12;  ///< point_covariance_fast's test (|middle| < 1e-6)
  /// `s.nod` is not used: each lane brings its own variance.
  CovarianceLanes(RpyOrder order, const PointSigmas& s);
  /// Lanes [0, n rounded up to kGroup): both arrays must hold that many lanes per row, with
  /// finite or NaN inputs (never read uninitialised) in the lanes past n.
  void compute(const float* in, float* res, std::size_t stride, std::size_t n) const;
  /// The squared length of the middle pose axis (outer x inner) for an inner axis.
  double middle_norm2(double ix, double iy, double iz) const {
    return xyz_ ? iy * iy + iz * iz : ix * ix + iy * iy;
  }

 private:
  bool xyz_;
  float var_range_, var_bearing_, var_outer_, var_middle_, var_inner_, var_pos_[3];
};

/// 1-sigma of a uniform quantization step q: q / sqrt(12).
inline double quantization_sigma(double q) { return q / 3.4641016151377544; }

/// Broten & Collier's small-angle estimate of the 3-D position error for an orientation error
/// d_eps in pitch and yaw (roll rotates about the beam): Delta s = sqrt(2) r d_eps (section 6.3.3).
/// Their Table 1 tabulates sqrt(2 r d_eps) instead (0.19 m at 1 m and 1 degree); we follow the
/// formula, which the propagated covariance reproduces.
inline double broten_collier_orientation_error(double range, double d_eps) { return 1.4142135623730951 * range * d_eps; }

}  // namespace pcdp
