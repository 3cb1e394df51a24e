// Internal to stage `reject_mixed_pixels` (not installed): the pieces its organized-pass and
// unorganized-cloud entry points and its pipeline stage share (reject_mixed_pixels.cpp,
// reject_mixed_pixels_cloud.cpp, reject_mixed_pixels_stage.cpp).
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "pcdp/core/pass.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"

namespace pcdp::mixed_detail {

/// The most extra rounds for runs of mixtures (a footprint up to three returns wide).
constexpr int kMaxExtraRounds = 2;
/// Returns searched each way in the rounds after the first.
constexpr int kRoundWindow = 3;
/// The most returns a side is read past inside the footprint before its window of
/// MixedPixelParams::window returns starts (the first round's reading past the footprint): a
/// footprint 16 lines deep, 15 mrad where the nod moves less than 1 mrad a line near its turns.
constexpr int kFootprintReach = 16;
/// Lines searched each way for the object a spike may be a mixture with: the pure returns of a
/// post's top are within two or three lines of its mixtures near a nod reversal, where the nod
/// barely moves from line to line.
constexpr long kObjectReach = 4;

/// The sweeps of a pass whose lines each hold a return (an organized pass): the first line of
/// each, then line_count(). Lines follow each other in nod only within one sweep: where the nod
/// reverses, the next line folds back over the last ones, so each sweep is a sequence of its own
/// for the tests across lines. The reversal is read from three consecutive lines' first nod
/// angles only (the extreme line ends its sweep), so a streamed window of `reach()` lines on each
/// side splits exactly where the whole pass does; a reversal hidden in a plateau of equal encoder
/// readings is not split.
inline std::vector<std::size_t> sweep_starts(const Pass& pass) {
  std::vector<std::size_t> starts{0};
  const auto nod_of = [&](std::size_t k) { return static_cast<double>(pass.nod[pass.line_begin[k]]); };
  for (std::size_t k = 2; k < pass.line_count(); ++k)
    if ((nod_of(k) - nod_of(k - 1)) * (nod_of(k - 1) - nod_of(k - 2)) < 0) starts.push_back(k);
  starts.push_back(pass.line_count());
  return starts;
}

/// The smallest range step that makes an edge at range r (jump_min, or jump_ratio of r if larger).
inline double jump_at(const MixedPixelParams& p, double r) { return std::max(p.jump_min, p.jump_ratio * r); }
/// How far from a surface a return at range r may lie and still be on it.
inline double tolerance_at(const MixedPixelParams& p, double r, double range_sigma) {
  return p.range_tolerance + p.range_tolerance_ratio * r + 3.0 * range_sigma;
}

/// Spikes along a sequence (one line), with the surface behind each (its flanks' mean range and
/// amplitude, `behind_r`, `behind_a`); reject_mixed_pixels_spikes.cpp says how.
void mark_spikes(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                 std::vector<char>& spike, std::vector<float>& behind_r, std::vector<float>& behind_a);
/// The spikes that lie off every surface in a sequence of the other direction (across lines), or
/// whose amplitude says they are mixtures with the surface behind.
void mark_spikes_off_surface(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                             double range_sigma, const std::vector<char>& spike, const std::vector<float>& behind_r,
                             const std::vector<float>& behind_a, std::vector<char>& off);

/// How the return at `pos` lies between its immediate neighbours in one direction. With only one
/// immediate neighbour (the other position is a void, or the end of the line or of the sweep),
/// whether it keeps the range of that neighbour (within an edge jump) or not: one neighbour cannot
/// say smooth or rough, but it can say the return is not flat there.
enum Smoothness : char { kUnknown = 0, kSmooth = 1, kRough = 2, kFlat = 3, kOneFlat = 4, kOneChanging = 5 };

/// How each return of a sequence lies between its immediate neighbours (smooth, rough, flat, or
/// with one neighbour only), for the other direction's verdict.
void mark_smooth(const ReturnsView& v, const std::vector<std::size_t>& seq, const MixedPixelParams& p,
                 double range_sigma, std::vector<char>& smooth);

/// The verdict from one direction's edge and the other direction's smoothness: a weak edge counts
/// where the return is rough across (grazing ground is smooth across; a veil is not); a corner
/// counts unless the return is flat across (the side face of a box, seen edge-on, is one return
/// wide along the line but keeps its range from line to line; a veil changes with the background).
/// Where the other direction has one immediate neighbour only (the first or last line of a nod
/// sweep, or beside a void), a corner counts if the return does not keep that neighbour's range:
/// it is then not flat (on benchmark seeds 1-15, 6 more mixed pixels in setting B and 8 in A, for
/// 4 and 5 more valid returns rejected). A weak edge there is not counted: one neighbour cannot
/// tell a veil from grazing ground, which changes range fast between lines but smoothly (counting
/// those whose return is also off the chord of its neighbours along the line found 8 more mixed
/// pixels in both settings for 11 valid returns, and 5 more of 18,110 on pure grazing ground).
inline bool is_mixed(char edge, char other_direction) {
  switch (edge) {
    case kStrongEdge:
    case kBesideVoid: return true;
    case kCornerEdge: return other_direction == kSmooth || other_direction == kRough || other_direction == kOneChanging;
    case kWeakEdge: return other_direction == kRough;
    default: return false;
  }
}

}  // namespace pcdp::mixed_detail
