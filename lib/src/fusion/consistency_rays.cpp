// The ray walk of check_consistency (ConsistencyEvidence::walk_rays): which lonely voxels each
// kept ray crosses, by the scan lines' ray fans or, for lines that make no fan, a walk over coarse
// cells of the lonely voxels. Every candidate is tested exactly (crosses()).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <optional>

#include "fusion/ifloor.hpp"
#include "pcdp/fusion/consistency.hpp"
#include "pipeline/ordered_parallel.hpp"

namespace pcdp {

namespace {
using detail::ifloor;

// A ray o + t d (d a unit vector, 0 <= t < tend) in double precision, from a stored Ray.
struct Segment {
  double o[3], d[3], inv[3], tend;  // inv: 1 / d, for the cell walks (set_inverse; the exact test divides)
};
// A ray's origin, its vector to the return (e - o) and length: false when the ray gives no
// free-space evidence (no origin, too short or too long).
struct RayExtent {
  double o[3], dl[3], len;
};
// The coordinate (m) of the centre of voxel v along one axis.
inline double centre_of(std::int64_t v, double res) { return (static_cast<double>(v) + 0.5) * res; }
bool extent_of(const ConsistencyEvidence::Ray& r, const double anchor[3], const ConsistencyParams& p, RayExtent& x) {
  double len2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    x.o[a] = anchor[a] + static_cast<double>(r.o[a]);
    x.dl[a] = static_cast<double>(r.e[a]) - static_cast<double>(r.o[a]);
    len2 += x.dl[a] * x.dl[a];
  }
  x.len = std::sqrt(len2);
  return x.len > p.margin && !(x.len > p.max_range);  // also false for a NaN origin
}
void segment_of(const RayExtent& x, const ConsistencyParams& p, Segment& s) {
  for (int a = 0; a < 3; ++a) {
    s.o[a] = x.o[a];
    s.d[a] = x.dl[a] / x.len;
  }
  s.tend = x.len - p.margin;
}
// Fills s.inv, which only the grid walks need.
void set_inverse(Segment& s) {
  for (int a = 0; a < 3; ++a) s.inv[a] = 1.0 / s.d[a];
}

// Whether the ray enters voxel v (signed voxel indices) for some 0 <= t < tend: exactly the
// voxels a voxel-by-voxel walk (3-D DDA, Amanatides & Woo) from o visits, up to rays that run
// exactly along a voxel edge. An axis the ray does not move along (|d| <= 1e-12, as the walk
// treated it) stays in the origin's voxel.
bool crosses(const Segment& s, const std::int64_t v[3], double res) {
  double enter = -INFINITY, exit = INFINITY;
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(s.d[a]) > 1e-12) {
      double t0 = (static_cast<double>(v[a]) * res - s.o[a]) / s.d[a];
      double t1 = (static_cast<double>(v[a] + 1) * res - s.o[a]) / s.d[a];
      if (t0 > t1) std::swap(t0, t1);
      enter = std::max(enter, t0);
      exit = std::min(exit, t1);
    } else if (ifloor(s.o[a] / res) != v[a]) {
      return false;
    }
  }
  return enter < exit && enter < s.tend && exit > 0.0;
}

// Clips the part t0 <= t < t1 of the segment to the box [lo, hi); false when nothing is left.
bool clip(const Segment& s, const double lo[3], const double hi[3], double& t0, double& t1) {
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(s.d[a]) > 1e-12) {
      double ta = (lo[a] - s.o[a]) * s.inv[a], tb = (hi[a] - s.o[a]) * s.inv[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    } else if (s.o[a] < lo[a] || s.o[a] >= hi[a]) {
      return false;
    }
  }
  return t0 < t1;
}

// A 3-D DDA over a box of n[0] x n[1] x n[2] cells of edge `cell` with its low corner at `lo`:
// f(x, y, z, t_in, t_out) for every cell the part t0 <= t < t1 of the segment (inside the box)
// passes through, in order. The state is kept in scalars, not arrays indexed by the stepping
// axis (with those, every step waits on a store).
template <class F>
void walk_cells(const Segment& s, double t0, double t1, const double lo[3], double cell, const std::int64_t n[3], F&& f) {
  std::int64_t c[3], step[3];
  double tmax[3], tdelta[3];
  for (int a = 0; a < 3; ++a) {
    const double p = s.o[a] + t0 * s.d[a];
    c[a] = std::clamp<std::int64_t>(ifloor((p - lo[a]) * (1.0 / cell)), 0, n[a] - 1);
    step[a] = s.d[a] > 0 ? 1 : -1;
    if (std::fabs(s.d[a]) > 1e-12) {
      tmax[a] = (lo[a] + static_cast<double>(c[a] + (s.d[a] > 0 ? 1 : 0)) * cell - s.o[a]) * s.inv[a];
      tdelta[a] = cell * std::fabs(s.inv[a]);
    } else {
      tmax[a] = INFINITY;
      tdelta[a] = INFINITY;
    }
  }
  std::int64_t x = c[0], y = c[1], z = c[2];
  double tx = tmax[0], ty = tmax[1], tz = tmax[2];
  const double dx = tdelta[0], dy = tdelta[1], dz = tdelta[2];
  const std::int64_t sx = step[0], sy = step[1], sz = step[2], nx = n[0], ny = n[1], nz = n[2];
  for (double t = t0;;) {
    if (tx < ty && tx < tz) {
      f(x, y, z, t, std::min(tx, t1));
      if (tx >= t1) return;
      t = tx;
      tx += dx;
      x += sx;
      if (x < 0 || x >= nx) return;
    } else if (ty < tz) {
      f(x, y, z, t, std::min(ty, t1));
      if (ty >= t1) return;
      t = ty;
      ty += dy;
      y += sy;
      if (y < 0 || y >= ny) return;
    } else {
      f(x, y, z, t, std::min(tz, t1));
      if (tz >= t1) return;
      t = tz;
      tz += dz;
      z += sz;
      if (z < 0 || z >= nz) return;
    }
  }
}

// The lonely voxels grouped by the cell (an edge of `edge` voxels) they fall in, cells grouped in
// blocks of 8 x 8 x 8, with a dense directory over the blocks' cells. A ray walks the blocks;
// in a block with a few lonely voxels it tests them all, in one with more it walks the block's
// cells and tests only the voxels of the cells it crosses. Every test is exact (crosses()).
struct LonelyCells {
  struct Box {
    std::int64_t v[3];    // signed voxel indices
    std::uint32_t index;  // position in the evidence's lonely list
  };
  static constexpr std::uint32_t kFew = 8;  // boxes a block tests without walking its cells
  double lo_w[3] = {0, 0, 0};        // the grid's low corner (the lowest lonely voxel's), m
  std::int64_t n[3] = {0, 0, 0};     // cells per axis
  std::int64_t nb[3] = {0, 0, 0};    // blocks per axis
  std::uint32_t edge;                // voxels per cell edge
  std::vector<std::uint32_t> begin;  // per cell (block-major: block * 512 + cell in block), into boxes; one more at the end
  std::vector<Box> boxes;

  template <class Lonely>
  LonelyCells(const std::vector<Lonely>& lonely, std::uint32_t cell_edge, double res) : edge(cell_edge) {
    if (lonely.empty()) return;
    std::int64_t vlo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, vhi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
    for (const Lonely& l : lonely)
      for (int a = 0; a < 3; ++a) {
        vlo[a] = std::min(vlo[a], l.v[a]);
        vhi[a] = std::max(vhi[a], l.v[a]);
      }
    // The smallest cells (from the given edge) whose directory stays within 4 M entries (16 MB).
    for (;; edge *= 2) {
      std::size_t cells = 512;
      for (int a = 0; a < 3; ++a) {
        n[a] = (vhi[a] - vlo[a]) / edge + 1;
        nb[a] = (n[a] + 7) / 8;
        cells *= static_cast<std::size_t>(nb[a]);
      }
      if (cells <= (std::size_t{1} << 22)) break;
    }
    for (int a = 0; a < 3; ++a) lo_w[a] = static_cast<double>(vlo[a]) * res;
    std::vector<std::uint32_t> cell_of(lonely.size());
    begin.assign(static_cast<std::size_t>(nb[0] * nb[1] * nb[2]) * 512 + 1, 0);
    for (std::size_t i = 0; i < lonely.size(); ++i) {
      std::int64_t cc[3];
      for (int a = 0; a < 3; ++a) cc[a] = (lonely[i].v[a] - vlo[a]) / edge;
      cell_of[i] = static_cast<std::uint32_t>(cell_index(cc));
      ++begin[cell_of[i] + 1];
    }
    for (std::size_t c = 1; c < begin.size(); ++c) begin[c] += begin[c - 1];
    std::vector<std::uint32_t> next(begin.begin(), begin.end() - 1);
    boxes.resize(lonely.size());
    for (std::size_t i = 0; i < lonely.size(); ++i) {
      Box& b = boxes[next[cell_of[i]]++];
      for (int a = 0; a < 3; ++a) b.v[a] = lonely[i].v[a];
      b.index = static_cast<std::uint32_t>(i);
    }
  }
  std::size_t block_index(const std::int64_t b[3]) const { return static_cast<std::size_t>((b[2] * nb[1] + b[1]) * nb[0] + b[0]); }
  std::size_t cell_index(const std::int64_t c[3]) const {
    const std::int64_t b[3] = {c[0] >> 3, c[1] >> 3, c[2] >> 3};
    return block_index(b) * 512 + static_cast<std::size_t>((c[0] & 7) | ((c[1] & 7) << 3) | ((c[2] & 7) << 6));
  }

  // f(box) for the lonely voxels near the segment: every one of each cell it passes through, and
  // maybe some others of the blocks it passes through.
  template <class F>
  void for_each_near(const Segment& s, double res, F&& f) const {
    if (boxes.empty()) return;
    const double cell = res * edge, block = 8 * cell;
    double hi_w[3];
    for (int a = 0; a < 3; ++a) hi_w[a] = lo_w[a] + cell * static_cast<double>(n[a]);
    double t0 = 0.0, t1 = s.tend;
    if (!clip(s, lo_w, hi_w, t0, t1)) return;
    walk_cells(s, t0, t1, lo_w, block, nb, [&](std::int64_t bx, std::int64_t by, std::int64_t bz, double tin, double tout) {
      const std::int64_t b[3] = {bx, by, bz};
      const std::size_t first = block_index(b) * 512;
      const std::uint32_t from = begin[first], to = begin[first + 512];
      if (to - from <= kFew) {
        for (std::uint32_t k = from; k < to; ++k) f(boxes[k]);
        return;
      }
      double blo[3];
      std::int64_t bn[3];
      for (int a = 0; a < 3; ++a) {
        blo[a] = lo_w[a] + static_cast<double>(b[a]) * block;
        bn[a] = std::min<std::int64_t>(8, n[a] - 8 * b[a]);
      }
      walk_cells(s, tin, tout, blo, cell, bn, [&](std::int64_t cx, std::int64_t cy, std::int64_t cz, double, double) {
        const std::size_t i = first + static_cast<std::size_t>(cx | (cy << 3) | (cz << 6));
        for (std::uint32_t k = begin[i], e = begin[i + 1]; k < e; ++k) f(boxes[k]);
      });
    });
  }
};

// The pseudo-angle of the direction (x, y), in [0, 4): it increases with the angle and changes by
// at most the angle's change in radians (in the first quadrant it is y / (x + y), whose derivative
// in the angle is 1 / (1 + sin 2a), between 1/2 and 1; the other quadrants are this turned). It
// orders a fan's rays without an atan2 per ray.
inline double pseudo_angle(double x, double y) {
  if (y >= 0) return x >= 0 ? (x + y > 0 ? y / (x + y) : 0.0) : 1.0 - x / (y - x);
  return x < 0 ? 2.0 - y / (-x - y) : 3.0 + x / (x - y);
}

// A scan line's rays seen as a fan: a 2-D scanner's beams of one line leave from (nearly) one
// point in (nearly) one plane, so a voxel can be crossed only by the few rays of the few lines
// whose planes pass through it and whose bearings point at it. Bounds measured on the rays
// themselves make every cut conservative, and each candidate is then tested exactly (crosses()),
// so the fans find exactly the crossings a walk of every ray finds:
//  - every point of every ray lies within `dev` of the plane through `o` with unit normal `n`
//    (a segment's points are blends of its two ends, so the ends bound it);
//  - every origin lies within `spread` of `o`; every direction makes an angle of at most
//    asin(`tilt`) with the plane;
//  - `order` holds the rays' pseudo-angles in the plane (axes u, v), sorted.
struct Fan {
  double o[3], n[3], u[3], v[3];
  double dev = 0, spread = 0, tilt = 0;
  std::vector<std::pair<double, std::uint32_t>> order;  // (pseudo-angle, position in the line's rays)
};

double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// False when the line's rays do not make a usable fan (fewer than two, all nearly parallel, or
// not flat: a cloud with no scan lines is one "line" of rays in every direction); their rays are
// walked instead. One square root (in extent_of) and one division a ray: the bounds use each
// ray's whole vector o .. e (its segment stops short of e) and compare ratios by multiplying.
bool make_fan(const std::vector<RayExtent>& rays, double max_dev, Fan& f) {
  if (rays.size() < 2) return false;
  const double* a = rays.front().dl;
  const double a2 = dot3(a, a);
  // The ray most nearly perpendicular to the first: least (a . d)^2 / |d|^2.
  const RayExtent* b = &rays.front();
  double num = a2 * a2, den = a2;
  for (const RayExtent& x : rays) {
    const double c = dot3(a, x.dl), d2 = x.len * x.len;
    if (c * c * den < num * d2) {
      num = c * c;
      den = d2;
      b = &x;
    }
  }
  const double* bd = b->dl;
  const double n[3] = {a[1] * bd[2] - a[2] * bd[1], a[2] * bd[0] - a[0] * bd[2], a[0] * bd[1] - a[1] * bd[0]};
  const double nn = std::sqrt(dot3(n, n));
  if (!(nn > 0.1 * std::sqrt(a2) * b->len)) return false;  // the rays span less than about 6 degrees
  for (int k = 0; k < 3; ++k) {
    f.n[k] = n[k] / nn;
    f.o[k] = rays.front().o[k];
  }
  // u: away from the middle ray, made exactly perpendicular to n; v = n x u. The pseudo-angles
  // then run from 0 to 4 with the middle ray at 2, so a line of less than a full turn does not
  // wrap: its rays are in order, or in reverse order.
  const double* m = rays[rays.size() / 2].dl;
  const double mn = dot3(m, f.n);
  double un = 0;
  for (int k = 0; k < 3; ++k) {
    f.u[k] = mn * f.n[k] - m[k];
    un += f.u[k] * f.u[k];
  }
  un = std::sqrt(un);
  if (!(un > 0)) return false;
  for (double& c : f.u) c /= un;
  f.v[0] = f.n[1] * f.u[2] - f.n[2] * f.u[1];
  f.v[1] = f.n[2] * f.u[0] - f.n[0] * f.u[2];
  f.v[2] = f.n[0] * f.u[1] - f.n[1] * f.u[0];
  f.dev = f.spread = 0;
  f.order.clear();
  const double on = dot3(f.o, f.n);
  double tilt_num = 0, tilt_den = 1;  // the largest |d . n| / |d|
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const RayExtent& x = rays[i];
    const double dn = dot3(x.dl, f.n), start = dot3(x.o, f.n) - on;
    f.dev = std::max({f.dev, std::fabs(start), std::fabs(start + dn)});
    if (std::fabs(dn) * tilt_den > tilt_num * x.len) {
      tilt_num = std::fabs(dn);
      tilt_den = x.len;
    }
    const double w[3] = {x.o[0] - f.o[0], x.o[1] - f.o[1], x.o[2] - f.o[2]};
    f.spread = std::max(f.spread, dot3(w, w));
    f.order.emplace_back(pseudo_angle(dot3(x.dl, f.u), dot3(x.dl, f.v)), static_cast<std::uint32_t>(i));
  }
  // Rounded up a little: the bounds are compared with values computed in other ways.
  f.tilt = tilt_num / tilt_den * (1.0 + 1e-12);
  f.spread = std::sqrt(f.spread) * (1.0 + 1e-12);
  if (!(f.dev <= max_dev) || !(f.tilt <= 0.5)) return false;
  if (!std::is_sorted(f.order.begin(), f.order.end())) {
    std::reverse(f.order.begin(), f.order.end());  // lines scanned the other way round
    if (!std::is_sorted(f.order.begin(), f.order.end())) std::sort(f.order.begin(), f.order.end());
  }
  return true;
}

// The lonely voxels' centres relative to `ref`, in single precision for the slab tests that cull
// most of them (their rounding is allowed for), grouped in clusters of up to 16 neighbouring
// voxels so that a fan's plane is tested against a cluster's bounding sphere first (a fan's
// slab holds about 1 % of the voxels).
struct Centres {
  double ref[3] = {0, 0, 0};
  double reach = 0;                  // the largest |centre - ref|, m
  std::vector<std::uint32_t> id;     // position in the lonely list, in cluster order
  std::vector<float> x, y, z;        // centres, in cluster order
  std::vector<std::uint32_t> begin;  // cluster k is [begin[k], begin[k + 1])
  std::vector<float> cx, cy, cz, r;  // clusters' bounding spheres (of the centres)

  template <class Lonely>
  Centres(const std::vector<Lonely>& lonely, double res, const double origin[3]) {
    for (int a = 0; a < 3; ++a) ref[a] = origin[a];
    // Neighbours first: ordered by the 8-voxel cube they fall in, cubes in Morton order.
    const auto morton = [](std::uint64_t c[3]) {
      std::uint64_t m = 0;
      for (int b = 0; b < 21; ++b)
        for (int a = 0; a < 3; ++a) m |= ((c[a] >> b) & 1u) << (3 * b + a);
      return m;
    };
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
    order.reserve(lonely.size());
    for (std::size_t j = 0; j < lonely.size(); ++j) {
      std::uint64_t c[3];
      for (int a = 0; a < 3; ++a) c[a] = static_cast<std::uint64_t>(lonely[j].v[a] >> 3) & 0x1fffff;
      order.emplace_back(morton(c), static_cast<std::uint32_t>(j));
    }
    std::sort(order.begin(), order.end());
    std::int64_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    const auto close = [&] {
      double mid[3], r2 = 0;
      for (int a = 0; a < 3; ++a) {
        mid[a] = (0.5 * static_cast<double>(lo[a] + hi[a]) + 0.5) * res - ref[a];
        const double e = 0.5 * static_cast<double>(hi[a] - lo[a]) * res;
        r2 += e * e;
      }
      cx.push_back(static_cast<float>(mid[0]));
      cy.push_back(static_cast<float>(mid[1]));
      cz.push_back(static_cast<float>(mid[2]));
      r.push_back(static_cast<float>(std::sqrt(r2)));
    };
    for (const auto& [key, j] : order) {
      const std::int64_t* v = lonely[j].v;
      const std::size_t size = id.size() - (begin.empty() ? 0 : begin.back());
      bool fits = !begin.empty() && size < 16;
      for (int a = 0; a < 3 && fits; ++a) fits = std::max(hi[a], v[a]) - std::min(lo[a], v[a]) < 16;
      if (fits) {
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], v[a]);
          hi[a] = std::max(hi[a], v[a]);
        }
      } else {
        if (!begin.empty()) close();
        begin.push_back(static_cast<std::uint32_t>(id.size()));
        for (int a = 0; a < 3; ++a) lo[a] = hi[a] = v[a];
      }
      id.push_back(j);
      double c[3];
      for (int a = 0; a < 3; ++a) c[a] = centre_of(v[a], res) - ref[a];
      x.push_back(static_cast<float>(c[0]));
      y.push_back(static_cast<float>(c[1]));
      z.push_back(static_cast<float>(c[2]));
      reach = std::max(reach, std::sqrt(dot3(c, c)));
    }
    if (!begin.empty()) close();
    begin.push_back(static_cast<std::uint32_t>(id.size()));
  }
};

// asin(x) <= x asin(1/2) / (1/2) for 0 <= x <= 1/2 (asin is convex there); the constant rounded up.
constexpr double kAsinSlope = 1.0472;

// f(j, i) for the lonely voxels j (positions in the lonely list) and rays i (positions in the
// line's rays) where the ray may cross the voxel: a superset of the crossings.
template <class Lonely, class F>
void for_each_in_fan(const Fan& fan, const Centres& c, const std::vector<Lonely>& lonely, double res,
                     std::vector<float>& dist, F&& f) {
  const double half = 0.5 * std::sqrt(3.0) * res;  // the voxel's half diagonal
  const double rel[3] = {fan.o[0] - c.ref[0], fan.o[1] - c.ref[1], fan.o[2] - c.ref[2]};
  const float nx = static_cast<float>(fan.n[0]), ny = static_cast<float>(fan.n[1]), nz = static_cast<float>(fan.n[2]);
  const float off = static_cast<float>(dot3(rel, fan.n));
  // Single-precision error of the dot products: a few units in the last place of the largest terms.
  const double slack = 1e-4 + 1e-6 * (c.reach + std::sqrt(dot3(rel, rel)));
  const float tol = static_cast<float>(half + fan.dev + slack);
  const std::size_t nc = c.r.size();
  dist.resize(nc);
  float* d = dist.data();
  for (std::size_t k = 0; k < nc; ++k) d[k] = std::fabs(nx * c.cx[k] + ny * c.cy[k] + nz * c.cz[k] - off) - c.r[k];
  for (std::size_t k = 0; k < nc; ++k) {
    if (d[k] > tol) continue;
    for (std::uint32_t q = c.begin[k]; q < c.begin[k + 1]; ++q) {
      if (std::fabs(nx * c.x[q] + ny * c.y[q] + nz * c.z[q] - off) > tol) continue;
      const std::size_t j = c.id[q];
      double w[3];
      for (int a = 0; a < 3; ++a) w[a] = centre_of(lonely[j].v[a], res) - fan.o[a];
      const double D = std::sqrt(dot3(w, w)), off_plane = std::fabs(dot3(w, fan.n));
      // A ray i that meets the voxel at p: p - o = (o_i - o) + t d_i with t > spread (so the voxel
      // must be further than half + 2 spread), so d_i is within asin(spread / |p - o|) of p - o,
      // which is within asin(half / D) of the centre's direction: alpha <= asin x1 + asin x2.
      const double x1 = fan.spread / (D - half), x2 = half / D;
      // In the plane: two unit vectors at angle alpha whose projections are at least m long
      // project to directions at most 2 asin(sin(alpha / 2) / m) apart; sin(a) <= a and the
      // bound on asin above make that theta below, when every asin's argument is at most 1/2.
      const double tilt = std::max(fan.tilt, off_plane / D);
      const double m = std::sqrt(std::max(0.0, 1.0 - tilt * tilt));
      const double half_alpha = 0.5 * kAsinSlope * (x1 + x2);
      if (!(D > half + 2.0 * fan.spread + 1e-9) || !(x1 <= 0.5 && x2 <= 0.5 && half_alpha < 0.5 * m)) {
        for (const auto& ray : fan.order) f(j, ray.second);  // near the apex, or a wide cone
        continue;
      }
      const double theta = 2.0 * kAsinSlope * half_alpha / m * (1.0 + 1e-9) + 1e-12;
      const double psi = pseudo_angle(dot3(w, fan.u), dot3(w, fan.v));
      const auto range = [&](double lo, double hi) {
        auto it = std::lower_bound(fan.order.begin(), fan.order.end(), std::make_pair(lo, std::uint32_t{0}));
        for (; it != fan.order.end() && it->first <= hi; ++it) f(j, it->second);
      };
      const double lo = psi - theta, hi = psi + theta;  // theta < 1.05: no wrap on both sides
      range(std::max(lo, 0.0), std::min(hi, 4.0));
      if (lo < 0.0) range(lo + 4.0, 4.0);
      if (hi > 4.0) range(0.0, hi - 4.0);
    }
  }
}
}  // namespace

std::vector<ConsistencyEvidence::Chunk> ConsistencyEvidence::line_chunks() const {
  // Whole lines of a few thousand rays in all.
  constexpr std::size_t kRays = 4096;
  std::vector<Chunk> out;
  for (std::size_t k = 0; k < passes_.size(); ++k) {
    const std::vector<std::uint32_t>& lines = passes_[k].lines;
    for (std::size_t b = 0; b + 1 < lines.size();) {
      std::size_t e = b + 1;
      while (e + 1 < lines.size() && lines[e] - lines[b] < kRays) ++e;
      out.push_back({k, b, e});
      b = e;
    }
  }
  return out;
}

void ConsistencyEvidence::walk_rays(unsigned threads) {
  const double res = p_.resolution;
  // The lonely voxels' centres for the fans' slab tests, relative to the first pass's anchor.
  const double zero[3] = {0.0, 0.0, 0.0};
  const Centres centres(lonely_, res, passes_.empty() ? zero : passes_.front().anchor);
  // Lines whose rays make no fan walk them over a coarse grid of the lonely voxels' cells, built
  // the first time a line needs it. Cells of 4 voxels: on the benchmark's eight passes and on
  // Kurt3D, 2 and 8 are slower (fewer exact tests but more cell steps, or the reverse).
  std::once_flag cells_built;
  std::optional<LonelyCells> cells;
  // A fan whose rays stray further than this from its plane would pass most voxels' slab test.
  const double max_dev = std::max(0.5, 4.0 * res);
  // A voxel's half diagonal, rounded up for the prefilter of the exact test.
  const double near = 0.5 * std::sqrt(3.0) * res * (1.0 + 1e-9) + 1e-9, near2 = near * near;
  struct Crossed {
    std::vector<std::uint32_t> lonely;  // positions in lonely_
    std::uint64_t walked = 0, fanned = 0;
  };
  const std::vector<Chunk> work = line_chunks();
  std::vector<Crossed> crossed(work.size());  // small: the crossings only
  detail::parallel_for(work.size(), threads, [&](std::size_t w) {
    Crossed& out = crossed[w];
    const PassRays& pr = passes_[work[w].pass];
    std::vector<RayExtent> rays;
    std::vector<float> dist;
    Fan fan;
    Segment s;
    for (std::size_t k = work[w].begin; k < work[w].end; ++k) {
      rays.clear();
      RayExtent x;
      for (std::uint32_t i = pr.lines[k]; i < pr.lines[k + 1]; ++i)
        if (extent_of(pr.rays[i], pr.anchor, p_, x)) rays.push_back(x);
      out.walked += rays.size();
      if (make_fan(rays, max_dev, fan)) {
        out.fanned += rays.size();
        for_each_in_fan(fan, centres, lonely_, res, dist, [&](std::size_t j, std::uint32_t i) {
          // Most candidates pass wide of the voxel: a ray that enters it passes within
          // `half` of its centre (no division: |w x dl| against half |dl|).
          const RayExtent& ray = rays[i];
          double to[3];
          for (int a = 0; a < 3; ++a) to[a] = centre_of(lonely_[j].v[a], res) - ray.o[a];
          const double c[3] = {to[1] * ray.dl[2] - to[2] * ray.dl[1], to[2] * ray.dl[0] - to[0] * ray.dl[2],
                               to[0] * ray.dl[1] - to[1] * ray.dl[0]};
          if (dot3(c, c) > near2 * (ray.len * ray.len)) return;
          segment_of(ray, p_, s);
          if (crosses(s, lonely_[j].v, res)) out.lonely.push_back(static_cast<std::uint32_t>(j));
        });
        continue;
      }
      std::call_once(cells_built, [&] { cells.emplace(lonely_, 4, res); });
      for (const RayExtent& g : rays) {
        segment_of(g, p_, s);
        set_inverse(s);
        cells->for_each_near(s, res, [&](const LonelyCells::Box& b) {
          if (crosses(s, b.v, res)) out.lonely.push_back(b.index);
        });
      }
    }
  });
  for (std::size_t w = 0; w < work.size(); ++w) {
    const Crossed& c = crossed[w];
    const std::uint64_t bit = passes_[work[w].pass].bit;
    stats_.rays_walked += c.walked;
    stats_.rays_in_fans += c.fanned;
    stats_.crossings += c.lonely.size();
    for (const std::uint32_t i : c.lonely) lonely_[i].free |= bit;
  }
}

}  // namespace pcdp
