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
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ez = Eigen::Vector3d::UnitZ();
  // The outer and inner axes in the map frame; the middle one is normal to both.
  const Eigen::Vector3d outer = order == RpyOrder::kXyz ? ex : ez;
  const Eigen::Vector3d inner = order == RpyOrder::kXyz ? Eigen::Vector3d(R_MV.col(2)) : Eigen::Vector3d(R_MV.col(0));
  Eigen::Vector3d middle = order == RpyOrder::kXyz ? inner.cross(outer) : outer.cross(inner);
  const double nm = middle.norm();
  if (nm < 1e-6) {  // gimbal lock: the middle axis is undefined; take the angle path
    const Rpy rpy = matrix_to_rpy(R_MV, order);
    return point_covariance(r, std::atan2(sn, cn), std::atan2(se, ce), T_V_N, rpy, order, s);
  }
  middle /= nm;
  const Eigen::Vector3d u(cn * ce, sn, cn * se);
  const Eigen::Matrix3d R_MN = R_MV * T_V_N.linear();
  const Eigen::Vector3d Rp = R_MV * (T_V_N * (r * u));
  Eigen::Matrix3d Jm;  // the measurement columns (r, nu, eta)
  Jm.col(0) = R_MN * u;
  Jm.col(1) = R_MN * Eigen::Vector3d(-r * sn * ce, r * cn, -r * sn * se);
  Jm.col(2) = R_MN * Eigen::Vector3d(-r * cn * se, 0.0, r * cn * ce);
  Eigen::Matrix3d Ja;  // the pose-angle columns, in the order roll, pitch, yaw
  if (order == RpyOrder::kXyz) {  // R = Rx(roll) Ry(pitch) Rz(yaw)
    Ja.col(0) = outer.cross(Rp);
    Ja.col(1) = middle.cross(Rp);
    Ja.col(2) = inner.cross(Rp);
  } else {  // R = Rz(yaw) Ry(pitch) Rx(roll)
    Ja.col(0) = inner.cross(Rp);
    Ja.col(1) = middle.cross(Rp);
    Ja.col(2) = outer.cross(Rp);
  }
  const Eigen::Vector3d vm(s.range * s.range, s.bearing * s.bearing, s.nod * s.nod);
  const Eigen::Vector3d va = s.rpy.cwiseProduct(s.rpy);
  Eigen::Matrix3d C = Jm * vm.asDiagonal() * Jm.transpose() + Ja * va.asDiagonal() * Ja.transpose();
  C.diagonal() += s.position.cwiseProduct(s.position);  // the position columns are the identity
  return C;
}

}  // namespace pcdp
