#include "pcdp/occlusion_model.hpp"

#include <algorithm>
#include <cmath>

namespace pcdp {

namespace {
constexpr double kPi = 3.14159265358979323846;

double profile(const EdgeParams& e, double x, double scale2) {
  const double a1 = e.d1 * e.alpha;
  if (a1 <= 0.0) return x < 0 ? e.p1 : e.p2;  // a pencil beam: a step
  const double on1 = 1.0 - disk_fraction(x / a1);
  const double seen2 = disk_fraction((x - x1(e)) / scale2);
  return e.p1 * on1 + e.p2 * seen2;
}
}  // namespace

double disk_fraction(double u) {
  if (u <= 0.0) return 0.0;
  if (u >= 1.0) return 1.0;
  const double th = std::acos(1.0 - 2.0 * u);
  return (th - std::sin(2.0 * th) / 2.0) / kPi;
}

double effective_separation(const EdgeParams& e) { return e.separation * std::cos(e.theta); }

double x1(const EdgeParams& e) {
  const double s = effective_separation(e);
  return s > 0.0 && e.d2 > e.d1 ? s * (e.d2 - e.d1) / e.d2 : 0.0;
}

double x2(const EdgeParams& e) { return x1(e) + e.d1 * e.alpha; }

double amplitude_at(const EdgeParams& e, double x) { return profile(e, x, e.d1 * e.alpha); }

double amplitude_as_printed(const EdgeParams& e, double x) { return profile(e, x, e.d2 * e.alpha); }

ProfileMinimum profile_minimum(const EdgeParams& e) {
  // The minimum lies in [X1, 2 r1] (eqs. 17, 18); search [0, X2] to be safe for any input.
  const double hi = std::max(x2(e), 1e-12);
  constexpr int kGrid = 400;
  ProfileMinimum best{0.0, amplitude_at(e, 0.0)};
  for (int i = 1; i <= kGrid; ++i) {
    const double x = hi * i / kGrid;
    const double a = amplitude_at(e, x);
    if (a < best.amplitude) best = {x, a};
  }
  // Golden-section refinement around the best grid point.
  double lo = std::max(0.0, best.x - hi / kGrid), up = std::min(hi, best.x + hi / kGrid);
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int it = 0; it < 60; ++it) {
    const double a = up - g * (up - lo), b = lo + g * (up - lo);
    if (amplitude_at(e, a) < amplitude_at(e, b))
      up = b;
    else
      lo = a;
  }
  const double xm = 0.5 * (lo + up);
  const double am = amplitude_at(e, xm);
  if (am < best.amplitude) best = {xm, am};
  return best;
}

std::vector<std::pair<double, double>> amplitude_profile(const EdgeParams& e, int n) {
  std::vector<std::pair<double, double>> out;
  const double span = std::max(x2(e), 1e-6);
  for (int i = 0; i < n; ++i) {
    const double x = -0.2 * span + 1.4 * span * i / std::max(1, n - 1);
    out.emplace_back(x, amplitude_at(e, x));
  }
  return out;
}

std::vector<std::pair<double, double>> minimum_vs_theta(EdgeParams e, int n) {
  std::vector<std::pair<double, double>> out;
  const double base = e.separation;
  for (int i = 0; i < n; ++i) {
    const double th = -kPi + 2.0 * kPi * i / std::max(1, n - 1);
    e.theta = 0.0;
    e.separation = base * std::fabs(std::cos(th));
    out.emplace_back(th, profile_minimum(e).amplitude);
  }
  return out;
}

}  // namespace pcdp
