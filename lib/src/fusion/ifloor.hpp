// floor() to an integer voxel index, shared by the consistency evidence's sources.
#pragma once

#include <cstdint>

namespace pcdp::detail {

/// floor() for finite values within +-2^62, inline (std::floor is a call into libm here).
inline std::int64_t ifloor(double v) {
  const auto i = static_cast<std::int64_t>(v);
  return i - (static_cast<double>(i) > v ? 1 : 0);
}

}  // namespace pcdp::detail
