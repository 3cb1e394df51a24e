#include "pcdp/sim/nodding_sim.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <random>
#include <sstream>

#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/pcd.hpp"

namespace pcdp::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Hit {
  double t = kInf;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double reflectivity = 0.0;
  int object = -1;  ///< box index, or -1 for the terrain
};

/// Ray (o + t d, t in (0, hit.t)) against an axis-aligned box; updates `hit` when nearer.
bool hit_aabb(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, Hit& hit) {
  double tmin = 0.0, tmax = hit.t;
  int axis = -1;
  double sign = 1.0;
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(d[a]) < 1e-15) {
      if (o[a] < b.min[a] || o[a] > b.max[a]) return false;
      continue;
    }
    double t1 = (b.min[a] - o[a]) / d[a], t2 = (b.max[a] - o[a]) / d[a];
    double s = -1.0;  // entering through the min face: outward normal -axis
    if (t1 > t2) {
      std::swap(t1, t2);
      s = 1.0;
    }
    if (t1 > tmin) {
      tmin = t1;
      axis = a;
      sign = s;
    }
    tmax = std::min(tmax, t2);
    if (tmin > tmax) return false;
  }
  if (axis < 0 || tmin <= 1e-9) return false;  // origin inside (or on) the box
  hit.t = tmin;
  hit.normal = Eigen::Vector3d::Zero();
  hit.normal[axis] = sign;
  hit.reflectivity = b.reflectivity;
  return true;
}

/// Ray against a box turned by b.yaw: the ray in the box's own frame against the axis-aligned
/// box, the normal turned back (yaw 0 is hit_aabb itself, bit for bit).
bool hit_box(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, Hit& hit) {
  if (b.yaw == 0.0) return hit_aabb(b, o, d, hit);
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  const double cx = 0.5 * (b.min.x() + b.max.x()), cy = 0.5 * (b.min.y() + b.max.y());
  const double ox = o.x() - cx, oy = o.y() - cy;
  const Eigen::Vector3d ol(c * ox + s * oy + cx, -s * ox + c * oy + cy, o.z());
  const Eigen::Vector3d dl(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  if (!hit_aabb(b, ol, dl, hit)) return false;
  const Eigen::Vector3d n = hit.normal;
  hit.normal = Eigen::Vector3d(c * n.x() - s * n.y(), s * n.x() + c * n.y(), n.z());
  return true;
}

/// Ray against a vertical cylinder (side and both caps); updates `hit` when nearer.
bool hit_post(const Post& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d, Hit& hit) {
  const double r2 = p.radius * p.radius;
  const double ox = o.x() - p.x, oy = o.y() - p.y;
  const bool inside_xy = ox * ox + oy * oy <= r2;
  if (inside_xy && o.z() >= p.z_min && o.z() <= p.z_max) return false;  // origin inside
  double best = hit.t;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  bool found = false;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-18 && !inside_xy) {  // the side: entering root of |o + t d - c|^2 = r^2 in xy
    const double bq = ox * d.x() + oy * d.y();
    const double disc = bq * bq - a * (ox * ox + oy * oy - r2);
    if (disc >= 0.0) {
      const double t = (-bq - std::sqrt(disc)) / a;
      const double z = o.z() + t * d.z();
      if (t > 1e-9 && t < best && z >= p.z_min && z <= p.z_max) {
        best = t;
        normal = Eigen::Vector3d((ox + t * d.x()) / p.radius, (oy + t * d.y()) / p.radius, 0.0);
        found = true;
      }
    }
  }
  if (std::fabs(d.z()) > 1e-15) {  // the caps: the top seen from above, the bottom from below
    const double zc = d.z() < 0 ? p.z_max : p.z_min;
    if ((d.z() < 0 && o.z() > zc) || (d.z() > 0 && o.z() < zc)) {
      const double t = (zc - o.z()) / d.z();
      const double x = ox + t * d.x(), y = oy + t * d.y();
      if (t > 1e-9 && t < best && x * x + y * y <= r2) {
        best = t;
        normal = Eigen::Vector3d(0.0, 0.0, d.z() < 0 ? 1.0 : -1.0);
        found = true;
      }
    }
  }
  if (!found) return false;
  hit.t = best;
  hit.normal = normal;
  hit.reflectivity = p.reflectivity;
  return true;
}

void hit_terrain(const Scene& sc, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max, Hit& hit) {
  const double t_end = std::min(t_max, hit.t);
  if (sc.undulation_amplitude == 0.0) {
    if (std::fabs(d.z()) < 1e-15) return;
    const double t = (sc.ground_z - o.z()) / d.z();
    if (t > 1e-9 && t < t_end) {
      hit.t = t;
      hit.normal = Eigen::Vector3d::UnitZ();
      hit.reflectivity = sc.ground_reflectivity;
    }
    return;
  }
  // Sphere tracing on a Lipschitz height field: the terrain's slope is at most L, so a step of
  // f / (|dz| + L |dxy|) cannot cross it; bisection refines the first sign change.
  const double k = 2 * kPi / sc.undulation_wavelength;
  const double L = sc.undulation_amplitude * k * std::sqrt(2.0);
  const double rate = std::fabs(d.z()) + L * std::hypot(d.x(), d.y());
  const auto above = [&](double t) {
    const Eigen::Vector3d p = o + t * d;
    return p.z() - sc.terrain_height(p.x(), p.y());
  };
  double t = 0.0, f = above(0.0);
  if (f <= 0.0) return;
  while (t < t_end) {
    const double t_new = t + std::max(f / rate, 0.002);
    const double f_new = above(t_new);
    if (f_new <= 0.0) {
      double lo = t, hi = t_new;
      for (int it = 0; it < 50; ++it) {
        const double mid = 0.5 * (lo + hi);
        (above(mid) > 0.0 ? lo : hi) = mid;
      }
      const double th = 0.5 * (lo + hi);
      if (th < t_end) {
        hit.t = th;
        const Eigen::Vector3d p = o + th * d;
        const double e = 1e-4;
        const double gx = (sc.terrain_height(p.x() + e, p.y()) - sc.terrain_height(p.x() - e, p.y())) / (2 * e);
        const double gy = (sc.terrain_height(p.x(), p.y() + e) - sc.terrain_height(p.x(), p.y() - e)) / (2 * e);
        hit.normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
        hit.reflectivity = sc.ground_reflectivity;
      }
      return;
    }
    t = t_new;
    f = f_new;
  }
}

Hit cast(const Scene& sc, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max) {
  Hit hit;
  hit.t = t_max;
  bool any = false;
  for (std::size_t k = 0; k < sc.boxes.size(); ++k)
    if (hit_box(sc.boxes[k], o, d, hit)) {
      any = true;
      hit.object = static_cast<int>(k);
    }
  for (std::size_t k = 0; k < sc.posts.size(); ++k)
    if (hit_post(sc.posts[k], o, d, hit)) {
      any = true;
      hit.object = static_cast<int>(sc.boxes.size() + k);
    }
  const double before = hit.t;
  hit_terrain(sc, o, d, t_max, hit);
  if (hit.t < before) {
    any = true;
    hit.object = -1;
  }
  if (!any) hit.t = kInf;
  return hit;
}

/// Is the segment p -> r blocked by a box or a post? (The terrain is smooth and the receiver is centimetres
/// from the transmitter, whose ray to p was clear, so only boxes can hide p from the receiver.)
bool blocked(const Scene& sc, const Eigen::Vector3d& p, const Eigen::Vector3d& r) {
  const Eigen::Vector3d d = r - p;
  const double len = d.norm();
  if (len < 1e-12) return false;
  const Eigen::Vector3d u = d / len;
  const Eigen::Vector3d start = p + 1e-6 * u;
  for (const auto& b : sc.boxes) {
    Hit h;
    h.t = len - 2e-6;
    if (hit_box(b, start, u, h)) return true;
  }
  for (const auto& post : sc.posts) {
    Hit h;
    h.t = len - 2e-6;
    if (hit_post(post, start, u, h)) return true;
  }
  return false;
}

Eigen::Matrix3d terrain_frame(const Scene& sc, double x, double y, double yaw) {
  const double e = 1e-3;
  const double gx = (sc.terrain_height(x + e, y) - sc.terrain_height(x - e, y)) / (2 * e);
  const double gy = (sc.terrain_height(x, y + e) - sc.terrain_height(x, y - e)) / (2 * e);
  const Eigen::Vector3d z = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
  const Eigen::Vector3d f(std::cos(yaw), std::sin(yaw), gx * std::cos(yaw) + gy * std::sin(yaw));
  const Eigen::Vector3d yv = z.cross(f).normalized();
  const Eigen::Vector3d xv = yv.cross(z);
  Eigen::Matrix3d r;
  r.col(0) = xv;
  r.col(1) = yv;
  r.col(2) = z;
  return r;
}

double quantize(double v, double q) { return q > 0 ? std::round(v / q) * q : v; }
}  // namespace

double Scene::terrain_height(double x, double y) const {
  if (undulation_amplitude == 0.0) return ground_z;
  const double k = 2 * kPi / undulation_wavelength;
  return ground_z + undulation_amplitude * std::sin(k * x) * std::cos(k * y);
}

double Scene::top_height(double x, double y) const {
  double z = terrain_height(x, y);
  for (const auto& b : boxes)
    if (b.covers(x, y)) z = std::max(z, b.max.z());
  for (const auto& p : posts)
    if ((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y) <= p.radius * p.radius) z = std::max(z, p.z_max);
  return z;
}

bool Box::covers(double x, double y) const {
  if (yaw != 0.0) {  // into the box's own frame
    const double c = std::cos(yaw), s = std::sin(yaw);
    const double cx = 0.5 * (min.x() + max.x()), cy = 0.5 * (min.y() + max.y());
    const double dx = x - cx, dy = y - cy;
    x = c * dx + s * dy + cx;
    y = -s * dx + c * dy + cy;
  }
  return x >= min.x() && x <= max.x() && y >= min.y() && y <= max.y();
}

double constant_rate_nod(const Scanner& s, double t) {
  const double span = s.nod_max - s.nod_min;
  if (span <= 0.0 || s.nod_rate <= 0.0) return s.nod_min;
  const double half = span / s.nod_rate;  // time for one sweep up
  double ph = std::fmod(t, 2 * half);
  if (ph < 0) ph += 2 * half;
  return ph <= half ? s.nod_min + s.nod_rate * ph : s.nod_max - s.nod_rate * (ph - half);
}

NodTrajectory::NodTrajectory(const SimConfig& cfg, std::size_t lines)
    : t0_(cfg.t0), period_(cfg.scanner.line_period) {
  const Scanner& s = cfg.scanner;
  eta_.resize(lines + 1);
  if (s.profile == NodProfile::kConstantRate) {
    for (std::size_t k = 0; k <= lines; ++k) eta_[k] = constant_rate_nod(s, static_cast<double>(k) * period_);
    return;
  }
  // Uniform sample distance (Broten & Collier 4.2, 5.1): the depression below the horizon is
  // delta = mount pitch - eta; the ground point of the beam is x = h / tan(delta), and each line
  // moves it by d -/+ v tau (up: the vehicle's motion helps, down: it works against the nod).
  const double h = cfg.mount_translation.z() + (cfg.motion.follow_terrain ? cfg.motion.start.z()
                                                                           : cfg.motion.start.z() - cfg.scene.ground_z);
  const double pitch = cfg.mount_rpy.pitch;
  double eta_low = s.nod_min;
  if (s.dead_zone_time > 0.0 && cfg.motion.speed > 0.0) {
    // Dead zone (5.2): do not look nearer than the stopping distance s: delta_end = atan(h / s).
    const double stop = cfg.motion.speed * s.dead_zone_time;
    eta_low = std::max(eta_low, pitch - std::atan2(h, stop));
  }
  const double max_step = s.max_nod_rate * period_;
  double eta = s.nod_max;
  bool down = true;
  for (std::size_t k = 0; k <= lines; ++k) {
    eta_[k] = eta;
    const double delta = pitch - eta;
    double step = max_step;
    if (delta > 1e-3 && delta < kPi / 2) {
      const double x = h / std::tan(delta);
      const double dr = s.sample_distance + (down ? 1.0 : -1.0) * cfg.motion.speed * period_;
      const double x_next = down ? x - dr : x + dr;
      const double delta_next = x_next > 0 ? std::atan2(h, x_next) : kPi / 2;
      step = std::min(std::fabs(delta_next - delta), max_step);
    }
    if (s.encoder_resolution > 0) step = std::max(1.0, std::round(step / s.encoder_resolution)) * s.encoder_resolution;
    double next = down ? eta - step : eta + step;
    if (down && next <= eta_low) {
      next = eta_low;
      down = false;
    } else if (!down && next >= s.nod_max) {
      next = s.nod_max;
      down = true;
    }
    eta = next;
  }
}

double NodTrajectory::at(double t) const {
  const double u = (t - t0_) / period_;
  if (u <= 0) return eta_.front();
  const std::size_t k = static_cast<std::size_t>(u);
  if (k + 1 >= eta_.size()) return eta_.back();
  const double s = u - static_cast<double>(k);
  return eta_[k] + s * (eta_[k + 1] - eta_[k]);
}

Eigen::Isometry3d vehicle_pose(const SimConfig& cfg, double t) {
  const Motion& m = cfg.motion;
  const double tt = t - cfg.t0;
  const double yaw = m.yaw + m.yaw_rate * tt;
  Eigen::Vector3d pos;
  if (std::fabs(m.yaw_rate) < 1e-12) {
    pos = m.start + m.speed * tt * Eigen::Vector3d(std::cos(m.yaw), std::sin(m.yaw), 0.0);
  } else {  // arc of a circle
    const double r = m.speed / m.yaw_rate;
    pos = m.start + Eigen::Vector3d(r * (std::sin(yaw) - std::sin(m.yaw)), -r * (std::cos(yaw) - std::cos(m.yaw)), 0.0);
  }
  const double w = 2 * kPi * m.sway_frequency * tt;
  const double roll = m.roll_amplitude * std::sin(w), pitch = m.pitch_amplitude * std::sin(w + 1.0);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (m.follow_terrain) {
    pos.z() = cfg.scene.terrain_height(pos.x(), pos.y()) + m.start.z();
    T.linear() = terrain_frame(cfg.scene, pos.x(), pos.y(), yaw) * rot_x(roll) * rot_y(pitch);
  } else {
    T.linear() = rpy_to_matrix({roll, pitch, yaw}, cfg.rpy_order);
  }
  T.translation() = pos;
  return T;
}

BeamResult cast_beam(const SimConfig& cfg, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                     const Eigen::Vector3d& u, const Eigen::Vector3d& v, double bearing) {
  const Scanner& s = cfg.scanner;
  const int K = std::max(1, s.subrays);
  const double half = 0.5 * s.beam_divergence;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  const double theta = s.mirror ? bearing + s.transceiver_angle_offset : s.transceiver_angle_offset;
  const Eigen::Vector3d receiver = origin + s.transceiver_separation * (std::cos(theta) * u + std::sin(theta) * v);
  BeamResult r;
  double wsum = 0.0, wd = 0.0;
  struct Lit {
    double d;
    int object;
    double reflectivity, w;
  };
  std::vector<Lit> lit;  // visible sub-rays
  lit.reserve(static_cast<std::size_t>(K));
  for (int k = 0; k < K; ++k) {
    Eigen::Vector3d dk = dir;
    if (K > 1 && half > 0) {  // sunflower pattern: uniform over the disk of the footprint
      const double rho = std::tan(half * std::sqrt((k + 0.5) / K));
      const double phi = k * golden;
      dk = (dir + rho * (std::cos(phi) * u + std::sin(phi) * v)).normalized();
    }
    const Hit hit = cast(cfg.scene, origin, dk, s.range_max);
    if (!std::isfinite(hit.t)) continue;
    r.any_hit = true;
    const double cos_inc = std::fabs(hit.normal.dot(dk));
    const double w = s.amplitude_scale * hit.reflectivity * cos_inc /
                     (K * std::pow(std::max(hit.t, 0.1), s.amplitude_range_exponent));
    r.amplitude_full += w;
    const Eigen::Vector3d p = origin + hit.t * dk;
    const bool visible = s.transceiver_separation <= 0.0 || !blocked(cfg.scene, p, receiver);
    if (!visible) continue;
    lit.push_back({hit.t, hit.object, hit.reflectivity, w});
    r.amplitude += w;
    wsum += w;
    wd += w * hit.t;
  }
  if (wsum > 0) {
    r.range = wd / wsum;
    // Distance from the mixture range to the nearest lit surface: each object's lit sub-rays span
    // a depth interval (a slanted surface spans a long one at grazing incidence); the range is on
    // an object if it falls inside (or near) its interval.
    r.min_dev = kInf;
    std::vector<std::pair<double, double>> span;  // per object: min, max depth
    std::vector<int> ids;
    for (const auto& l : lit) {
      const auto it = std::find(ids.begin(), ids.end(), l.object);
      if (it == ids.end()) {
        ids.push_back(l.object);
        span.emplace_back(l.d, l.d);
      } else {
        auto& sp = span[static_cast<std::size_t>(it - ids.begin())];
        sp.first = std::min(sp.first, l.d);
        sp.second = std::max(sp.second, l.d);
      }
    }
    r.objects = static_cast<int>(ids.size());
    const auto [ln, lf] = std::minmax_element(lit.begin(), lit.end(), [](const Lit& a, const Lit& b) { return a.d < b.d; });
    r.near = ln->d;
    r.far = lf->d;
    r.near_object = ln->object;
    r.far_object = lf->object;
    r.near_reflectivity = ln->reflectivity;
    r.far_reflectivity = lf->reflectivity;
    double wn = 0.0;
    for (const auto& l : lit) wn += l.object == ln->object ? l.w : 0.0;
    r.near_power_share = wn / wsum;
    for (const auto& [lo, hi] : span)
      r.min_dev = std::min(r.min_dev, r.range < lo ? lo - r.range : r.range > hi ? r.range - hi : 0.0);
  }
  return r;
}

SimResult simulate(const SimConfig& cfg) {
  SimResult out;
  const Scanner& sc = cfg.scanner;
  std::mt19937_64 rng(cfg.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Isometry3d T_V_N = make_transform(cfg.mount_translation, cfg.mount_rpy, cfg.rpy_order);
  const double dt_beam = sc.line_period / sc.beams;
  const std::size_t total_lines = static_cast<std::size_t>(cfg.passes) * static_cast<std::size_t>(cfg.lines_per_pass);
  const NodTrajectory nod(cfg, total_lines + 1);
  std::uint32_t line_index = 0;
  for (int k = 0; k < cfg.passes; ++k) {
    SimPass sp;
    Pass& p = sp.pass;
    p.index = static_cast<std::size_t>(k);
    p.organized = true;
    for (int l = 0; l < cfg.lines_per_pass; ++l, ++line_index) {
      const double t_line = cfg.t0 + line_index * sc.line_period;
      const double t_read = t_line + (sc.beams - 1) * dt_beam;  // encoder read at the last return (3.2)
      const float reading = static_cast<float>(quantize(nod.at(t_read), sc.encoder_resolution));
      p.line_begin.push_back(p.range.size());
      for (int b = 0; b < sc.beams; ++b) {
        const double t = t_line + b * dt_beam;
        const double bearing = sc.beams > 1 ? sc.bearing_min + (sc.bearing_max - sc.bearing_min) * b / (sc.beams - 1)
                                            : sc.bearing_min;
        const double eta = nod.at(t);
        const Eigen::Isometry3d T_M_N = vehicle_pose(cfg, t) * T_V_N;
        const Eigen::Matrix3d& R = T_M_N.linear();
        const Eigen::Vector3d o = T_M_N.translation();
        const Eigen::Vector3d d = R * nod_frame_point(1.0, bearing, eta);
        const Eigen::Vector3d u = R * Eigen::Vector3d(-std::sin(bearing) * std::cos(eta), std::cos(bearing),
                                                      -std::sin(bearing) * std::sin(eta));  // d/d(bearing)
        const Eigen::Vector3d v = R * Eigen::Vector3d(-std::sin(eta), 0.0, std::cos(eta));  // d/d(nod), unit
        const BeamResult beam = cast_beam(cfg, o, d, u, v, bearing);
        const double xi = gauss(rng), a_noise = gauss(rng), coin = unit(rng), false_r = unit(rng);

        float range = 0.0f;
        Label truth = Label::kKept;
        Eigen::Vector3d point = Eigen::Vector3d::Constant(kNaN);
        if (!beam.any_hit) {
          truth = Label::kNoReturn;
        } else if (beam.amplitude < sc.min_amplitude || beam.amplitude <= 0.0) {
          if (coin < sc.false_range_probability) {
            range = static_cast<float>(quantize(sc.range_min + false_r * (sc.range_max - sc.range_min), sc.range_quantum));
            truth = beam.amplitude_full >= sc.min_amplitude ? Label::kOcclusion : Label::kLowAmplitude;
          } else {
            truth = Label::kNoReturn;
          }
        } else {
          const double z = sc.range_n * beam.range + sc.range_c + sc.range_sigma * xi;
          range = static_cast<float>(std::max(quantize(z, sc.range_quantum), 0.0));
          truth = beam.objects > 1 && beam.min_dev > sc.mixed_pixel_tolerance ? Label::kMixedPixel : Label::kKept;
          point = o + beam.range * d;
          if (range <= 0.0f) truth = Label::kNoReturn;
        }
        const double amp = std::clamp(std::round(beam.amplitude + sc.amplitude_sigma * a_noise), 0.0, 255.0);
        p.line.push_back(line_index);
        p.beam.push_back(static_cast<std::uint32_t>(b));
        p.range.push_back(range);
        p.bearing.push_back(static_cast<float>(bearing));
        p.amplitude.push_back(static_cast<float>(amp));
        p.nod.push_back(reading);
        p.stamp.push_back(t);
        sp.true_point.push_back(point);
        sp.true_nod.push_back(static_cast<float>(eta));
        sp.truth.push_back(truth);
        sp.true_amplitude.push_back(static_cast<float>(beam.amplitude));
        sp.footprint.push_back({static_cast<float>(beam.near), static_cast<float>(beam.far), beam.near_object,
                                beam.far_object, static_cast<float>(beam.near_reflectivity),
                                static_cast<float>(beam.far_reflectivity), static_cast<float>(beam.near_power_share)});
      }
    }
    p.line_begin.push_back(p.range.size());
    p.label.assign(p.range.size(), Label::kKept);
    p.flags.assign(p.range.size(), 0);
    out.passes.push_back(std::move(sp));
  }
  // Poses over the whole run (with a margin), written with IMU-like noise.
  const double t_end = cfg.t0 + line_index * sc.line_period + sc.line_period;
  const double dt = 1.0 / cfg.motion.pose_rate;
  const std::size_t n = static_cast<std::size_t>(std::ceil((t_end - cfg.t0) / dt)) + 3;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = cfg.t0 - dt + static_cast<double>(i) * dt;
    const Eigen::Isometry3d T = vehicle_pose(cfg, t);
    PoseSample truth{t, T.translation(), Eigen::Quaterniond(T.linear())};
    out.true_poses.push_back(truth);
    PoseSample noisy = truth;
    const double px = gauss(rng), py = gauss(rng), pz = gauss(rng), ar = gauss(rng), ap = gauss(rng), ay = gauss(rng);
    noisy.position += cfg.motion.position_sigma * Eigen::Vector3d(px, py, pz);
    if (cfg.motion.rpy_sigma > 0) {
      Rpy rpy = matrix_to_rpy(T.linear(), cfg.rpy_order);
      rpy.roll += cfg.motion.rpy_sigma * ar;
      rpy.pitch += cfg.motion.rpy_sigma * ap;
      rpy.yaw += cfg.motion.rpy_sigma * ay;
      noisy.orientation = Eigen::Quaterniond(rpy_to_matrix(rpy, cfg.rpy_order));
    }
    out.poses.push_back(noisy);
  }
  return out;
}

SimConfig geometric(SimConfig cfg) {
  Scanner& s = cfg.scanner;
  s.encoder_resolution = 0.0;
  s.range_n = 1.0;
  s.range_c = 0.0;
  s.range_sigma = 0.0;
  s.range_quantum = 0.0;
  s.beam_divergence = 0.0;
  s.subrays = 1;
  s.transceiver_separation = 0.0;
  s.amplitude_sigma = 0.0;
  s.min_amplitude = 0.0;
  s.false_range_probability = 0.0;
  cfg.motion.position_sigma = 0.0;
  cfg.motion.rpy_sigma = 0.0;
  return cfg;
}

}  // namespace pcdp::sim
