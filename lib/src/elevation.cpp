#include "pcdp/elevation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pcdp {

void ElevationCell::absorb(const HeightBand& b) {
  if (b.empty()) return;
  for (auto& x : bands)
    if (!x.empty() && x.index == b.index) {
      x.w += b.w;
      x.wz += b.wz;
      x.count += b.count;
      return;
    }
  // Insert keeping the highest kBands, highest first.
  int pos = 0;
  while (pos < kBands && !bands[static_cast<std::size_t>(pos)].empty() && bands[static_cast<std::size_t>(pos)].index > b.index) ++pos;
  if (pos == kBands) return;  // lower than every kept band
  for (int k = kBands - 1; k > pos; --k) bands[static_cast<std::size_t>(k)] = bands[static_cast<std::size_t>(k - 1)];
  bands[static_cast<std::size_t>(pos)] = b;
}

void ElevationCell::surface(std::uint32_t min_support, double& w, double& wz) const {
  w = wz = 0;
  for (int k = 0; k < kBands; ++k) {
    const HeightBand& b = bands[static_cast<std::size_t>(k)];
    if (b.empty()) return;
    if (b.count < min_support) continue;
    w = b.w;
    wz = b.wz;
    if (k + 1 < kBands) {
      const HeightBand& below = bands[static_cast<std::size_t>(k + 1)];
      if (!below.empty() && below.index == b.index - 1) {
        w += below.w;
        wz += below.wz;
      }
    }
    return;
  }
}

void ElevationGrid::add(double x, double y, double z, double var_z, std::int32_t pass) {
  ElevationCell& c = cells_[key(cell_index(x), cell_index(y))];
  HeightBand b;
  b.index = static_cast<std::int32_t>(std::floor(z / band_));
  b.w = 1.0 / var_z;
  b.wz = z / var_z;
  b.count = 1;
  c.absorb(b);
  ++c.count;
  if (pass != c.last_pass) {
    ++c.passes;
    c.last_pass = pass;
  }
  c.zmin = std::min(c.zmin, static_cast<float>(z));
  c.zmax = std::max(c.zmax, static_cast<float>(z));
}

void ElevationGrid::merge(const ElevationGrid& other) {
  if (std::fabs(other.res_ - res_) > 1e-12 || std::fabs(other.band_ - band_) > 1e-12)
    throw std::invalid_argument("elevation grids differ in resolution or band and cannot be merged");
  for (const auto& [k, o] : other.cells_) {
    if (o.empty()) continue;
    ElevationCell& c = cells_[k];
    for (const auto& b : o.bands) c.absorb(b);
    c.count += o.count;
    c.passes += o.passes;
    c.zmin = std::min(c.zmin, o.zmin);
    c.zmax = std::max(c.zmax, o.zmax);
  }
}

void ElevationGrid::set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c) { cells_[key(ix, iy)] = c; }

bool ElevationGrid::surface(const ElevationCell& c, double& elevation, double& variance) const {
  double w, wz;
  c.surface(min_support_, w, wz);
  if (w <= 0) return false;
  elevation = wz / w;
  variance = 1.0 / w;
  return true;
}

const ElevationCell* ElevationGrid::find(std::int64_t ix, std::int64_t iy) const {
  const auto it = cells_.find(key(ix, iy));
  return it == cells_.end() ? nullptr : &it->second;
}

bool ElevationGrid::bounds(std::int64_t& ix0, std::int64_t& iy0, std::int64_t& ix1, std::int64_t& iy1) const {
  bool any = false;
  for (const auto& [k, c] : cells_) {
    if (c.empty()) continue;
    const std::int64_t x = unkey_x(k), y = unkey_y(k);
    if (!any) {
      ix0 = ix1 = x;
      iy0 = iy1 = y;
      any = true;
    }
    ix0 = std::min(ix0, x);
    ix1 = std::max(ix1, x);
    iy0 = std::min(iy0, y);
    iy1 = std::max(iy1, y);
  }
  return any;
}

}  // namespace pcdp
