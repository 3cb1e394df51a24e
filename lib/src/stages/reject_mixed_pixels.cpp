#include "pcdp/stages/reject_mixed_pixels.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/models/mixing_model.hpp"
#include "reject_mixed_pixels_detail.hpp"

namespace pcdp {

using namespace mixed_detail;

namespace {
constexpr double kPi = 3.14159265358979323846;

struct Nb {
  int count = 0;  ///< up to 2 neighbours used for the tests
  std::size_t idx[2] = {0, 0};
  double r[2] = {0, 0};
  double at[2] = {0, 0};
  double predicted = 0;
  double r3 = 0, at3 = 0;  ///< a third neighbour, for the side's acceleration
  bool has3 = false;
  bool beside_void = false;  ///< the next position on this side holds no usable return (not the end of the scan)
};

/// Whether the beams of returns k and i are closer than `within` (rad) in the view's scan
/// direction. Equal readings (a scanner that does not nod, an encoder's plateau) cannot say the
/// beams are close; bearings may wrap at +-pi.
bool beams_closer(const float* ang, std::size_t k, std::size_t i, double within) {
  const double d = std::fabs(static_cast<double>(ang[k]) - ang[i]);
  return d > 0 && std::min(d, 2 * kPi - d) < within;
}

/// A side's nearest returns within the window. With look_through_tol >= 0, the nearest is not one
/// whose beam lies inside the return's footprint and whose range is within look_through_tol of its.
/// With min_angle > 0, the nearest is not one whose beam lies closer than min_angle to the return's
/// (`skipped`: the farthest position passed so); the window then starts past them, up to
/// kFootprintReach positions out.
Nb neighbours(const ReturnsView& v, const std::vector<std::size_t>& seq, std::size_t pos, int dir, const MixedPixelParams& p,
              double look_through_tol = -1, double min_angle = 0, int* skipped = nullptr) {
  Nb nb;
  const float* ang = v.across ? v.across_angle : v.along_angle;
  const std::size_t self = seq[pos];
  const long next = static_cast<long>(pos) + dir;
  nb.beside_void = next >= 0 && next < static_cast<long>(seq.size()) ? !v.usable[seq[static_cast<std::size_t>(next)]]
                                                                     : v.ends_are_voids;
  int limit = p.window;
  for (int step = 1; step <= limit && !nb.has3; ++step) {
    const long q = static_cast<long>(pos) + dir * step;
    if (q < 0 || q >= static_cast<long>(seq.size())) break;
    const std::size_t k = seq[static_cast<std::size_t>(q)];
    if (!v.usable[k]) continue;
    if (nb.count == 0 && min_angle > 0 && ang && beams_closer(ang, k, self, min_angle)) {
      if (skipped) *skipped = step;
      if (step <= kFootprintReach) limit = std::max(limit, step + p.window);
      continue;
    }
    if (nb.count == 0 && look_through_tol >= 0 && ang &&
        std::fabs(static_cast<double>(v.range[k]) - v.range[self]) <= look_through_tol &&
        beams_closer(ang, k, self, 0.5 * v.divergence))
      continue;
    if (nb.count < 2) {
      nb.idx[nb.count] = k;
      nb.r[nb.count] = v.range[k];
      nb.at[nb.count] = step;
      ++nb.count;
    } else {
      nb.r3 = v.range[k];
      nb.at3 = step;
      nb.has3 = true;
    }
  }
  if (nb.count == 0) return nb;
  nb.predicted = nb.r[0];
  if (nb.count == 2) {
    const double step = std::fabs(nb.r[1] - nb.r[0]) / (nb.at[1] - nb.at[0]);
    if (step <= jump_at(p, std::min(nb.r[0], nb.r[1])))
      nb.predicted = nb.r[0] - (nb.r[1] - nb.r[0]) / (nb.at[1] - nb.at[0]) * nb.at[0];
  }
  return nb;
}

/// Whether return i lies within tol of the plane-model line through returns a and b: on the plane
/// they sample (models/mixing_model.hpp). Exact on planes at any incidence, where a linear or
/// quadratic trend in range is not (ground and step tops at grazing incidence).
bool on_plane_of(const ReturnsView& v, std::size_t i, std::size_t a, std::size_t b, double tol) {
  const Eigen::Vector3d o(v.ox[i], v.oy[i], v.oz[i]), p(v.x[i], v.y[i], v.z[i]);
  const Eigen::Vector3d d = p - o;
  const double r = d.norm();
  if (!(r > 0)) return false;
  double miss = NAN;
  const double pred = range_on_line(o, d / r, {v.x[a], v.y[a], v.z[a]}, {v.x[b], v.y[b], v.z[b]}, &miss);
  return std::fabs(r - pred) <= tol && miss <= tol;  // false for NaN: no prediction
}

/// The neighbours of return a in the other scan direction (both usable), if the view has one.
bool cross_neighbours(const ReturnsView& v, std::size_t a, std::size_t& c0, std::size_t& c1) {
  if (v.width == 0) return false;
  if (v.across) {  // neighbouring beams on a's line
    if (a % v.width == 0 || (a + 1) % v.width == 0) return false;
    c0 = a - 1;
    c1 = a + 1;
  } else {  // the same beam on the lines before and after
    if (a < v.width || a + v.width >= v.n) return false;
    c0 = a - v.width;
    c1 = a + v.width;
  }
  return v.usable[c0] && v.usable[c1];
}

/// Whether return i lies on the plane of a side's 2-D patch: the side's two nearest returns a, b
/// and a's two neighbours in the other scan direction, where the four are one plane (each of a's
/// neighbours within tol, in range, of the plane through a spanned by b - a and c1 - c0). The
/// plane predicts the range on a plane at any incidence and for any spacing of the lines (a nod
/// that speeds up or turns), where a trend through returns of one beam bends with the beam's
/// trace over the surface.
bool on_patch_of(const ReturnsView& v, std::size_t i, const Nb& nb, double tol, bool excuse_poses) {
  if (nb.count < 2) return false;
  std::size_t c0 = 0, c1 = 0;
  const std::size_t a = nb.idx[0], b = nb.idx[1];
  if (!cross_neighbours(v, a, c0, c1)) return false;
  const auto P = [&](std::size_t k) { return Eigen::Vector3d(v.x[k], v.y[k], v.z[k]); };
  const auto O = [&](std::size_t k) { return Eigen::Vector3d(v.ox[k], v.oy[k], v.oz[k]); };
  const Eigen::Vector3d pa = P(a), u = P(b) - pa, w = P(c1) - P(c0);
  // a lies between its two neighbours (not where the nod reverses and both are on one side).
  if (!(w.dot(pa - P(c0)) > 0 && w.dot(P(c1) - pa) > 0)) return false;
  Eigen::Vector3d nrm = u.cross(w);
  const double nn = nrm.norm();
  if (!(nn > 0.2 * u.norm() * w.norm())) return false;  // the two directions nearly parallel
  nrm /= nn;
  // How far return k lies past its allowance off the plane, along the normal: the range
  // tolerance along k's beam (seen along the normal it shrinks with the cosine of the incidence:
  // a grazing beam's range noise moves it little off the plane), plus, where k was registered
  // with another pose than a (another line) and `poses` says so, two poses' noise, which moves a
  // point in any direction. NaN (not on the plane) where k's beam runs along the plane.
  const auto past = [&](std::size_t k, bool poses) {
    const Eigen::Vector3d o = O(k), d = P(k) - o;
    const double r = d.norm();
    const double c = std::fabs(nrm.dot(d)) / r;
    const double ps = std::sqrt(v.pose_position_sigma * v.pose_position_sigma + r * r * v.pose_rpy_sigma * v.pose_rpy_sigma);
    return c * (std::fabs(r - range_on_plane(o, d / r, pa, nrm)) - tol) - (poses ? 3.0 * std::sqrt(2.0) * ps : 0.0);
  };
  // The patch is one plane: along a line a's neighbours are on other lines (their poses' noise is
  // allowed), across lines they are on a's line.
  if (!(past(c0, !v.across) <= 0) || !(past(c1, !v.across) <= 0)) return false;
  return past(i, v.across && excuse_poses) <= 0;
}

double angle_to(const ReturnsView& v, std::size_t i, std::size_t j) {
  const Eigen::Vector3d p(v.x[i], v.y[i], v.z[i]);
  const Eigen::Vector3d b = (p - Eigen::Vector3d(v.ox[i], v.oy[i], v.oz[i])).normalized();
  const Eigen::Vector3d s = Eigen::Vector3d(v.x[j], v.y[j], v.z[j]) - p;
  const double n = s.norm();
  if (n < 1e-12) return 0.0;
  return std::acos(std::min(1.0, std::fabs(b.dot(s)) / n));  // 0 .. pi/2
}

/// A side's amplitude: its two nearest returns if they are one surface, else the nearest alone
/// (beside a thin post the second one is the background).
double side_amp(const ReturnsView& v, const Nb& nb, const MixedPixelParams& p) {
  if (!v.amplitude) return NAN;
  if (nb.count == 1 || std::fabs(nb.r[1] - nb.r[0]) > jump_at(p, nb.r[0]))
    return v.amplitude[nb.idx[0]];
  return 0.5 * (v.amplitude[nb.idx[0]] + v.amplitude[nb.idx[1]]);
}

/// One-sided test: whether return i, beside a void on the `gap` side, breaks sharply from the
/// trend of its one visible surface `own` (a mixture with a surface too weak to return on its
/// own), rather than continuing it (a valid return at the end of a surface) or continuing the
/// surface across the void (grazing ground whose returns fade in and out near the detection
/// limit). The trend is quadratic where `own` has three adjacent returns on one smooth surface
/// (successive steps within a factor 1.5: ground at grazing incidence grows hyperbolically, and
/// a quadratic's error there stays within a quarter step), allowing a quarter of its step;
/// otherwise linear, allowing half a step per step away.
bool breaks_from_side(const ReturnsView& v, std::size_t i, const Nb& own, const Nb& gap, double tol,
                      const MixedPixelParams& p) {
  if (own.count < 2 || own.at[1] != own.at[0] + 1) return false;
  const double ri = v.range[i];
  // Beside a void the far surface's depth is unknown: any step from the own surface larger than the
  // tolerance (which holds 3 sigma of range noise) may be a mixture with it; the trend test decides.
  if (std::fabs(ri - own.r[0]) <= tol) return false;
  const double step = own.r[1] - own.r[0];
  double trend = own.r[0] - step * own.at[0], allow = 0.5 * std::fabs(step) * own.at[0];
  if (own.at[0] == 1 && own.has3 && own.at3 == 3) {
    const double step2 = own.r3 - own.r[1];
    const double ratio = std::fabs(step) / std::max(std::fabs(step2), 1e-9);
    if (step * step2 > 0 && ratio >= 1.0 / 1.5 && ratio <= 1.5) {
      trend = 3 * own.r[0] - 3 * own.r[1] + own.r3;
      allow = 0.25 * std::fabs(step);
    }
  }
  if (std::fabs(ri - trend) <= std::max(tol, allow)) return false;
  // On its own surface's plane; across lines within the noise of two lines' poses where the return
  // is as bright as that surface: a mixture with a void (a surface too weak to return) loses the
  // void's share of the power. Only where the amplitude can tell: the surface's amplitude is not
  // clipped and its lower bound, (1 - amplitude_ratio) a - amplitude_slack, is above zero.
  if (on_plane_of(v, i, own.idx[0], own.idx[1], tol)) return false;
  const double a = v.amplitude ? static_cast<double>(v.amplitude[i]) : NAN, a_own = side_amp(v, own, p);
  const bool as_bright = std::isfinite(a) && std::isfinite(a_own) && a_own < p.amplitude_saturation &&
                         a_own * (1 - p.amplitude_ratio) - p.amplitude_slack > 0 &&
                         a >= a_own * (1 - p.amplitude_ratio) - p.amplitude_slack;
  if (on_patch_of(v, i, own, tol, as_bright)) return false;
  if (on_patch_of(v, i, gap, tol, false)) return false;
  if (gap.count >= 2 && gap.at[1] == gap.at[0] + 1 && on_plane_of(v, i, gap.idx[0], gap.idx[1], tol)) return false;
  if (gap.count >= 2 && gap.at[1] == gap.at[0] + 1) {
    const double gstep = gap.r[1] - gap.r[0];
    if (std::fabs(ri - (gap.r[0] - gstep * gap.at[0])) <= std::max(tol, 0.5 * std::fabs(gstep) * gap.at[0])) return false;
  } else if (gap.count >= 1 && std::fabs(ri - gap.r[0]) <= jump_at(p, ri)) {
    return false;
  }
  return angle_to(v, i, own.idx[0]) <= p.max_angle;
}

/// Whether the return next to `pos` on side `dir` may lie inside its footprint (its beam closer than
/// the divergence; a void there may hide a nearer one past it), so that reading the side past the
/// footprint can differ from reading it plainly.
bool inside_footprint(const ReturnsView& v, const std::vector<std::size_t>& seq, std::size_t pos, int dir) {
  const long q = static_cast<long>(pos) + dir;
  if (q < 0 || q >= static_cast<long>(seq.size())) return false;
  const std::size_t k = seq[static_cast<std::size_t>(q)];
  if (!v.usable[k]) return true;
  return beams_closer(v.across ? v.across_angle : v.along_angle, k, seq[pos], v.divergence);
}

/// Beside a void past the footprint (across lines, the first round): whether return `pos`, its
/// sides read past its footprint (far_l, far_r; skipped_l, skipped_r positions read past), has
/// one side that is a surface within the span of 6 steps past the returns read past, and the
/// other a void (its first position past the returns read past was read and holds no usable
/// return: not the end of the sweep, nor beyond the search), and breaks from that surface's
/// trend as a mixture with the void does (breaks_from_side). Where the nod slows to its turns a footprint
/// spans many lines, and a ramp of mixtures between a surface and a background too weak to
/// return (a wall's top against a far, dark ground) is as deep: the returns next to the void are
/// judged beside it and the later rounds peel two more, but the ones deeper in have mixtures on
/// both sides. Along a line the footprint spans divergence / bearing step beams, which the rounds
/// peel (docs/mixed_pixels.md).
bool beside_void_past_footprint(const ReturnsView& v, const std::vector<std::size_t>& seq, std::size_t pos, const Nb& far_l,
                                int skipped_l, const Nb& far_r, int skipped_r, double tol, const MixedPixelParams& p) {
  if ((far_l.count == 0) == (far_r.count == 0)) return false;
  const bool void_right = far_l.count > 0;
  const Nb& surface = void_right ? far_l : far_r;
  const int void_skipped = void_right ? skipped_r : skipped_l;
  if (surface.at[0] - (void_right ? skipped_l : skipped_r) > p.max_span) return false;
  // The search reads at most kFootprintReach + window positions (neighbours()).
  if (void_skipped == 0 || void_skipped >= kFootprintReach + p.window) return false;
  const long first_past = static_cast<long>(pos) + (void_right ? 1 : -1) * (void_skipped + 1);
  return first_past >= 0 && first_past < static_cast<long>(seq.size()) &&
         breaks_from_side(v, seq[pos], surface, void_right ? far_r : far_l, tol, p);
}

/// Tests 1-4 (docs/mixed_pixels.md) at return i between sides l and r: the kind of edge found
/// (kNoEdge where a test fails). `skipped` positions were read past on the two sides together
/// (returns inside the footprint), which do not count against the sides' span.
char two_sided_edge(const ReturnsView& v, std::size_t i, const Nb& l, const Nb& r, int skipped, double tol,
                    const MixedPixelParams& p, bool coaxial) {
  const double ri = v.range[i];
  // Two-sided: each side needs a return; and one of them a second one, for its rate of change
  // (with one return on each side, a surface crossing the return looks like an edge).
  if (l.count == 0 || r.count == 0 || (l.count < 2 && r.count < 2)) return kNoEdge;
  // The two sides must be close: across a run of missing returns they may be different surfaces.
  if (l.at[0] + r.at[0] - skipped > p.max_span) return kNoEdge;
  // 1. An edge: the nearest neighbours on the two sides are far apart...
  const bool left_near = l.r[0] < r.r[0];
  const Nb& nr = left_near ? l : r;
  const Nb& fr = left_near ? r : l;
  if (fr.r[0] - nr.r[0] <= jump_at(p, nr.r[0])) return kNoEdge;
  // ...and much faster than each side changes on its own (grazing ground changes range by
  // comparable steps everywhere; a veil hangs between two sides that change slowly).
  // A side's own rate of change, from its two nearest returns, unless the second one lies back
  // on the other side's surface (a thin post one return wide: its "side" is post, background).
  // The rate is scaled by the side's own acceleration (ratio of its last two steps, from three
  // returns, clamped to [1, 3]): ground seen at the ends of a scan line grows hyperbolically.
  bool corner = false;
  const auto rate = [&](const Nb& nb, const Nb& other) {
    if (nb.count < 2) return 0.0;
    if (std::fabs(nb.r[1] - other.r[0]) < std::fabs(nb.r[1] - nb.r[0])) return 0.0;
    const double s1 = std::fabs(nb.r[1] - nb.r[0]) / (nb.at[1] - nb.at[0]);
    if (!nb.has3) return s1;
    const double s2 = std::fabs(nb.r3 - nb.r[1]) / (nb.at3 - nb.at[1]);
    // A corner: the side's first step is itself an edge, beyond any smooth acceleration (a face
    // seen edge-on, one return wide, then another surface); the next step stands in.
    if (nb.at3 == 3 && s1 > jump_at(p, nb.r[0]) && s1 > 3.0 * s2) {
      corner = true;
      return s2;
    }
    return s2 > 1e-9 ? s1 * std::clamp(s1 / s2, 1.0, 3.0) : s1;
  };
  const double across = (fr.r[0] - nr.r[0]) / (l.at[0] + r.at[0]);
  const double side_rate = std::max(rate(l, r), rate(r, l));
  if (across <= p.weak_edge_factor * side_rate) return kNoEdge;
  const char strength = across <= p.edge_factor * side_rate ? kWeakEdge : corner ? kCornerEdge : kStrongEdge;
  // 2. ...and the return lies strictly between them, on neither surface: not within the
  // tolerance of either side, nor of either side's linear trend (grazing ground changes range
  // quickly between lines, but smoothly, so it continues a trend; a veil continues none).
  if (!(ri > nr.r[0] + tol && ri < fr.r[0] - tol)) return kNoEdge;
  const auto on_trend = [&](const Nb& nb) {
    if (nb.count < 2) return false;
    const double extrap = nb.r[0] - (nb.r[1] - nb.r[0]) / (nb.at[1] - nb.at[0]) * nb.at[0];
    if (std::fabs(ri - extrap) <= tol) return true;
    if (on_plane_of(v, i, nb.idx[0], nb.idx[1], tol)) return true;
    if (!nb.has3) return on_patch_of(v, i, nb, tol, false);
    // Quadratic through the side's three returns (at -at0, -at1, -at3), evaluated at 0.
    const double x0 = -nb.at[0], x1 = -nb.at[1], x2 = -nb.at3;
    const double quad = nb.r[0] * (x1 * x2) / ((x0 - x1) * (x0 - x2)) + nb.r[1] * (x0 * x2) / ((x1 - x0) * (x1 - x2)) +
                        nb.r3 * (x0 * x1) / ((x2 - x0) * (x2 - x1));
    return std::fabs(ri - quad) <= tol || on_patch_of(v, i, nb, tol, false);
  };
  if (on_trend(l) || on_trend(r)) return kNoEdge;
  const double d1 = nr.predicted, d2 = fr.predicted;
  // 3. Geometry: the segment to at least one side runs along the beam (a mixture close to one
  // surface makes a wide angle with that side's neighbour, a narrow one with the other's).
  if (std::min(angle_to(v, i, nr.idx[0]), angle_to(v, i, fr.idx[0])) > p.max_angle) return kNoEdge;
  const double a = v.amplitude ? static_cast<double>(v.amplitude[i]) : NAN;
  const double p1 = side_amp(v, nr, p), p2 = side_amp(v, fr, p);
  const bool saturated = a >= p.amplitude_saturation || p1 >= p.amplitude_saturation || p2 >= p.amplitude_saturation;
  // 4. amplitude mixing (models/mixing_model.hpp); unknown where a side's amplitude is 0.
  const double pred = std::isfinite(a) && !saturated && d2 > d1 ? mixture_amplitude_at(ri, d1, p1, d2, p2) : NAN;
  if (std::isfinite(pred)) {
    if (a > pred * (1 + p.amplitude_ratio) + p.amplitude_slack) return kNoEdge;
    if (coaxial && a < pred * (1 - p.amplitude_ratio) - p.amplitude_slack) return kNoEdge;
  }
  return strength;
}
}  // namespace

void mark_mixed_pixels(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                       double range_sigma, bool coaxial, std::vector<char>& mixed) {
  for (std::size_t pos = 0; pos < seq.size(); ++pos) {
    const std::size_t i = seq[pos];
    if (!v.usable[i] || mixed[i] || (v.focus && !v.focus[i])) continue;
    const double ri = v.range[i];
    const double tol = tolerance_at(p, ri, range_sigma);
    // Most returns lie inside a surface, with returns on both sides next to them (no void beside,
    // so no one-sided test), and either close to each other (no edge across them) or with the
    // return on the line through the two nearest on one side (on that side's trend, test 2).
    // The tests below would reach the same verdict after searching the window on both sides, but
    // for the inner returns of a run of three or more mixtures at one range inside one footprint,
    // which this settles as a surface (docs/mixed_pixels.md: returns that share a footprint).
    if (pos > 0 && pos + 1 < seq.size() && v.usable[seq[pos - 1]] && v.usable[seq[pos + 1]]) {
      const double ra = v.range[seq[pos - 1]], rb = v.range[seq[pos + 1]];
      if (std::fabs(ra - rb) <= jump_at(p, std::min(ra, rb))) continue;
      if (pos >= 2 && v.usable[seq[pos - 2]] && std::fabs(ri - (2 * ra - v.range[seq[pos - 2]])) <= tol) continue;
      if (pos + 2 < seq.size() && v.usable[seq[pos + 2]] && std::fabs(ri - (2 * rb - v.range[seq[pos + 2]])) <= tol)
        continue;
    }
    Nb l = neighbours(v, seq, pos, -1, p), r = neighbours(v, seq, pos, +1, p);
    // One-sided: beside a void (no return, or only rejected ones: the other surface was too weak
    // to return on its own, e.g. a dark box in front of the ground), the side the return has is
    // the only evidence. The side is the one with a return right next to this one or, if neither
    // has, the only one with a return within the window; the other side must be a void, not the
    // end of the scan (which says nothing about a missing surface).
    const bool l_next = l.count > 0 && l.at[0] == 1, r_next = r.count > 0 && r.at[0] == 1;
    const Nb* own = l_next != r_next ? (l_next ? &l : &r) : (l.count == 0) != (r.count == 0) ? (l.count ? &l : &r) : nullptr;
    const Nb* gap = own == &l ? &r : &l;
    if (p.one_sided && own && gap->beside_void && breaks_from_side(v, i, *own, *gap, tol, p)) {
      mixed[i] = kBesideVoid;
      continue;
    }
    // A neighbour whose beam lies inside this return's footprint (closer than half the
    // divergence) and keeps its range witnesses no surface: two mixtures of one edge, where the
    // beams are that close, keep each other's range as two returns of one surface do. In the
    // first round the side is read past such neighbours, to the first return whose beam is outside
    // the footprint or whose range differs. The later rounds do not: their returns lie beside
    // mixtures already found, where a neighbour that keeps their range is more often the surface
    // they continue (docs/mixed_pixels.md).
    if (!v.focus && v.divergence > 0 && (v.across ? v.across_angle : v.along_angle)) {
      if (l.count > 0 && std::fabs(l.r[0] - ri) <= tol) l = neighbours(v, seq, pos, -1, p, tol);
      if (r.count > 0 && std::fabs(r.r[0] - ri) <= tol) r = neighbours(v, seq, pos, +1, p, tol);
    }
    char strength = two_sided_edge(v, i, l, r, 0, tol, p, coaxial);
    // Past the footprint: where the beams are closer than the divergence, a mixture's nearest
    // neighbours may be mixtures of the same edge (their footprints overlap this one's), and a
    // run of them makes a ramp from one surface to the other with a step beside every return as
    // steep as the one across it, so against its nearest neighbours no return in it shows more
    // than a weak edge or a corner, which a line flat in the other direction does not confirm
    // (behind a table's edge under a footprint three lines wide). In the first round, unless a
    // strong edge was found, each side is then read again from the first return whose beam lies a
    // full divergence or more from this one's: outside every footprint that overlaps it, so on a
    // surface if the return is within half the divergence of the edge. Tests 1-4 decide as
    // before, the stronger verdict stands, and the returns read past do not count against the
    // sides' span (docs/mixed_pixels.md).
    if (strength < kStrongEdge && !v.focus && v.divergence > 0 && (v.across ? v.across_angle : v.along_angle) &&
        (inside_footprint(v, seq, pos, -1) || inside_footprint(v, seq, pos, +1))) {
      int skipped_l = 0, skipped_r = 0;
      const Nb far_l = neighbours(v, seq, pos, -1, p, -1, v.divergence, &skipped_l);
      const Nb far_r = neighbours(v, seq, pos, +1, p, -1, v.divergence, &skipped_r);
      if (skipped_l + skipped_r > 0)
        strength = std::max(strength, two_sided_edge(v, i, far_l, far_r, skipped_l + skipped_r, tol, p, coaxial));
      if (strength == kNoEdge && v.across && p.one_sided &&
          beside_void_past_footprint(v, seq, pos, far_l, skipped_l, far_r, skipped_r, tol, p)) {
        mixed[i] = kBesideVoid;
        continue;
      }
    }
    if (strength != kNoEdge) mixed[i] = std::max(mixed[i], strength);
  }
}

namespace mixed_detail {
void mark_smooth(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                 double range_sigma, std::vector<char>& smooth) {
  for (std::size_t pos = 0; pos < seq.size(); ++pos) {
    const std::size_t i = seq[pos];
    if (!v.usable[i] || (v.focus && !v.focus[i])) continue;
    const bool has_a = pos > 0 && v.usable[seq[pos - 1]], has_b = pos + 1 < seq.size() && v.usable[seq[pos + 1]];
    if (has_a != has_b) {
      const double r_other = v.range[has_a ? seq[pos - 1] : seq[pos + 1]];
      smooth[i] = std::fabs(r_other - v.range[i]) <= jump_at(p, v.range[i]) ? kOneFlat : kOneChanging;
      continue;
    }
    if (!has_a) continue;
    const std::size_t a = seq[pos - 1], b = seq[pos + 1];
    const double tol = tolerance_at(p, v.range[i], range_sigma);
    // Curved surfaces (ground at grazing incidence) bend by a few per cent of the local step.
    const double allow = tol + 0.05 * std::fabs(v.range[b] - v.range[a]);
    if (std::fabs(v.range[i] - 0.5 * (v.range[a] + v.range[b])) > allow && !(on_plane_of(v, i, a, b, tol)))
      smooth[i] = kRough;
    else
      smooth[i] = std::fabs(v.range[b] - v.range[a]) <= jump_at(p, v.range[i]) ? kFlat : kSmooth;
  }
}
}  // namespace mixed_detail

namespace {
/// The arrays one round fills, kept between rounds so that a later round allocates nothing.
struct RoundScratch {
  std::vector<char> usable, along, across, smooth_along, smooth_across, spike, spike_off;
  // The surface behind each spike (its flanks along the line); filled and read only when the
  // round runs the spike tests (the first), so later rounds may leave it stale.
  std::vector<float> behind_r, behind_a;
  std::vector<char> line_tested, stretch_tested;
  std::vector<std::size_t> seq;
};

/// One round of the tests over the returns still kept; labels what it finds. A later round tests
/// only the returns `focused` lists (in pass order; `focus` is the same as a mask) and reads
/// only the lines and, across lines, the stretches of a column that hold one.
/// The returns it labels are appended to `labelled` if given.
std::size_t mark_round(Pass& pass, const MixedPixelParams& p, const SensorParams& sensor, const PoseSigma& pose_sigma,
                       RoundScratch& sc, const char* focus = nullptr, const std::vector<std::size_t>* focused = nullptr,
                       std::vector<std::size_t>* labelled = nullptr) {
  const std::size_t n = pass.size();  // registered: checked by reject_mixed_pixels
  std::vector<char>& usable = sc.usable;
  usable.resize(n);
  for (std::size_t i = 0; i < n; ++i) usable[i] = pass.is_kept(i) && std::isfinite(pass.x[i]);
  ReturnsView v{n, pass.x.data(), pass.y.data(), pass.z.data(), pass.ox.data(), pass.oy.data(), pass.oz.data(),
                pass.range_cal.data(), pass.amplitude.data(), usable.data()};
  v.focus = focus;
  v.pose_position_sigma = pose_sigma.position;
  v.pose_rpy_sigma = pose_sigma.rpy;
  v.along_angle = pass.bearing.data();
  v.across_angle = pass.nod.data();
  v.divergence = std::isfinite(sensor.beam_divergence) ? sensor.beam_divergence : 0.0;
  const bool coaxial = sensor.transceiver_separation <= 0.0;
  // Candidates along and across lines (2: strong edge, 1: weak edge), and where each return lies
  // smoothly on a surface in each direction. A weak-edge candidate that is smooth in the other
  // direction is grazing ground, not a veil.
  for (std::vector<char>* a : {&sc.along, &sc.across, &sc.smooth_along, &sc.smooth_across, &sc.spike, &sc.spike_off})
    a->assign(n, 0);
  std::vector<char> &along = sc.along, &across = sc.across, &smooth_along = sc.smooth_along,
                    &smooth_across = sc.smooth_across, &spike = sc.spike, &spike_off = sc.spike_off;
  std::vector<float> &behind_r = sc.behind_r, &behind_a = sc.behind_a;
  if (p.spikes) {
    behind_r.assign(n, NAN);
    behind_a.assign(n, NAN);
  }
  bool organized = pass.line_count() > 1;
  for (std::size_t k = 1; organized && k < pass.line_count(); ++k)
    organized = pass.line_begin[k + 1] - pass.line_begin[k] == pass.line_begin[1] - pass.line_begin[0];
  if (organized) {
    v.width = pass.line_begin[1] - pass.line_begin[0];
  }
  // With a focus, the lines holding a return to test.
  std::vector<char>& line_tested = sc.line_tested;
  if (focus) {
    line_tested.assign(pass.line_count(), 0);
    std::size_t k = 0;
    for (const std::size_t i : *focused) {  // in pass order
      while (i >= pass.line_begin[k + 1]) ++k;
      line_tested[k] = 1;
    }
  }
  std::vector<std::size_t>& seq = sc.seq;
  for (std::size_t k = 0; k < pass.line_count(); ++k) {
    if (focus && !line_tested[k]) continue;
    seq.clear();
    for (std::size_t i = pass.line_begin[k]; i < pass.line_begin[k + 1]; ++i) seq.push_back(i);
    mark_mixed_pixels(v, seq, p, sensor.range_sigma, coaxial, along);
    mark_smooth(v, seq, p, sensor.range_sigma, smooth_along);
    if (p.spikes) mark_spikes(v, seq, p, spike, behind_r, behind_a);
  }
  if (p.across_lines && organized) {
    v.across = true;  // a return's patch: its neighbouring beams on its line
    const std::vector<std::size_t> sweep_begin = sweep_starts(pass);  // each sweep is a sequence of its own
    const std::size_t sweeps = sweep_begin.size() - 1;
    std::vector<char>& stretch_tested = sc.stretch_tested;  // [sweep * width + column]
    if (focus) {
      stretch_tested.assign(sweeps * v.width, 0);
      std::size_t s = 0;
      for (const std::size_t i : *focused) {  // in pass order
        while (i >= pass.line_begin[sweep_begin[s + 1]]) ++s;
        stretch_tested[s * v.width + (i - pass.line_begin[sweep_begin[s]]) % v.width] = 1;
      }
    }
    for (std::size_t b = 0; b < v.width; ++b) {
      for (std::size_t s = 0; s < sweeps; ++s) {
        if (focus && !stretch_tested[s * v.width + b]) continue;
        seq.clear();
        for (std::size_t k = sweep_begin[s]; k < sweep_begin[s + 1]; ++k) seq.push_back(pass.line_begin[k] + b);
        mark_mixed_pixels(v, seq, p, sensor.range_sigma, coaxial, across);
        mark_smooth(v, seq, p, sensor.range_sigma, smooth_across);
        if (p.spikes) mark_spikes_off_surface(v, seq, p, sensor.range_sigma, spike, behind_r, behind_a, spike_off);
      }
    }
  }
  std::size_t count = 0;
  const auto verdict = [&](std::size_t i) {
    const bool by_along = is_mixed(along[i], smooth_across[i]), by_across = is_mixed(across[i], smooth_along[i]);
    if (by_along || by_across || spike_off[i]) {
      pass.label[i] = Label::kMixedPixel;
      pass.flags[i] |= static_cast<std::uint8_t>((by_along ? kFlagMixedAlong : 0) | (by_across ? kFlagMixedAcross : 0) |
          ((by_along && along[i] == kBesideVoid) || (by_across && across[i] == kBesideVoid) ? kFlagBesideVoid : 0) |
          (spike_off[i] ? kFlagSpike : 0) | (focus ? kFlagMixedRun : 0));  // the evidence (docs/data_contract.md)
      ++count;
      if (labelled) labelled->push_back(i);
    }
  };
  if (focus)
    for (const std::size_t i : *focused) verdict(i);
  else
    for (std::size_t i = 0; i < n; ++i) verdict(i);
  return count;
}

/// How many more rounds a footprint wider than the beam step needs: with divergence / step = k
/// the footprint spans k + 1 beams, so up to k + 1 mixtures of one edge lie side by side and the
/// inner ones have another mixture, not a surface, as their nearest neighbour. Each round peels
/// the outer mixtures of a run (only returns next to one found in the round before count).
int extra_rounds(const Pass& pass, const SensorParams& sensor) {
  // The bearing step: the median |difference| of neighbouring bearings on the first line with at
  // least three returns (bearings may wrap at +-pi; an organized scan has the same on every line,
  // so a streamed window finds the step the whole pass does).
  for (std::size_t k = 0; k < pass.line_count(); ++k) {
    const std::size_t b = pass.line_begin[k], e = pass.line_begin[k + 1];
    if (e - b < 3) continue;
    std::vector<double> d;
    d.reserve(e - b - 1);
    for (std::size_t i = b + 1; i < e; ++i) {
      double x = std::fabs(static_cast<double>(pass.bearing[i]) - static_cast<double>(pass.bearing[i - 1]));
      if (x > kPi) x = 2 * kPi - x;
      if (std::isfinite(x)) d.push_back(x);
    }
    if (d.empty()) return 0;
    std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
    const double step = d[d.size() / 2];
    if (!(step > 0) || !std::isfinite(sensor.beam_divergence)) return 0;
    return static_cast<int>(std::min(static_cast<double>(kMaxExtraRounds), std::floor(sensor.beam_divergence / step)));
  }
  return 0;
}
}  // namespace

std::size_t reject_mixed_pixels(Pass& pass, const MixedPixelParams& params, const SensorParams& sensor,
                                const PoseSigma& pose_sigma) {
  if (pass.range_cal.size() != pass.size()) throw std::logic_error("reject_mixed_pixels needs a registered pass");
  if (pass.flags.size() != pass.size()) pass.flags.assign(pass.size(), 0);
  MixedPixelParams p = params;
  p.amplitude_saturation = sensor.amplitude_saturation;  // the clipping level is the sensor's
  // Along a line the footprint spans divergence / bearing step beams, the same on every line.
  // Across lines it spans divergence / the line step, which a nod that speeds up, slows down or
  // turns changes from line to line: in every round, a return's neighbours across lines are
  // tested again only where the nod step to them lets a run of that length fit in the footprint
  // (read locally, so a streamed window decides as the whole pass does).
  const int along = extra_rounds(pass, sensor);
  const bool more_across = p.across_lines && pass.line_count() > 2 && sensor.beam_divergence > 0;
  const int rounds = more_across ? kMaxExtraRounds : along;
  RoundScratch scratch;
  if (rounds == 0) return mark_round(pass, p, sensor, pose_sigma, scratch);
  std::vector<std::size_t> found;  // labelled in the round before
  std::size_t count = mark_round(pass, p, sensor, pose_sigma, scratch, nullptr, nullptr, &found);
  // Where each return sits in its line, and the lines' width if they are all alike (organized:
  // the same beam on the next line is `width` returns on).
  const std::size_t n = pass.size();
  std::vector<std::size_t> column(n);
  std::size_t width = pass.line_begin[1] - pass.line_begin[0];  // rounds > 0: a line has 3 returns
  for (std::size_t k = 0; k < pass.line_count(); ++k) {
    if (pass.line_begin[k + 1] - pass.line_begin[k] != width) width = 0;
    for (std::size_t i = pass.line_begin[k]; i < pass.line_begin[k + 1]; ++i) column[i] = i - pass.line_begin[k];
  }
  std::vector<char> focus(n, 0);
  std::vector<std::size_t> focused;
  // The later rounds look at most kRoundWindow returns each way for a run's sides (a run's
  // sides are next to it), so each adds kRoundWindow lines to the stage's reach. No spikes:
  // a run is an edge's.
  MixedPixelParams later = p;
  later.spikes = false;
  later.window = std::min(p.window, kRoundWindow);
  for (int round = 0; round < rounds && !found.empty(); ++round) {
    for (const std::size_t i : focused) focus[i] = 0;
    focused.clear();
    const auto consider = [&](std::size_t i) {
      if (focus[i] || !pass.is_kept(i)) return;
      focus[i] = 1;
      focused.push_back(i);
    };
    // Across lines, round + 1 more mixtures fit in the footprint only where the nod moved the beam
    // by at most divergence / (round + 1) between the lines; farther apart the footprints do not
    // overlap, the other line's return is in no run with this one and is not tested again.
    const auto deep = [&](std::size_t i, std::size_t j) {
      const double step = std::fabs(static_cast<double>(pass.nod[i]) - static_cast<double>(pass.nod[j]));
      return step > 0 && (round + 1) * step <= sensor.beam_divergence;
    };
    for (const std::size_t j : found) {  // the returns next to one found in the round before
      if (round < along) {
        if (column[j] > 0) consider(j - 1);
        if (j + 1 < n && column[j + 1] == column[j] + 1) consider(j + 1);
      }
      if (p.across_lines && width > 0) {
        if (j >= width && deep(j - width, j)) consider(j - width);
        if (j + width < n && deep(j + width, j)) consider(j + width);
      }
    }
    if (focused.empty()) break;
    std::sort(focused.begin(), focused.end());
    found.clear();
    count += mark_round(pass, later, sensor, pose_sigma, scratch, focus.data(), &focused, &found);
  }
  return count;
}

}  // namespace pcdp
