#include "pcdp/core/cloud_pass.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace pcdp {

Pass pass_from_cloud(const CartesianCloud& c) {
  const std::size_t n = c.points.size();
  if (c.height == 0 || n != c.width * c.height)
    throw std::invalid_argument("pass_from_cloud: " + std::to_string(n) + " points is not width " +
                                std::to_string(c.width) + " x height " + std::to_string(c.height));
  if (!c.intensity.empty() && c.intensity.size() != n)
    throw std::invalid_argument("pass_from_cloud: " + std::to_string(c.intensity.size()) + " intensities for " +
                                std::to_string(n) + " points");
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  constexpr double kNaNd = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Matrix3d R_cloud_sensor = c.orientation.normalized().toRotationMatrix();
  Pass p;
  p.organized = c.height > 1;
  p.line.resize(n);
  p.beam.resize(n);
  p.range.resize(n);
  p.bearing.resize(n);
  p.amplitude.assign(n, kNaN);
  p.nod.resize(n);
  p.stamp.resize(n);
  p.label.assign(n, Label::kKept);
  p.flags.assign(n, 0);
  p.range_cal.resize(n);
  p.nod_at_return.resize(n);
  p.x.resize(n);
  p.y.resize(n);
  p.z.resize(n);
  p.ox.assign(n, c.origin.x());
  p.oy.assign(n, c.origin.y());
  p.oz.assign(n, c.origin.z());
  std::vector<double> nods;
  for (std::size_t row = 0; row < c.height; ++row) {
    p.line_begin.push_back(row * c.width);
    nods.clear();
    for (std::size_t col = 0; col < c.width; ++col) {
      const std::size_t i = row * c.width + col;
      p.line[i] = static_cast<std::uint32_t>(row);
      p.beam[i] = static_cast<std::uint32_t>(col);
      p.stamp[i] = static_cast<double>(i);  // order only: a cloud has no times
      if (!c.intensity.empty()) p.amplitude[i] = c.intensity[i];
      const Eigen::Vector3d q = c.points[i].cast<double>();
      const Eigen::Vector3d d = R_cloud_sensor.transpose() * (q - c.origin);
      const double r = d.norm();
      if (!q.allFinite() || !(r > 0.0)) {
        p.label[i] = Label::kNoReturn;
        p.range[i] = 0.0f;
        p.range_cal[i] = kNaN;
        p.x[i] = p.y[i] = p.z[i] = kNaNd;
        p.bearing[i] = kNaN;
        p.nod_at_return[i] = kNaN;
        continue;
      }
      p.x[i] = q.x();
      p.y[i] = q.y();
      p.z[i] = q.z();
      p.range[i] = static_cast<float>(r);
      p.range_cal[i] = static_cast<float>(r);
      p.bearing[i] = static_cast<float>(std::atan2(d.y(), std::hypot(d.x(), d.z())));
      p.nod_at_return[i] = static_cast<float>(std::atan2(d.z(), d.x()));
      nods.push_back(p.nod_at_return[i]);
    }
    double nod = 0.0;
    if (!nods.empty()) {
      std::nth_element(nods.begin(), nods.begin() + static_cast<long>(nods.size() / 2), nods.end());
      nod = nods[nods.size() / 2];
    }
    for (std::size_t col = 0; col < c.width; ++col) {
      const std::size_t i = row * c.width + col;
      p.nod[i] = static_cast<float>(nod);
      if (!std::isfinite(p.nod_at_return[i])) p.nod_at_return[i] = static_cast<float>(nod);
    }
  }
  p.line_begin.push_back(n);
  // A no-return's bearing: its column's neighbours along the row (interpolated), else 0.
  for (std::size_t row = 0; row < c.height; ++row)
    for (std::size_t col = 0; col < c.width; ++col) {
      const std::size_t i = row * c.width + col;
      if (std::isfinite(p.bearing[i])) continue;
      float b = 0.0f;
      for (std::size_t k = 1; k < c.width; ++k) {
        if (col >= k && std::isfinite(p.bearing[i - k])) { b = p.bearing[i - k]; break; }
        if (col + k < c.width && std::isfinite(p.bearing[i + k])) { b = p.bearing[i + k]; break; }
      }
      p.bearing[i] = b;
    }
  return p;
}

}  // namespace pcdp
