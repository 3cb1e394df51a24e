#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pcdp/core/uncertainty.hpp"

using namespace pcdp;

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;

Eigen::Vector3d chain(const Eigen::Matrix<double, 9, 1>& q, const Eigen::Isometry3d& T_V_N, RpyOrder order) {
  const Eigen::Isometry3d T_M_V = make_transform(q.segment<3>(3), {q[6], q[7], q[8]}, order);
  return T_M_V * (T_V_N * nod_frame_point(q[0], q[1], q[2]));
}
}  // namespace

TEST(Uncertainty, AnalyticJacobianMatchesNumericDifferentiation) {
  const Eigen::Isometry3d T_V_N = make_transform({0.5, 0.1, 1.64}, {0.02, 0.19775, -0.03}, RpyOrder::kXyz);
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    Eigen::Matrix<double, 9, 1> q;
    q << 12.0, 0.4, -0.2, 3.0, -1.0, 0.3, 0.05, -0.04, 1.2;
    const auto J = chain_jacobian(q[0], q[1], q[2], T_V_N, {q[6], q[7], q[8]}, order);
    for (int k = 0; k < 9; ++k) {
      Eigen::Matrix<double, 9, 1> a = q, b = q;
      a[k] += 1e-6;
      b[k] -= 1e-6;
      const Eigen::Vector3d num = (chain(a, T_V_N, order) - chain(b, T_V_N, order)) / 2e-6;
      EXPECT_LT((num - J.col(k)).norm(), 1e-5) << "parameter " << k;
    }
  }
}

TEST(Uncertainty, PropagatedCovarianceAgreesWithMonteCarlo) {
  // Every error source at once: range (Gaussian), bearing and encoder quantization (uniform),
  // position and roll/pitch/yaw (Gaussian). 10^4 samples per case; the standard deviation along
  // each axis agrees within 10 %.
  const Eigen::Isometry3d T_V_N = make_transform({0.5, 0.0, 1.64}, {0.0, 0.19775, 0.0}, RpyOrder::kXyz);
  const Rpy rpy{0.03, -0.02, 0.7};
  const Eigen::Vector3d pos(10.0, -4.0, 0.5);
  PointSigmas s;
  s.range = 0.0053;
  const double bearing_res = 0.5 * kDeg, enc_res = 0.072 * kDeg;
  s.bearing = quantization_sigma(bearing_res);
  s.nod = quantization_sigma(enc_res);
  s.position = Eigen::Vector3d::Constant(0.005);
  s.rpy = Eigen::Vector3d::Constant(0.00035 * 5);
  std::mt19937_64 rng(42);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (double r : {2.0, 10.0, 25.0}) {
    for (double eta : {-0.4, 0.0, 0.3}) {
      const double nu = 0.6;
      const Eigen::Matrix3d C = point_covariance(r, nu, eta, T_V_N, rpy, RpyOrder::kXyz, s);
      constexpr int N = 10000;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
      for (int k = 0; k < N; ++k) {
        Eigen::Matrix<double, 9, 1> q;
        q << r + s.range * g(rng), nu + bearing_res * u(rng), eta + enc_res * u(rng), pos.x() + 0.005 * g(rng),
            pos.y() + 0.005 * g(rng), pos.z() + 0.005 * g(rng), rpy.roll + s.rpy[0] * g(rng), rpy.pitch + s.rpy[1] * g(rng),
            rpy.yaw + s.rpy[2] * g(rng);
        const Eigen::Vector3d p = chain(q, T_V_N, RpyOrder::kXyz);
        mean += p;
        sq += p.cwiseProduct(p);
      }
      mean /= N;
      const Eigen::Vector3d sd = (sq / N - mean.cwiseProduct(mean)).cwiseSqrt();
      for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(sd[a], std::sqrt(C(a, a)), 0.1 * std::sqrt(C(a, a))) << "r " << r << " eta " << eta << " axis " << a;
    }
  }
}

TEST(Uncertainty, ReproducesBrotenColliersSmallAngleEstimate) {
  // Orientation error only, equal in roll, pitch and yaw, beam straight ahead: roll turns about
  // the beam and moves nothing, pitch and yaw each move the point r * d_eps: sqrt(2) r d_eps.
  PointSigmas s;
  for (double deg : {1.0, 3.0, 6.0}) {
    s.rpy = Eigen::Vector3d::Constant(deg * kDeg);
    for (double r : {1.0, 10.0, 30.0}) {
      const Eigen::Matrix3d C = point_covariance(r, 0.0, 0.0, Eigen::Isometry3d::Identity(), {}, RpyOrder::kXyz, s);
      EXPECT_NEAR(std::sqrt(C.trace()), broten_collier_orientation_error(r, deg * kDeg), 1e-9);
    }
  }
  // Table 1 of the report lists 0.19 m at 1 m and 1 degree, which is sqrt(2 r d_eps); the formula
  // (and this propagation) gives 0.025 m.
  EXPECT_NEAR(broten_collier_orientation_error(1.0, kDeg), 0.0247, 1e-4);
  EXPECT_NEAR(std::sqrt(2.0 * 1.0 * kDeg), 0.19, 0.005);
}

TEST(Uncertainty, FastCovarianceEqualsTheAnglePath) {
  // point_covariance_fast (axes from R_MV, cached sines) against point_covariance (roll, pitch,
  // yaw and elementary rotations) on random returns, poses, mounts and both RPY orders.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 2000; ++k) {
    const RpyOrder order = k % 2 ? RpyOrder::kXyz : RpyOrder::kZyx;
    const Rpy rpy{1.5 * u(rng), 1.4 * u(rng), 3.1 * u(rng)};
    const Eigen::Isometry3d T_V_N = make_transform(Eigen::Vector3d(u(rng), u(rng), 1 + u(rng)), Rpy{0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)}, order);
    const double r = 1.0 + 20.0 * (u(rng) + 1.0), nu = 1.6 * u(rng), eta = 0.8 * u(rng);
    PointSigmas s;
    s.range = 0.005;
    s.bearing = 0.001 * (1 + u(rng));
    s.nod = 0.0004;
    s.position = Eigen::Vector3d(0.01, 0.02, 0.03);
    s.rpy = Eigen::Vector3d(0.001, 0.002, 0.003);
    const Eigen::Matrix3d a = point_covariance(r, nu, eta, T_V_N, rpy, order, s);
    const Eigen::Matrix3d b = point_covariance_fast(r, std::cos(nu), std::sin(nu), std::cos(eta), std::sin(eta),
                                                    rpy_to_matrix(rpy, order), T_V_N, order, s);
    EXPECT_LT((a - b).norm(), 1e-9 * a.norm()) << k;
  }
  // Gimbal lock: pitch at 90 degrees takes the angle path and stays finite.
  const Rpy lock{0.2, 1.5707963267948966, 0.1};
  PointSigmas s;
  s.rpy = Eigen::Vector3d::Constant(0.001);
  const Eigen::Matrix3d c = point_covariance_fast(5, 1, 0, 1, 0, rpy_to_matrix(lock, RpyOrder::kXyz),
                                                  Eigen::Isometry3d::Identity(), RpyOrder::kXyz, s);
  EXPECT_TRUE(c.allFinite());
}

TEST(Uncertainty, CovarianceLanesEqualTheAnglePath) {
  // The single-precision lane kernel against point_covariance (double, roll/pitch/yaw), on
  // random returns, poses and mounts, both RPY orders, a lane count that is not a whole number of
  // groups (the lanes past it are computed and must not be written); each lane's result lands in
  // its own column.
  using L = CovarianceLanes;
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (RpyOrder order : {RpyOrder::kXyz, RpyOrder::kZyx}) {
    PointSigmas s;
    s.range = 0.0053;
    s.bearing = 0.0025;
    s.position = Eigen::Vector3d(0.01, 0.02, 0.03);
    s.rpy = Eigen::Vector3d(0.001, 0.002, 0.003);
    const L lanes(order, s);
    const std::size_t n = 5 * L::kGroup + 7, stride = 6 * L::kGroup + 3;
    std::vector<float> in(L::kInputs * stride, 0.0f), res(6 * stride, -1.0f);
    std::vector<Eigen::Matrix3d> want(n);
    for (std::size_t j = 0; j < n; ++j) {
      const Rpy rpy{1.5 * u(rng), 1.4 * u(rng), 3.1 * u(rng)};
      const Eigen::Isometry3d T_V_N = make_transform(Eigen::Vector3d(u(rng), u(rng), 1 + u(rng)), Rpy{0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)}, order);
      const double r = 1.0 + 20.0 * (u(rng) + 1.0), nu = 1.6 * u(rng), eta = 0.8 * u(rng);
      PointSigmas si = s;
      si.nod = 0.0004 * (1.5 + u(rng));
      want[j] = point_covariance(r, nu, eta, T_V_N, rpy, order, si);
      const Eigen::Matrix3d R_MV = rpy_to_matrix(rpy, order), R_MN = R_MV * T_V_N.linear();
      const Eigen::Vector3d inner = R_MV.col(inner_pose_axis(order));
      const Eigen::Vector3d Rp = R_MV * (T_V_N * nod_frame_point(r, nu, eta));
      ASSERT_GE(lanes.middle_norm2(inner.x(), inner.y(), inner.z()), L::kGimbalLock);
      const double v[L::kInputs] = {r, std::cos(nu), std::sin(nu), std::cos(eta), std::sin(eta), si.nod * si.nod,
                                    R_MN(0, 0), R_MN(1, 0), R_MN(2, 0), R_MN(0, 1), R_MN(1, 1), R_MN(2, 1),
                                    R_MN(0, 2), R_MN(1, 2), R_MN(2, 2), inner.x(), inner.y(), inner.z(),
                                    Rp.x(), Rp.y(), Rp.z()};
      for (int k = 0; k < L::kInputs; ++k) in[k * stride + j] = static_cast<float>(v[k]);
    }
    lanes.compute(in.data(), res.data(), stride, n);
    double worst = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      const Eigen::Matrix3d& C = want[j];
      const double e[6] = {C(0, 0), C(0, 1), C(0, 2), C(1, 1), C(1, 2), C(2, 2)};
      for (int k = 0; k < 6; ++k) worst = std::max(worst, std::fabs(res[k * stride + j] - e[k]) / C.norm());
    }
    // Single precision: a few 1e-7 of the norm. A wrong axis, sign or variance is off by 1e-3 or more.
    EXPECT_LT(worst, 2e-6) << rpy_order_name(order);
    // Whole groups are computed (6 groups here), nothing past them.
    for (int k = 0; k < 6; ++k) EXPECT_EQ(res[k * stride + 6 * L::kGroup], -1.0f);
  }
  // Gimbal lock: the middle axis vanishes (the caller takes the angle path).
  PointSigmas s;
  const L lanes(RpyOrder::kXyz, s);
  const Eigen::Matrix3d lock = rpy_to_matrix({0.2, 1.5707963267948966, 0.1}, RpyOrder::kXyz);
  EXPECT_LT(lanes.middle_norm2(lock(0, 2), lock(1, 2), lock(2, 2)), L::kGimbalLock);
}

