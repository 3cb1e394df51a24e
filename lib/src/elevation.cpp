#include "pcdp/elevation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pcdp {

void ElevationGrid::absorb(ElevationCell& c, std::int32_t b, double w, double wz) {
  if (b > c.top) {  // a new top band: the old top becomes "next" if adjacent, else both drop
    if (b == c.top + 1) {
      c.w_next = c.w_top;
      c.wz_next = c.wz_top;
    } else {
      c.w_next = c.wz_next = 0;
    }
    c.w_top = c.wz_top = 0;
    c.top = b;
  }
  if (b == c.top) {
    c.w_top += w;
    c.wz_top += wz;
  } else if (b == c.top - 1) {
    c.w_next += w;
    c.wz_next += wz;
  }  // lower bands: not fused (overhang, face)
}

void ElevationGrid::add(double x, double y, double z, double var_z, std::int32_t pass) {
  ElevationCell& c = cells_[key(cell_index(x), cell_index(y))];
  const std::int32_t b = static_cast<std::int32_t>(std::floor(z / band_));
  absorb(c, b, 1.0 / var_z, z / var_z);
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
    // Bring in the other's two bands (highest first): the result holds the top two bands of the
    // union, whatever the order.
    if (o.top > c.top) {
      const ElevationCell mine = c;
      c.top = o.top;
      c.w_top = o.w_top;
      c.wz_top = o.wz_top;
      c.w_next = o.w_next;
      c.wz_next = o.wz_next;
      if (mine.count) {
        if (mine.top == c.top - 1) {
          c.w_next += mine.w_top;
          c.wz_next += mine.wz_top;
        }
      }
    } else {
      if (o.top == c.top) {
        c.w_top += o.w_top;
        c.wz_top += o.wz_top;
        c.w_next += o.w_next;
        c.wz_next += o.wz_next;
      } else if (o.top == c.top - 1) {
        c.w_next += o.w_top;
        c.wz_next += o.wz_top;
      }
    }
    c.count += o.count;
    c.passes += o.passes;
    c.zmin = std::min(c.zmin, o.zmin);
    c.zmax = std::max(c.zmax, o.zmax);
  }
}

void ElevationGrid::set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c) { cells_[key(ix, iy)] = c; }

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
