#include "kurt3d_reference.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <utility>

#include <Eigen/Dense>

namespace pcdp::test {

Kurt3DScan read_kurt3d_scan(const std::string& path) {
  Kurt3DScan s;
  std::ifstream in(path);
  std::string header;
  if (!in || !std::getline(in, header)) return s;
  for (double x, y, z; in >> x >> y >> z;) s.points.emplace_back(x / 100.0, y / 100.0, z / 100.0);
  s.range.resize(s.points.size());
  s.valid.resize(s.points.size());
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    s.range[i] = s.points[i].norm();
    s.valid[i] = s.range[i] > 0.48 && s.range[i] < 32.7;
  }
  return s;
}

Kurt3DScore score_kurt3d(const Kurt3DScan& s, const std::vector<char>& removed, const std::vector<char>& scored) {
  Kurt3DScore sc;
  const auto& p = s.points;
  const auto& rg = s.range;
  const auto& ok = s.valid;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!ok[i] || !scored[i] || p[i].x() <= 0.5 || p[i].z() < 3.0 || p[i].z() > 12.0 || p[i].y() < 0.0 || p[i].y() > 1.2)
      continue;
    ++sc.wall;
    sc.wall_removed += removed[i] != 0;
  }
  const std::size_t W = Kurt3DScan::kBeams;
  for (std::size_t l = 1; l + 1 < Kurt3DScan::kLines; ++l)
    for (std::size_t b = 1; b + 1 < W; ++b) {
      const std::size_t i = l * W + b;
      if (i + W >= p.size() || !ok[i - 1] || !ok[i] || !ok[i + 1] || !scored[i]) continue;
      const double r0 = rg[i - 1], r1 = rg[i], r2 = rg[i + 1];
      if (!(std::fabs(r0 - r2) > 1.0 && std::fabs(r1 - r0) > 0.2 && std::fabs(r1 - r2) > 0.2 && r1 > std::min(r0, r2) &&
            r1 < std::max(r0, r2)))
        continue;
      // Where the beam meets the line through the two neighbours (least squares: s u = p0 + t d).
      const Eigen::Vector3d u = p[i] / r1, p0 = p[i - 1], d = p[i + 1] - p[i - 1];
      const double ud = u.dot(d), dd = d.dot(d), det = dd - ud * ud;
      const double at = det > 1e-12 ? (u.dot(p0) * dd - ud * d.dot(p0)) / det : NAN;
      const bool off_line = !(std::fabs(r1 - at) <= 0.05);
      const auto far_across = [&](std::size_t j) { return ok[j] && std::fabs(rg[j] - r1) > 0.2; };
      const bool rough = far_across(i - W) && far_across(i + W);
      std::size_t& n = !off_line ? sc.on_line : rough ? sc.veils : sc.flat;
      std::size_t& m = !off_line ? sc.on_line_removed : rough ? sc.veils_removed : sc.flat_removed;
      ++n;
      m += removed[i] != 0;
    }
  // The floor and ceiling (y up): y = a x + b z + c through the points in each height band.
  std::vector<char> on_plane(p.size(), 0);
  for (const auto& [lo, hi] : {std::pair{-0.5, -0.3}, std::pair{1.9, 2.1}}) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < p.size(); ++i)
      if (ok[i] && p[i].y() > lo && p[i].y() < hi) {
        const Eigen::Vector3d row(p[i].x(), p[i].z(), 1.0);
        A += row * row.transpose();
        rhs += row * p[i].y();
      }
    const Eigen::Vector3d abc = A.ldlt().solve(rhs);
    for (std::size_t i = 0; i < p.size(); ++i)
      if (ok[i] && std::fabs(p[i].y() - (abc[0] * p[i].x() + abc[1] * p[i].z() + abc[2])) < 0.02) on_plane[i] = 1;
  }
  for (std::size_t l = 1; l + 1 < Kurt3DScan::kLines; ++l)
    for (std::size_t b = 1; b + 1 < W; ++b) {
      const std::size_t i = l * W + b;
      if (i + W >= p.size() || !scored[i]) continue;
      if (on_plane[i] && on_plane[i - 1] && on_plane[i + 1] && on_plane[i - W] && on_plane[i + W]) {
        ++sc.planar;
        sc.planar_removed += removed[i] != 0;
      }
    }
  return sc;
}

void expect_kurt3d_bars(const Kurt3DScore& sc, double min_veils, const std::string& what) {
  const auto share = [](std::size_t n, std::size_t of) { return static_cast<double>(n) / static_cast<double>(of); };
  ASSERT_GT(sc.wall, 500u) << what;
  ASSERT_GT(sc.on_line, 50u) << what;
  ASSERT_GT(sc.veils, 25u) << what;
  ASSERT_GT(sc.planar, 5000u) << what;
  EXPECT_LE(share(sc.wall_removed, sc.wall), 0.10) << what << ": the wall is not gutted";
  EXPECT_LE(share(sc.on_line_removed, sc.on_line), 0.15) << what << ": planes at grazing incidence stay";
  EXPECT_GE(share(sc.veils_removed, sc.veils), min_veils) << what << ": the veils go";
  EXPECT_LE(share(sc.planar_removed, sc.planar), 0.01) << what << ": the 1 % budget";
}

}  // namespace pcdp::test
