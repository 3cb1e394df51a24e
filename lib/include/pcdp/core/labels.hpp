// Return labels of the data contract (docs/data_contract.md). Codes are never renumbered;
// new reasons get new codes.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace pcdp {

enum class Label : std::uint8_t {
  kKept = 0,
  kNoReturn = 1,
  kOcclusion = 2,
  kMixedPixel = 3,
  kOutOfRange = 4,
  kOutlier = 5,
  kLowAmplitude = 6,
  kNoPose = 7,
  kInconsistent = 8,
};

inline constexpr std::size_t kLabelCount = 9;

/// snake_case name of a label ("kept", "no_return", ...), as used in report.json and the docs.
const char* label_name(Label l);
/// One sentence on what the label means (docs/data_contract.md "Labels"; report.json's label_codes).
const char* label_meaning(Label l);
/// Label from its name; throws std::invalid_argument for an unknown name.
Label label_from_name(const std::string& name);

using LabelHistogram = std::array<std::uint64_t, kLabelCount>;

}  // namespace pcdp
