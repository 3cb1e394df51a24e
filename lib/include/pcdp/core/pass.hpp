// One nodding pass: the raw returns of one PCD file (docs/data_contract.md "Input 1"), ordered by line and
// beam, plus what the stages derive (labels, calibrated ranges, map points, sensor origins).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/core/field.hpp"
#include "pcdp/core/labels.hpp"

namespace pcdp {

/// A field of the input that the contract does not name; carried through to returns.pcd.
struct ExtraField {
  Field field;
  std::vector<std::uint8_t> data;  ///< points * field.bytes(), in pass order
};

/// Pass::flags bits.
inline constexpr std::uint8_t kFlagRepaired = 1;  ///< range replaced by its prediction (reject_occlusion repair)
// The evidence behind a `mixed_pixel` label (reject_mixed_pixels; docs/mixed_pixels.md): one or
// more of these, set only on the returns it labels.
inline constexpr std::uint8_t kFlagMixedAlong = 2;   ///< the tests along its scan line found it
inline constexpr std::uint8_t kFlagMixedAcross = 4;  ///< the tests across lines (same beam) found it
inline constexpr std::uint8_t kFlagBesideVoid = 8;   ///< ... in a direction where one side is a void (test 5)
inline constexpr std::uint8_t kFlagSpike = 16;       ///< a spike whose range or amplitude gives it away (test 6)
inline constexpr std::uint8_t kFlagMixedRun = 32;    ///< found in a later round, inside a run of mixtures

struct Pass {
  std::size_t index = 0;  ///< position of the pass file in the run's ordered list
  std::string source;     ///< file path
  bool organized = false; ///< the file was organized (WIDTH = returns per line)

  // Raw columns (docs/data_contract.md), sorted by (line, beam).
  std::vector<std::uint32_t> line, beam;
  std::vector<float> range, bearing, amplitude, nod;
  std::vector<double> stamp;
  std::vector<ExtraField> extra;

  /// Returns of line k are [line_begin[k], line_begin[k+1]).
  std::vector<std::size_t> line_begin;

  // Derived by stages.
  std::vector<Label> label;        ///< kKept until a stage says otherwise
  std::vector<std::uint8_t> flags; ///< bit flags, see kFlag* (written to returns.pcd)
  std::vector<float> range_cal;    ///< calibrated range, m (NaN where there is no return)
  std::vector<float> nod_at_return;///< nod angle at the return's own stamp (skew-corrected)
  std::vector<double> x, y, z;     ///< map frame, NaN where there is no point
  std::vector<double> ox, oy, oz;  ///< sensor (nod-axis) origin in the map frame at the return
  /// Covariance of (x, y, z), 6 per return: xx, xy, xz, yy, yz, zz (m^2); empty when not computed.
  std::vector<float> cov;

  std::size_t size() const { return range.size(); }
  std::size_t line_count() const { return line_begin.empty() ? 0 : line_begin.size() - 1; }
  std::size_t kept() const;
  bool is_kept(std::size_t i) const { return label[i] == Label::kKept; }
};

/// Lines [from, to) of a pass as a pass of their own (as a streamed window or a finished line
/// holds them): every per-return column the pass holds, raw and derived, cut to those lines; the
/// pass's index, source and organization carried over. Requires from <= to <= line_count().
Pass lines_of(const Pass& p, std::size_t from, std::size_t to);

// Reading a pass from a PCD file (read_pass, check_pass_header): pcdp/io/pass_file.hpp.

}  // namespace pcdp
