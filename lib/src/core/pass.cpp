#include "pcdp/core/pass.hpp"

#include <algorithm>

namespace pcdp {

std::size_t Pass::kept() const {
  return static_cast<std::size_t>(std::count(label.begin(), label.end(), Label::kKept));
}

}  // namespace pcdp
