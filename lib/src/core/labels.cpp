#include "pcdp/core/labels.hpp"

#include <stdexcept>

namespace pcdp {

namespace {
constexpr const char* kNames[kLabelCount] = {"kept",         "no_return", "occlusion",
                                             "mixed_pixel",  "out_of_range", "outlier",
                                             "low_amplitude", "no_pose",   "inconsistent"};
constexpr const char* kMeanings[kLabelCount] = {
    "a valid return",
    "range 0 or NaN",
    "a false range of a non-coaxial receiver past a range edge (Liu et al. 2005)",
    "the footprint straddled an edge; the range lies between the surfaces (Ye & Borenstein 4.5)",
    "calibrated range outside sensor.range_min..range_max",
    "reserved for statistical outlier rejection",
    "amplitude below the sensor's minimum detectable amplitude",
    "no pose at the return's stamp",
    "contradicted by other passes (it lies in space they saw through)"};
}

const char* label_name(Label l) {
  const auto i = static_cast<std::size_t>(l);
  return i < kLabelCount ? kNames[i] : "unknown";
}

const char* label_meaning(Label l) {
  const auto i = static_cast<std::size_t>(l);
  return i < kLabelCount ? kMeanings[i] : "unknown";
}

Label label_from_name(const std::string& name) {
  for (std::size_t i = 0; i < kLabelCount; ++i)
    if (name == kNames[i]) return static_cast<Label>(i);
  throw std::invalid_argument("unknown label '" + name + "'");
}

}  // namespace pcdp
