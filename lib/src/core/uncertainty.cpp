#include "pcdp/core/uncertainty.hpp"

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

CovarianceLanes::CovarianceLanes(RpyOrder order, const PointSigmas& s) : xyz_(order == RpyOrder::kXyz) {
  var_range_ = static_cast<float>(s.range * s.range);
  var_bearing_ = static_cast<float>(s.bearing * s.bearing);
  // roll outer (e_x) and yaw inner for xyz; roll inner and yaw outer (e_z) for zyx.
  var_outer_ = static_cast<float>(xyz_ ? s.rpy.x() * s.rpy.x() : s.rpy.z() * s.rpy.z());
  var_inner_ = static_cast<float>(xyz_ ? s.rpy.z() * s.rpy.z() : s.rpy.x() * s.rpy.x());
  var_middle_ = static_cast<float>(s.rpy.y() * s.rpy.y());
  for (int k = 0; k < 3; ++k) var_pos_[k] = static_cast<float>(s.position[k] * s.position[k]);
}

void CovarianceLanes::compute(const float* in, float* res, std::size_t stride, std::size_t n) const {
  // point_covariance_fast's sum of rank-1 terms, lane by lane. The loop runs over whole groups of
  // 16 lanes, so every lane goes through the vector body (none through a scalar remainder).
  n = (n + kGroup - 1) / kGroup * kGroup;
  const float vr = var_range_, vb = var_bearing_, vo = var_outer_, vm = var_middle_, vi = var_inner_;
  const float vpx = var_pos_[0], vpy = var_pos_[1], vpz = var_pos_[2];  // the position columns are the identity
  const float ox = xyz_ ? 1.0f : 0.0f, oz = xyz_ ? 0.0f : 1.0f;  // the outer axis: e_x or e_z
  const auto at = [&](int k) { return in + static_cast<std::size_t>(k) * stride; };
  const float *pr = at(kR), *pcn = at(kCn), *psn = at(kSn), *pce = at(kCe), *pse = at(kSe), *pvn = at(kVarNod);
  const float *p00 = at(kR00), *p10 = at(kR10), *p20 = at(kR20), *p01 = at(kR01), *p11 = at(kR11), *p21 = at(kR21);
  const float *p02 = at(kR02), *p12 = at(kR12), *p22 = at(kR22);
  const float *pix = at(kIx), *piy = at(kIy), *piz = at(kIz), *ppx = at(kPx), *ppy = at(kPy), *ppz = at(kPz);
  float *r0 = res, *r1 = res + stride, *r2 = res + 2 * stride, *r3 = res + 3 * stride, *r4 = res + 4 * stride,
        *r5 = res + 5 * stride;
  // The rows never overlap (in and res are distinct arrays): no alias checks needed. (GCC did
  // not vectorise this loop with the pointers declared __restrict.)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
  for (std::size_t j = 0; j < n; ++j) {
    const float r = pr[j], cn = pcn[j], sn = psn[j], ce = pce[j], se = pse[j];
    const float c0x = p00[j], c0y = p10[j], c0z = p20[j];
    const float c1x = p01[j], c1y = p11[j], c1z = p21[j];
    const float c2x = p02[j], c2y = p12[j], c2z = p22[j];
    const float wx = ce * c0x + se * c2x, wy = ce * c0y + se * c2y, wz = ce * c0z + se * c2z;
    const float ux = cn * wx + sn * c1x, uy = cn * wy + sn * c1y, uz = cn * wz + sn * c1z;
    const float bx = cn * c1x - sn * wx, by = cn * c1y - sn * wy, bz = cn * c1z - sn * wz;
    const float ex = ce * c2x - se * c0x, ey = ce * c2y - se * c0y, ez = ce * c2z - se * c0z;
    const float rr = r * r;
    const float v_b = rr * vb, v_e = rr * cn * cn * pvn[j];
    const float ix = pix[j], iy = piy[j], iz = piz[j];
    const float px = ppx[j], py = ppy[j], pz = ppz[j];
    // outer x Rp; middle = outer x inner (not normalised: its variance is divided by |middle|^2).
    const float jox = -oz * py, joy = oz * px - ox * pz, joz = ox * py;
    const float mx = -oz * iy, my = oz * ix - ox * iz, mz = ox * iy;
    const float v_m = vm / (mx * mx + my * my + mz * mz);
    const float jmx = my * pz - mz * py, jmy = mz * px - mx * pz, jmz = mx * py - my * px;
    const float jix = iy * pz - iz * py, jiy = iz * px - ix * pz, jiz = ix * py - iy * px;
    r0[j] = (vr * ux * ux + v_b * bx * bx + v_e * ex * ex + vo * jox * jox + v_m * jmx * jmx + vi * jix * jix) + vpx;
    r1[j] = vr * ux * uy + v_b * bx * by + v_e * ex * ey + vo * jox * joy + v_m * jmx * jmy + vi * jix * jiy;
    r2[j] = vr * ux * uz + v_b * bx * bz + v_e * ex * ez + vo * jox * joz + v_m * jmx * jmz + vi * jix * jiz;
    r3[j] = (vr * uy * uy + v_b * by * by + v_e * ey * ey + vo * joy * joy + v_m * jmy * jmy + vi * jiy * jiy) + vpy;
    r4[j] = vr * uy * uz + v_b * by * bz + v_e * ey * ez + vo * joy * joz + v_m * jmy * jmz + vi * jiy * jiz;
    r5[j] = (vr * uz * uz + v_b * bz * bz + v_e * ez * ez + vo * joz * joz + v_m * jmz * jmz + vi * jiz * jiz) + vpz;
  }
}

}  // namespace pcdp
