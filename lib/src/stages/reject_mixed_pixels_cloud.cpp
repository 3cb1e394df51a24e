// Stage `reject_mixed_pixels` on an unorganized cloud seen from one viewpoint: the cloud is put
// back into a range image and the organized tests run along its rows and columns
// (reject_mixed_pixels.hpp, mixed_pixels_in_cloud).
#include <algorithm>
#include <cmath>
#include <map>

#include "pcdp/stages/reject_mixed_pixels.hpp"
#include "reject_mixed_pixels_detail.hpp"

namespace pcdp {

using mixed_detail::is_mixed;
using mixed_detail::mark_smooth;

std::vector<char> mixed_pixels_in_cloud(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& viewpoint,
                                        const std::vector<float>& amplitude, double resolution,
                                        const MixedPixelParams& p, double range_sigma, CloudAngles angles,
                                        const Eigen::Quaterniond& orientation) {
  const Eigen::Matrix3d R_cloud_sensor = orientation.normalized().toRotationMatrix();
  const std::size_t n = points.size();
  std::vector<double> x(n), y(n), z(n), ox(n, viewpoint.x()), oy(n, viewpoint.y()), oz(n, viewpoint.z());
  std::vector<float> range(n);
  std::vector<char> usable(n), mixed(n, 0);
  std::vector<double> az(n), el(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = points[i] - viewpoint;
    x[i] = points[i].x();
    y[i] = points[i].y();
    z[i] = points[i].z();
    range[i] = static_cast<float>(d.norm());
    usable[i] = std::isfinite(range[i]) && range[i] > 0;
    const Eigen::Vector3d ds = R_cloud_sensor.transpose() * d;
    if (angles == CloudAngles::kNodding) {  // az: bearing in the scan plane, el: nod of the plane
      az[i] = std::atan2(ds.y(), std::hypot(ds.x(), ds.z()));
      el[i] = std::atan2(ds.z(), ds.x());
    } else {
      az[i] = std::atan2(ds.y(), ds.x());
      el[i] = std::atan2(ds.z(), std::hypot(ds.x(), ds.y()));
    }
  }
  ReturnsView v{n, x.data(), y.data(), z.data(), ox.data(), oy.data(), oz.data(), range.data(),
                amplitude.size() == n ? amplitude.data() : nullptr, usable.data(), true};
  // Bands of the spherical range image: rows (elevation) sorted by azimuth, columns (azimuth)
  // sorted by elevation.
  const auto band = [&](double a) { return static_cast<long>(std::floor(a / resolution + 0.5)); };
  std::map<long, std::vector<std::size_t>> rows, cols;
  for (std::size_t i = 0; i < n; ++i) {
    if (!usable[i]) continue;
    rows[band(el[i])].push_back(i);
    cols[band(az[i])].push_back(i);
  }
  // No spike test here (MixedPixelParams::spikes): a band of the range image interleaves the
  // returns of neighbouring scan lines, so a return nearer than its two neighbours in the band is
  // often just the nearer of two interleaved lines (bands alternating between two lines' ranges).
  std::vector<char> along(n, 0), across(n, 0), smooth_along(n, 0), smooth_across(n, 0);
  for (auto& [k, seq] : rows) {
    std::sort(seq.begin(), seq.end(), [&](std::size_t a, std::size_t b) { return az[a] < az[b]; });
    mark_mixed_pixels(v, seq, p, range_sigma, true, along);
    mark_smooth(v, seq, p, range_sigma, smooth_along);
  }
  for (auto& [k, seq] : cols) {
    std::sort(seq.begin(), seq.end(), [&](std::size_t a, std::size_t b) { return el[a] < el[b]; });
    mark_mixed_pixels(v, seq, p, range_sigma, true, across);
    mark_smooth(v, seq, p, range_sigma, smooth_across);
  }
  for (std::size_t i = 0; i < n; ++i)
    mixed[i] = is_mixed(along[i], smooth_across[i]) || is_mixed(across[i], smooth_along[i]);
  return mixed;
}

}  // namespace pcdp
