#include "pcdp/uncertainty.hpp"

#include <cmath>

namespace pcdp {

namespace {
Eigen::Vector3d cross_axis(int axis, const Eigen::Vector3d& v) { return Eigen::Vector3d::Unit(axis).cross(v); }
}  // namespace

Eigen::Matrix<double, 3, 9> chain_jacobian(double r, double nu, double eta, const Eigen::Isometry3d& T_V_N,
                                           const Rpy& rpy_MV, RpyOrder order) {
  Eigen::Matrix<double, 3, 9> J;
  const double cn = std::cos(nu), sn = std::sin(nu), ce = std::cos(eta), se = std::sin(eta);
  const Eigen::Vector3d u(cn * ce, sn, cn * se);
  const Eigen::Vector3d du_dnu(-sn * ce, cn, -sn * se), du_deta(-cn * se, 0.0, cn * ce);
  const Eigen::Matrix3d Rx = rot_x(rpy_MV.roll), Ry = rot_y(rpy_MV.pitch), Rz = rot_z(rpy_MV.yaw);
  const Eigen::Matrix3d R_MV = order == RpyOrder::kXyz ? Eigen::Matrix3d(Rx * Ry * Rz) : Eigen::Matrix3d(Rz * Ry * Rx);
  const Eigen::Matrix3d R_MN = R_MV * T_V_N.linear();
  J.col(0) = R_MN * u;
  J.col(1) = R_MN * (r * du_dnu);
  J.col(2) = R_MN * (r * du_deta);
  J.block<3, 3>(0, 3).setIdentity();
  // d/d(angle) of a product of elementary rotations: d Rk(a)/da = Rk(a) [e_k]x.
  const Eigen::Vector3d p_V = T_V_N * (r * u);
  if (order == RpyOrder::kXyz) {  // R = Rx Ry Rz
    J.col(6) = Rx * cross_axis(0, Ry * Rz * p_V);
    J.col(7) = Rx * Ry * cross_axis(1, Rz * p_V);
    J.col(8) = Rx * Ry * Rz * cross_axis(2, p_V);
  } else {  // R = Rz Ry Rx
    J.col(8) = Rz * cross_axis(2, Ry * Rx * p_V);
    J.col(7) = Rz * Ry * cross_axis(1, Rx * p_V);
    J.col(6) = Rz * Ry * Rx * cross_axis(0, p_V);
  }
  return J;
}

Eigen::Matrix3d point_covariance(double r, double nu, double eta, const Eigen::Isometry3d& T_V_N, const Rpy& rpy_MV,
                                 RpyOrder order, const PointSigmas& s) {
  const Eigen::Matrix<double, 3, 9> J = chain_jacobian(r, nu, eta, T_V_N, rpy_MV, order);
  Eigen::Matrix<double, 9, 1> var;
  var << s.range * s.range, s.bearing * s.bearing, s.nod * s.nod, s.position.cwiseProduct(s.position),
      s.rpy.cwiseProduct(s.rpy);
  return J * var.asDiagonal() * J.transpose();
}

Eigen::Matrix3d point_covariance_fast(double r, double cn, double sn, double ce, double se, const Eigen::Matrix3d& R_MV,
                                      const Eigen::Isometry3d& T_V_N, RpyOrder order, const PointSigmas& s) {
  const Eigen::Matrix3d R_MN = R_MV * T_V_N.linear();
  const Eigen::Vector3d Rp = R_MV * (T_V_N * Eigen::Vector3d(r * cn * ce, r * sn, r * cn * se));
  return point_covariance_fast(r, cn, sn, ce, se, R_MV, T_V_N, R_MN, Rp, order, s);
}

Eigen::Matrix3d point_covariance_fast(double r, double cn, double sn, double ce, double se, const Eigen::Matrix3d& R_MV,
                                      const Eigen::Isometry3d& T_V_N, const Eigen::Matrix3d& R_MN,
                                      const Eigen::Vector3d& Rp, RpyOrder order, const PointSigmas& s) {
  // The pose-angle axes in the map frame (outer, middle, inner); the middle one is normal to the
  // other two: xyz: e_x, Rx e_y, R e_z (inner x e_x = (0, i_z, -i_y));
  // zyx: e_z, Rz e_y, R e_x (e_z x inner = (-i_y, i_x, 0)).
  const bool xyz = order == RpyOrder::kXyz;
  const Eigen::Vector3d inner = xyz ? Eigen::Vector3d(R_MV.col(2)) : Eigen::Vector3d(R_MV.col(0));
  Eigen::Vector3d middle = xyz ? Eigen::Vector3d(0.0, inner.z(), -inner.y()) : Eigen::Vector3d(-inner.y(), inner.x(), 0.0);
  const double nm = middle.norm();
  if (nm < 1e-6) {  // gimbal lock: the middle axis is undefined; take the angle path
    const Rpy rpy = matrix_to_rpy(R_MV, order);
    return point_covariance(r, std::atan2(sn, cn), std::atan2(se, ce), T_V_N, rpy, order, s);
  }
  middle /= nm;

  // C = J diag(sigma^2) J^T as a sum of rank-1 terms, one per error source, each column of J
  // written as a unit vector times a scale (only the 6 distinct entries are accumulated).
  // Measurement columns: with w = R_MN (ce, 0, se) and the columns c0, c1, c2 of R_MN,
  //   d p / d r   = U            = cn w + sn c1        (the beam direction)
  //   d p / d nu  = r E_nu       = r (-sn w + cn c1)
  //   d p / d eta = r cn E_eta   = r cn (-se c0 + ce c2)
  // Pose-angle columns: d p / d angle_k = a_k x Rp (a_k the k-th rotation axis in the map frame).
  double c00 = 0, c01 = 0, c02 = 0, c11 = 0, c12 = 0, c22 = 0;
  const auto add = [&](double vx, double vy, double vz, double var) {
    const double wx = var * vx, wy = var * vy;
    c00 += wx * vx;
    c01 += wx * vy;
    c02 += wx * vz;
    c11 += wy * vy;
    c12 += wy * vz;
    c22 += var * vz * vz;
  };
  const Eigen::Vector3d c0 = R_MN.col(0), c1 = R_MN.col(1), c2 = R_MN.col(2);
  const Eigen::Vector3d w = ce * c0 + se * c2;
  const Eigen::Vector3d U = cn * w + sn * c1, Enu = cn * c1 - sn * w, Eeta = ce * c2 - se * c0;
  add(U.x(), U.y(), U.z(), s.range * s.range);
  add(Enu.x(), Enu.y(), Enu.z(), r * r * s.bearing * s.bearing);
  add(Eeta.x(), Eeta.y(), Eeta.z(), r * r * cn * cn * s.nod * s.nod);
  // Variances of roll, pitch, yaw and their axes: xyz: roll outer (e_x), yaw inner;
  // zyx: roll inner, yaw outer (e_z).
  const double v_outer = xyz ? s.rpy.x() * s.rpy.x() : s.rpy.z() * s.rpy.z();
  const double v_inner = xyz ? s.rpy.z() * s.rpy.z() : s.rpy.x() * s.rpy.x();
  const double v_middle = s.rpy.y() * s.rpy.y();
  if (xyz)
    add(0.0, -Rp.z(), Rp.y(), v_outer);  // e_x x Rp
  else
    add(-Rp.y(), Rp.x(), 0.0, v_outer);  // e_z x Rp
  const Eigen::Vector3d jm = middle.cross(Rp), ji = inner.cross(Rp);
  add(jm.x(), jm.y(), jm.z(), v_middle);
  add(ji.x(), ji.y(), ji.z(), v_inner);
  Eigen::Matrix3d C;
  C << c00 + s.position.x() * s.position.x(), c01, c02,  //
      c01, c11 + s.position.y() * s.position.y(), c12,  // the position columns are the identity
      c02, c12, c22 + s.position.z() * s.position.z();
  return C;
}

}  // namespace pcdp
