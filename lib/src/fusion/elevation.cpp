#include "pcdp/fusion/elevation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

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

ElevationCell& ElevationGrid::touch(std::uint64_t k) {
  std::uint32_t& slot = index_[k];
  if (slot == 0) {  // new: the index holds place + 1, so that 0 (its default) means absent
    if (size_ == chunks_.size() * kChunk) chunks_.emplace_back();
    chunks_[size_ / kChunk].keys[size_ % kChunk] = k;
    slot = static_cast<std::uint32_t>(++size_);
  }
  return cell(slot - 1);
}

void ElevationGrid::set_key_origin(std::int64_t ix, std::int64_t iy) {
  if (size_ != 0) throw std::logic_error("ElevationGrid::set_key_origin on a grid that holds cells");
  kx0_ = ix;
  ky0_ = iy;
  set_limits();
}

void ElevationGrid::set_limits() {
  constexpr double kCells = static_cast<double>(kKeyReach) - 2.0, kBands = 2147483648.0 - 2.0;
  lim_[0] = (static_cast<double>(kx0_) - kCells) * res_;
  lim_[1] = (static_cast<double>(kx0_) + kCells) * res_;
  lim_[2] = (static_cast<double>(ky0_) - kCells) * res_;
  lim_[3] = (static_cast<double>(ky0_) + kCells) * res_;
  lim_[4] = kBands * band_;
}

std::uint64_t ElevationGrid::checked_key(std::int64_t ix, std::int64_t iy) const {
  if (!holds(ix, iy))
    throw std::out_of_range("elevation grid: cell (" + std::to_string(ix) + ", " + std::to_string(iy) +
                            ") is more than 2^30 cells from the grid's key origin (" + std::to_string(kx0_) + ", " +
                            std::to_string(ky0_) + ")");
  return key(ix, iy);
}

ElevationSample ElevationGrid::sample(double x, double y, double z, double var_z, std::int32_t pass) const {
  ElevationSample s;
  s.key = checked_key(cell_index(x), cell_index(y));
  s.band = static_cast<std::int32_t>(std::floor(z / band_));
  s.pass = pass;
  s.w = 1.0 / var_z;
  s.wz = z / var_z;
  s.z = static_cast<float>(z);
  return s;
}

void ElevationGrid::add(const ElevationSample* s, std::size_t n) {
  std::uint64_t last_key = FlatMap<std::uint32_t>::kEmpty;  // never a cell's key
  ElevationCell* at = nullptr;  // cells do not move: the pointer outlives later insertions
  for (std::size_t i = 0; i < n; ++i) {
    if (s[i].key != last_key) {
      last_key = s[i].key;
      at = &touch(last_key);
    }
    ElevationCell& c = *at;
    HeightBand b;
    b.index = s[i].band;
    b.w = s[i].w;
    b.wz = s[i].wz;
    b.count = 1;
    c.absorb(b);
    ++c.count;
    if (s[i].pass != c.last_pass) {
      ++c.passes;
      c.last_pass = s[i].pass;
    }
    c.zmin = std::min(c.zmin, s[i].z);
    c.zmax = std::max(c.zmax, s[i].z);
  }
}

void ElevationGrid::merge(const ElevationGrid& other) {
  if (std::fabs(other.res_ - res_) > 1e-12 || std::fabs(other.band_ - band_) > 1e-12)
    throw std::invalid_argument("elevation grids differ in resolution or band and cannot be merged");
  const bool same_keys = other.kx0_ == kx0_ && other.ky0_ == ky0_;
  for (std::size_t i = 0; i < other.size_; ++i) {
    const std::uint64_t k = other.chunks_[i / kChunk].keys[i % kChunk];
    merge_cell_at(same_keys ? k : checked_key(other.unkey_x(k), other.unkey_y(k)), other.cell(i));
  }
}

void ElevationGrid::merge_cell_at(std::uint64_t k, const ElevationCell& o) {
  if (o.empty()) return;
  ElevationCell& c = touch(k);
  for (const auto& b : o.bands) c.absorb(b);
  c.count += o.count;
  c.passes += o.passes;
  c.zmin = std::min(c.zmin, o.zmin);
  c.zmax = std::max(c.zmax, o.zmax);
}

void ElevationGrid::set_cell(std::int64_t ix, std::int64_t iy, const ElevationCell& c) { touch(checked_key(ix, iy)) = c; }

bool ElevationGrid::surface(const ElevationCell& c, double& elevation, double& variance) const {
  double w, wz;
  c.surface(min_support_, w, wz);
  if (w <= 0) return false;
  elevation = wz / w;
  variance = 1.0 / w;
  return true;
}

const ElevationCell* ElevationGrid::find(std::int64_t ix, std::int64_t iy) const {
  if (!holds(ix, iy)) return nullptr;
  const std::uint32_t* slot = index_.find(key(ix, iy));
  return slot ? &cell(*slot - 1) : nullptr;
}

bool ElevationGrid::bounds(std::int64_t& ix0, std::int64_t& iy0, std::int64_t& ix1, std::int64_t& iy1) const {
  bool any = false;
  for (std::size_t i = 0; i < size_; ++i) {
    if (cell(i).empty()) continue;
    const std::uint64_t k = chunks_[i / kChunk].keys[i % kChunk];
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
