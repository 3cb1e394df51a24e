// The simulator's files: passes, truth and poses as `simulate` writes them (sample_scans/README.md).
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

// ---- writers ------------------------------------------------------------------------------

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

struct RowWriter {
  std::uint8_t* d;
  template <typename T>
  void put(const T& v) {
    std::memcpy(d, &v, sizeof(T));
    d += sizeof(T);
  }
};

/// Writes `n` rows through `fill(i, row)` into `path` via a temporary name.
template <typename Fill>
void write_pcd(const std::string& path, const std::vector<io::PcdField>& fields, std::size_t n, std::uint64_t height,
               Fill fill) {
  const std::string tmp = path + ".tmp";
  {
    io::PcdWriter w(tmp, fields);
    std::vector<std::uint8_t> rows(n * w.point_bytes());
    for (std::size_t i = 0; i < n; ++i) {
      RowWriter rw{rows.data() + i * w.point_bytes()};
      fill(i, rw);
    }
    w.append(rows.data(), n);
    w.close(height);
  }
  std::filesystem::rename(tmp, path);
}

std::string pass_name(std::size_t k) {
  char name[32];
  std::snprintf(name, sizeof name, "pass_%03zu.pcd", k);
  return name;
}
}  // namespace

void write_pass_pcd(const Pass& pass, const std::string& path) {
  const std::vector<io::PcdField> fields = {{"line", 'U', 4, 1},    {"beam", 'U', 4, 1},      {"range", 'F', 4, 1},
                                            {"bearing", 'F', 4, 1}, {"amplitude", 'F', 4, 1}, {"nod", 'F', 4, 1},
                                            {"stamp", 'F', 8, 1}};
  write_pcd(path, fields, pass.size(), pass.line_count(), [&](std::size_t i, RowWriter& w) {
    w.put(pass.line[i]);
    w.put(pass.beam[i]);
    w.put(pass.range[i]);
    w.put(pass.bearing[i]);
    w.put(pass.amplitude[i]);
    w.put(pass.nod[i]);
    w.put(pass.stamp[i]);
  });
}

void write_truth(const SimResult& r, const SimConfig& cfg, const std::string& dir, double res) {
  const std::filesystem::path tdir = std::filesystem::path(dir) / "truth";
  std::filesystem::create_directories(tdir);
  const std::vector<io::PcdField> fields = {{"line", 'U', 4, 1}, {"beam", 'U', 4, 1},  {"x", 'F', 4, 1},
                                            {"y", 'F', 4, 1},    {"z", 'F', 4, 1},     {"nod", 'F', 4, 1},
                                            {"label", 'U', 1, 1}, {"amplitude", 'F', 4, 1}};
  double xmin = kInf, xmax = -kInf, ymin = kInf, ymax = -kInf;
  for (std::size_t k = 0; k < r.passes.size(); ++k) {
    const SimPass& sp = r.passes[k];
    for (const auto& p : sp.true_point)
      if (std::isfinite(p.x())) {
        xmin = std::min(xmin, p.x());
        xmax = std::max(xmax, p.x());
        ymin = std::min(ymin, p.y());
        ymax = std::max(ymax, p.y());
      }
    write_pcd((tdir / pass_name(k)).string(), fields, sp.pass.size(), sp.pass.line_count(),
              [&](std::size_t i, RowWriter& w) {
                w.put(sp.pass.line[i]);
                w.put(sp.pass.beam[i]);
                w.put(static_cast<float>(sp.true_point[i].x()));
                w.put(static_cast<float>(sp.true_point[i].y()));
                w.put(static_cast<float>(sp.true_point[i].z()));
                w.put(sp.true_nod[i]);
                w.put(static_cast<std::uint8_t>(sp.truth[i]));
                w.put(sp.true_amplitude[i]);
              });
  }
  if (!(xmax >= xmin)) return;
  // The true top surface over the observed extent, cell centres on a `res` grid.
  const double x0 = std::floor(xmin / res) * res, y0 = std::floor(ymin / res) * res;
  const std::size_t nx = static_cast<std::size_t>(std::ceil((xmax - x0) / res)) + 1;
  const std::size_t ny = static_cast<std::size_t>(std::ceil((ymax - y0) / res)) + 1;
  const std::vector<io::PcdField> gf = {{"x", 'F', 4, 1}, {"y", 'F', 4, 1}, {"z", 'F', 4, 1}};
  write_pcd((tdir / "height.pcd").string(), gf, nx * ny, ny, [&](std::size_t i, RowWriter& w) {
    const double x = x0 + (static_cast<double>(i % nx) + 0.5) * res, y = y0 + (static_cast<double>(i / nx) + 0.5) * res;
    w.put(static_cast<float>(x));
    w.put(static_cast<float>(y));
    w.put(static_cast<float>(cfg.scene.top_height(x, y)));
  });
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

std::vector<std::string> write_run(const SimResult& r, const SimConfig& cfg, const std::string& dir) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  for (std::size_t k = 0; k < r.passes.size(); ++k) {
    const std::string path = (std::filesystem::path(dir) / pass_name(k)).string();
    write_pass_pcd(r.passes[k].pass, path);
    files.push_back(path);
  }
  write_pose_csv(r.poses, cfg.rpy_order, (std::filesystem::path(dir) / "poses.csv").string());
  return files;
}

}  // namespace pcdp::sim
