// mixed_detail::sweep_starts: where reject_mixed_pixels splits an organized pass into the sweeps
// across which it compares a beam (the nod's reversals), which pcdp_mixed_sweep also uses to count
// the mixed pixels on the lines next to a nod turn (docs/mixed_pixels.md, Limits).
#include <gtest/gtest.h>

#include <vector>

#include "pcdp/core/pass.hpp"
#include "stages/reject_mixed_pixels_detail.hpp"

using namespace pcdp;

namespace {
/// A pass of two returns a line, each line's nod angle as given (the first return's is the one read).
Pass pass_with_nods(const std::vector<float>& nods) {
  Pass p;
  for (const float n : nods) {
    p.line_begin.push_back(p.nod.size());
    p.nod.push_back(n);
    p.nod.push_back(n + 0.5f);  // the second return's nod is not read
  }
  p.line_begin.push_back(p.nod.size());
  return p;
}
}  // namespace

TEST(MixedPixelSweeps, ASweepEndsOnTheExtremeLineAndTheNextBeginsAfterIt) {
  // Up 0, 1, 2; down 1, 0; up 1: the extreme lines 2 and 4 end their sweeps.
  const std::vector<std::size_t> want{0, 3, 5, 6};
  EXPECT_EQ(mixed_detail::sweep_starts(pass_with_nods({0, 1, 2, 1, 0, 1})), want);
}

TEST(MixedPixelSweeps, AMonotonicNodIsOneSweep) {
  const std::vector<std::size_t> want{0, 5};
  EXPECT_EQ(mixed_detail::sweep_starts(pass_with_nods({-0.4f, -0.3f, -0.1f, 0.0f, 0.2f})), want);
}

TEST(MixedPixelSweeps, AReversalInsideAPlateauOfEqualReadingsIsNotSplit) {
  // 0, 1, 1, 0: no three consecutive lines change direction (documented: the plateau hides it).
  const std::vector<std::size_t> want{0, 4};
  EXPECT_EQ(mixed_detail::sweep_starts(pass_with_nods({0, 1, 1, 0})), want);
}

TEST(MixedPixelSweeps, FewerThanThreeLinesAreOneSweep) {
  EXPECT_EQ(mixed_detail::sweep_starts(pass_with_nods({0, 1})), (std::vector<std::size_t>{0, 2}));
  EXPECT_EQ(mixed_detail::sweep_starts(pass_with_nods({})), (std::vector<std::size_t>{0, 0}));
}

TEST(MixedPixelSweeps, AStreamedWindowSplitsWhereTheWholePassDoes) {
  // Lines 2 .. 7 of a pass as a window of their own: its starts are the pass's, shifted.
  const std::vector<float> nods{0, 1, 2, 3, 2, 1, 0, 1, 2};
  const std::vector<std::size_t> whole = mixed_detail::sweep_starts(pass_with_nods(nods));
  const std::vector<std::size_t> window = mixed_detail::sweep_starts(pass_with_nods({nods.begin() + 2, nods.begin() + 8}));
  EXPECT_EQ(whole, (std::vector<std::size_t>{0, 4, 7, 9}));
  // In the window (lines 2 .. 7): reversals at 4 and 7 -> 2 and 5; its own ends 0 and 6.
  EXPECT_EQ(window, (std::vector<std::size_t>{0, 2, 5, 6}));
}
