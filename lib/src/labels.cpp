#include "pcdp/labels.hpp"

#include <stdexcept>

namespace pcdp {

namespace {
constexpr const char* kNames[kLabelCount] = {"kept",         "no_return", "occlusion",
                                             "mixed_pixel",  "out_of_range", "outlier",
                                             "low_amplitude", "no_pose",   "inconsistent"};
}

const char* label_name(Label l) {
  const auto i = static_cast<std::size_t>(l);
  return i < kLabelCount ? kNames[i] : "unknown";
}

Label label_from_name(const std::string& name) {
  for (std::size_t i = 0; i < kLabelCount; ++i)
    if (name == kNames[i]) return static_cast<Label>(i);
  throw std::invalid_argument("unknown label '" + name + "'");
}

}  // namespace pcdp
