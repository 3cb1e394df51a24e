#include "pcdp/occlusion_model.hpp"

#include <algorithm>
#include <cmath>

namespace pcdp {

namespace {
constexpr double kPi = 3.14159265358979323846;

/// eq. 14 with X1 computed once (profile_minimum evaluates it hundreds of times per edge).
double profile_at(const EdgeParams& e, double x, double x1v, double scale2) {
  const double a1 = e.d1 * e.alpha;
  if (a1 <= 0.0) return x < 0 ? e.p1 : e.p2;  // a pencil beam: a step
  const double on1 = 1.0 - disk_fraction(x / a1);
  const double seen2 = disk_fraction((x - x1v) / scale2);
  return e.p1 * on1 + e.p2 * seen2;
}

double profile(const EdgeParams& e, double x, double scale2) { return profile_at(e, x, x1(e), scale2); }
}  // namespace

double disk_fraction(double u) {
  if (u <= 0.0) return 0.0;
  if (u >= 1.0) return 1.0;
  // (th - sin(2 th) / 2) / pi with cos(th) = c: sin(2 th) / 2 = sin(th) cos(th) = c sqrt(1 - c^2).
  const double c = 1.0 - 2.0 * u;
  return (std::acos(c) - c * std::sqrt(std::max(0.0, 1.0 - c * c))) / kPi;
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
  const double x1v = x1(e), scale2 = e.d1 * e.alpha;
  const auto amp = [&](double x) { return profile_at(e, x, x1v, scale2); };
  // Where the minimum can be: before X1 only the near target's lit part shrinks (the profile
  // falls), after X2 only the far target's visible part grows (it rises); the paper puts it in
  // [X1, 2 r1] (eqs. 17, 18). So [max(0, X1), X2] is searched: a coarse grid on that interval,
  // which is d1 alpha wide whatever the separation, finds the dip's basin (16 cells: the property
  // test checks it against a dense scan of [0, X2] on 2000 random edges), golden section refines.
  const double hi = std::max(x1v + scale2, 1e-12);  // X2
  const double lo0 = std::clamp(x1v, 0.0, hi);
  constexpr int kGrid = 16;
  ProfileMinimum best{lo0, amp(lo0)};
  if (lo0 > 0.0) {  // the start of the interval searched before (the pencil-beam case)
    const double a0 = amp(0.0);
    if (a0 < best.amplitude) best = {0.0, a0};
  }
  const double cell = (hi - lo0) / kGrid;
  for (int i = 1; i <= kGrid; ++i) {
    const double x = lo0 + cell * i;
    const double a = amp(x);
    if (a < best.amplitude) best = {x, a};
  }
  // Golden-section refinement around the best grid point.
  double lo = std::max(0.0, best.x - cell), up = std::min(hi, best.x + cell);
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int it = 0; it < 30; ++it) {
    const double a = up - g * (up - lo), b = lo + g * (up - lo);
    if (amp(a) < amp(b))
      up = b;
    else
      lo = a;
  }
  const double xm = 0.5 * (lo + up);
  const double am = amp(xm);
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
