#include "pcdp/models/mixing_model.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace pcdp {

double mixture_range(double f, double d1, double p1, double d2, double p2) {
  const double a = f * p1 + (1 - f) * p2;
  return a > 0 ? (f * p1 * d1 + (1 - f) * p2 * d2) / a : NAN;
}

double mixture_amplitude(double f, double p1, double p2) { return f * p1 + (1 - f) * p2; }

double mixture_share(double r, double d1, double p1, double d2, double p2) {
  if (!(d2 > d1) || !(r >= d1 && r <= d2) || !(p1 > 0) || !(p2 > 0)) return NAN;
  const double w = (d2 - r) / (d2 - d1);  // power share of the near surface
  // w = f p1 / (f p1 + (1 - f) p2)  =>  f = w p2 / (w p2 + (1 - w) p1)
  return w * p2 / (w * p2 + (1 - w) * p1);
}

double mixture_amplitude_at(double r, double d1, double p1, double d2, double p2) {
  if (!(d2 > d1) || !(p1 > 0) || !(p2 > 0) || std::isnan(r)) return NAN;
  const double rc = std::clamp(r, d1, d2);
  // 1 / (w / p1 + (1 - w) / p2) with w = (d2 - r) / (d2 - d1), without dividing twice.
  return p1 * p2 * (d2 - d1) / (p2 * (d2 - rc) + p1 * (rc - d1));
}

double range_on_line(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, double* miss) {
  if (miss) *miss = NAN;
  Eigen::Vector3d e = b - a;
  const double len = e.norm();
  if (!(len > 1e-9)) return NAN;
  e /= len;
  const double c = dir.dot(e);
  const double den = 1.0 - c * c;  // sin^2 of the angle between ray and line
  if (!(den >= 1e-4)) return NAN;
  const Eigen::Vector3d w0 = origin - a;
  const double dw = dir.dot(w0), ew = e.dot(w0);
  const double t = (c * ew - dw) / den;  // along the ray
  if (miss) *miss = (w0 + t * dir - ((ew - c * dw) / den) * e).norm();
  return t;
}

double range_on_plane(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& point,
                      const Eigen::Vector3d& normal) {
  const double c = normal.dot(dir);  // cosine of the incidence
  if (!(std::fabs(c) >= 1e-7)) return NAN;
  return normal.dot(point - origin) / c;
}

}  // namespace pcdp
