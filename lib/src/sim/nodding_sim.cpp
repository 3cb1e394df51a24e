#include "pcdp/sim/nodding_sim.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <random>
#include <cstring>
#include <sstream>

#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/pcd.hpp"

namespace pcdp::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Hit {
  double t = std::numeric_limits<double>::infinity();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double reflectivity = 0.0;
};

void hit_box(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, Hit& hit) {
  double tmin = 0.0, tmax = hit.t;
  int axis = -1;
  double sign = 1.0;
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(d[a]) < 1e-15) {
      if (o[a] < b.min[a] || o[a] > b.max[a]) return;
      continue;
    }
    double t1 = (b.min[a] - o[a]) / d[a], t2 = (b.max[a] - o[a]) / d[a];
    double s = -1.0;  // entering through the min face: normal -axis
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
    if (tmin > tmax) return;
  }
  if (axis < 0 || tmin <= 1e-9) return;  // origin inside the box: ignore
  hit.t = tmin;
  hit.normal = Eigen::Vector3d::Zero();
  hit.normal[axis] = sign;
  hit.reflectivity = b.reflectivity;
}

void hit_terrain(const Scene& sc, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max, Hit& hit) {
  const auto above = [&](double t) {
    const Eigen::Vector3d p = o + t * d;
    return p.z() - sc.terrain_height(p.x(), p.y());
  };
  if (sc.undulation_amplitude == 0.0) {
    if (std::fabs(d.z()) < 1e-15) return;
    const double t = (sc.ground_z - o.z()) / d.z();
    if (t > 1e-9 && t < hit.t && t <= t_max) {
      hit.t = t;
      hit.normal = Eigen::Vector3d::UnitZ();
      hit.reflectivity = sc.ground_reflectivity;
    }
    return;
  }
  // March, then bisect the first sign change.
  const double step = std::min(0.05, sc.undulation_wavelength / 50.0);
  double t_prev = 0.0, f_prev = above(0.0);
  if (f_prev <= 0.0) return;
  const double t_end = std::min(t_max, hit.t);
  for (double t = step; t <= t_end + step; t += step) {
    const double f = above(t);
    if (f <= 0.0) {
      double lo = t_prev, hi = t;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        (above(mid) > 0.0 ? lo : hi) = mid;
      }
      const double th = 0.5 * (lo + hi);
      if (th < hit.t && th <= t_max) {
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
    t_prev = t;
    f_prev = f;
  }
}
}  // namespace

double Scene::terrain_height(double x, double y) const {
  if (undulation_amplitude == 0.0) return ground_z;
  const double k = 2 * kPi / undulation_wavelength;
  return ground_z + undulation_amplitude * std::sin(k * x) * std::cos(k * y);
}

double true_nod(const Scanner& s, double t) {
  const double span = s.nod_max - s.nod_min;
  if (span <= 0.0 || s.nod_rate <= 0.0) return s.nod_min;
  const double half = span / s.nod_rate;  // time for one sweep up
  double ph = std::fmod(t, 2 * half);
  if (ph < 0) ph += 2 * half;
  return ph <= half ? s.nod_min + s.nod_rate * ph : s.nod_max - s.nod_rate * (ph - half);
}

Eigen::Isometry3d vehicle_pose(const SimConfig& cfg, double t) {
  const Motion& m = cfg.motion;
  const double yaw = m.yaw + m.yaw_rate * t;
  Eigen::Vector3d pos;
  if (std::fabs(m.yaw_rate) < 1e-12) {
    pos = m.start + m.speed * t * Eigen::Vector3d(std::cos(m.yaw), std::sin(m.yaw), 0.0);
  } else {  // arc of a circle
    const double r = m.speed / m.yaw_rate;
    pos = m.start + Eigen::Vector3d(r * (std::sin(yaw) - std::sin(m.yaw)), -r * (std::cos(yaw) - std::cos(m.yaw)), 0.0);
  }
  const double w = 2 * kPi * m.sway_frequency * t;
  const Rpy rpy{m.roll_amplitude * std::sin(w), m.pitch_amplitude * std::sin(w + 1.0), yaw};
  return make_transform(pos, rpy, cfg.rpy_order);
}

SimResult simulate(const SimConfig& cfg) {
  SimResult out;
  const Scanner& sc = cfg.scanner;
  std::mt19937_64 rng(cfg.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Eigen::Isometry3d T_V_N = make_transform(cfg.mount_translation, cfg.mount_rpy, cfg.rpy_order);
  const double dt_beam = sc.line_period / sc.beams;
  std::uint32_t line_index = 0;
  for (int k = 0; k < cfg.passes; ++k) {
    SimPass sp;
    Pass& p = sp.pass;
    p.index = static_cast<std::size_t>(k);
    p.organized = true;
    for (int l = 0; l < cfg.lines_per_pass; ++l, ++line_index) {
      const double t_line = cfg.t0 + line_index * sc.line_period;
      const double t_read = t_line + (sc.beams - 1) * dt_beam;  // the last return's stamp
      double reading = true_nod(sc, t_read);
      if (sc.encoder_resolution > 0) reading = std::round(reading / sc.encoder_resolution) * sc.encoder_resolution;
      p.line_begin.push_back(p.range.size());
      for (int b = 0; b < sc.beams; ++b) {
        const double t = t_line + b * dt_beam;
        const double bearing = sc.beams > 1 ? sc.bearing_min + (sc.bearing_max - sc.bearing_min) * b / (sc.beams - 1)
                                            : sc.bearing_min;
        const double eta = true_nod(sc, t);
        const Eigen::Isometry3d T_M_N = vehicle_pose(cfg, t) * T_V_N;
        const Eigen::Vector3d o = T_M_N.translation();
        const Eigen::Vector3d d = T_M_N.linear() * nod_frame_point(1.0, bearing, eta);
        Hit hit;
        for (const auto& box : cfg.scene.boxes) hit_box(box, o, d, hit);
        hit_terrain(cfg.scene, o, d, sc.range_max, hit);
        float range = 0.0f, amp = 0.0f;
        Eigen::Vector3d truth = Eigen::Vector3d::Constant(kNaN);
        if (hit.t <= sc.range_max) {
          truth = o + hit.t * d;
          double r = hit.t + (sc.range_sigma > 0 ? sc.range_sigma * noise(rng) : 0.0);
          range = static_cast<float>(r);
          const double cos_inc = std::fabs(hit.normal.dot(d));
          amp = static_cast<float>(std::min(255.0, sc.amplitude_scale * hit.reflectivity * cos_inc / std::max(hit.t, 0.1)));
        }
        p.line.push_back(line_index);
        p.beam.push_back(static_cast<std::uint32_t>(b));
        p.range.push_back(range);
        p.bearing.push_back(static_cast<float>(bearing));
        p.amplitude.push_back(amp);
        p.nod.push_back(static_cast<float>(reading));
        p.stamp.push_back(t);
        sp.true_point.push_back(truth);
        sp.true_nod.push_back(static_cast<float>(eta));
      }
    }
    p.line_begin.push_back(p.range.size());
    p.label.assign(p.range.size(), Label::kKept);
    out.passes.push_back(std::move(sp));
  }
  const double t_end = cfg.t0 + line_index * sc.line_period + sc.line_period;
  const double dt = 1.0 / cfg.motion.pose_rate;
  for (double t = cfg.t0 - dt; t <= t_end + dt; t += dt) {
    const Eigen::Isometry3d T = vehicle_pose(cfg, t);
    out.poses.push_back({t, T.translation(), Eigen::Quaterniond(T.linear())});
  }
  return out;
}

void write_pass_pcd(const Pass& pass, const std::string& path) {
  const std::vector<io::PcdField> fields = {{"line", 'U', 4, 1},      {"beam", 'U', 4, 1}, {"range", 'F', 4, 1},
                                            {"bearing", 'F', 4, 1},   {"amplitude", 'F', 4, 1},
                                            {"nod", 'F', 4, 1},       {"stamp", 'F', 8, 1}};
  const std::string tmp = path + ".tmp";
  {
    io::PcdWriter w(tmp, fields);
    std::vector<std::uint8_t> row(w.point_bytes());
    for (std::size_t i = 0; i < pass.size(); ++i) {
      std::uint8_t* d = row.data();
      const auto put = [&](const void* v, std::size_t n) {
        std::memcpy(d, v, n);
        d += n;
      };
      put(&pass.line[i], 4);
      put(&pass.beam[i], 4);
      put(&pass.range[i], 4);
      put(&pass.bearing[i], 4);
      put(&pass.amplitude[i], 4);
      put(&pass.nod[i], 4);
      put(&pass.stamp[i], 8);
      w.append(row.data(), 1);
    }
    w.close(pass.line_count());
  }
  std::filesystem::rename(tmp, path);
}

void write_pose_csv(const std::vector<PoseSample>& poses, RpyOrder order, const std::string& path) {
  std::ostringstream os;
  os << "stamp,x,y,z,roll,pitch,yaw\n" << std::setprecision(17);
  for (const auto& p : poses) {
    const Rpy r = matrix_to_rpy(p.orientation.toRotationMatrix(), order);
    os << p.stamp << ',' << p.position.x() << ',' << p.position.y() << ',' << p.position.z() << ',' << r.roll << ','
       << r.pitch << ',' << r.yaw << '\n';
  }
  io::write_file_atomic(path, os.str());
}

void write_truth(const SimResult& r, const std::string& dir) {
  const std::filesystem::path tdir = std::filesystem::path(dir) / "truth";
  std::filesystem::create_directories(tdir);
  const std::vector<io::PcdField> fields = {{"line", 'U', 4, 1}, {"beam", 'U', 4, 1}, {"x", 'F', 8, 1},
                                            {"y", 'F', 8, 1},    {"z", 'F', 8, 1},    {"nod", 'F', 4, 1},
                                            {"label", 'U', 1, 1}};
  for (std::size_t k = 0; k < r.passes.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "pass_%03zu.pcd", k);
    const std::string path = (tdir / name).string();
    const SimPass& sp = r.passes[k];
    {
      io::PcdWriter w(path + ".tmp", fields);
      std::vector<std::uint8_t> row(w.point_bytes());
      for (std::size_t i = 0; i < sp.pass.size(); ++i) {
        std::uint8_t* d = row.data();
        const auto put = [&](const void* v, std::size_t n) {
          std::memcpy(d, v, n);
          d += n;
        };
        const std::uint8_t label = std::isnan(sp.true_point[i].x()) ? 1 : 0;
        put(&sp.pass.line[i], 4);
        put(&sp.pass.beam[i], 4);
        put(&sp.true_point[i].x(), 8);
        put(&sp.true_point[i].y(), 8);
        put(&sp.true_point[i].z(), 8);
        put(&sp.true_nod[i], 4);
        put(&label, 1);
        w.append(row.data(), 1);
      }
      w.close(sp.pass.line_count());
    }
    std::filesystem::rename(path + ".tmp", path);
  }
}

std::vector<std::string> write_run(const SimResult& r, const SimConfig& cfg, const std::string& dir) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  for (std::size_t k = 0; k < r.passes.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "pass_%03zu.pcd", k);
    const std::string path = (std::filesystem::path(dir) / name).string();
    write_pass_pcd(r.passes[k].pass, path);
    files.push_back(path);
  }
  write_pose_csv(r.poses, cfg.rpy_order, (std::filesystem::path(dir) / "poses.csv").string());
  return files;
}

}  // namespace pcdp::sim
