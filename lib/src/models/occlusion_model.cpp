#include "pcdp/models/occlusion_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pcdp {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

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

namespace {
/// The search of profile_minimum; it stops at the first amplitude found below `stop_below` (the
/// minimum is then below it too), so a caller that asks only whether the profile dips under a
/// level gets the same answer without the refinement.
ProfileMinimum search_minimum(const EdgeParams& e, double stop_below) {
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
  if (best.amplitude < stop_below) return best;
  if (lo0 > 0.0) {  // the start of the interval searched before (the pencil-beam case)
    const double a0 = amp(0.0);
    if (a0 < best.amplitude) best = {0.0, a0};
    if (best.amplitude < stop_below) return best;
  }
  const double cell = (hi - lo0) / kGrid;
  for (int i = 1; i <= kGrid; ++i) {
    const double x = lo0 + cell * i;
    const double a = amp(x);
    if (a < best.amplitude) best = {x, a};
    if (best.amplitude < stop_below) return best;
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
}  // namespace

ProfileMinimum profile_minimum(const EdgeParams& e) { return search_minimum(e, -kInfinity); }

double profile_lower_bound(const EdgeParams& e) {
  // The profile is p1 (1 - F(x / a1)) + p2 F((x - X1) / a1), F the disk fraction (increasing from
  // 0 to 1), a1 = d1 alpha. Both weights are at least m = min(p1, p2), so it is at least
  // m (1 - (F(u + c) - F(u))) with c = X1 / a1, u = (x - X1) / a1: one minus the rise of F over a
  // window of width c. F's slope is symmetric about 1/2 and largest there, so the rise is at most
  // that of the centred window, F(1/2 + c/2) - F(1/2 - c/2) = 2 F(1/2 + c/2) - 1. (Before X1,
  // where only the near target's share falls, the profile is p1 (1 - F(x / a1)) >= p1 (1 - F(c)),
  // which is above the same bound for c in [0, 1].) With c >= 1 the far target can be hidden
  // entirely: no bound but 0.
  const double a1 = e.d1 * e.alpha;
  if (!(a1 > 0.0)) return 0.0;
  const double c = std::min(1.0, x1(e) / a1);
  return std::max(0.0, std::min(e.p1, e.p2) * (2.0 - 2.0 * disk_fraction(0.5 + 0.5 * c)));
}

bool profile_dips_below(const EdgeParams& e, double level) {
  // Most edges a scan meets come nowhere near the level (a small separation, bright sides): the
  // bound settles them without the search. The margin keeps rounding from deciding.
  if (profile_lower_bound(e) > level + 1e-9 * (1.0 + std::fabs(level))) return false;
  return search_minimum(e, level).amplitude < level;
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
