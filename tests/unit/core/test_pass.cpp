// Cutting lines out of a pass (lines_of), as the line stream and window tests do.
#include <gtest/gtest.h>

#include <stdexcept>

#include "pcdp/core/pass.hpp"

using namespace pcdp;

namespace {
/// Lines of 2, 3 and 4 returns; range = return index, registered columns on, a 2-byte extra field.
Pass three_lines() {
  Pass p;
  p.index = 7;
  p.source = "three.pcd";
  p.organized = false;
  const std::size_t widths[] = {2, 3, 4};
  std::size_t i = 0;
  p.extra.push_back(ExtraField{Field{"ring", 'U', 2, 1}, {}});
  for (std::uint32_t k = 0; k < 3; ++k) {
    p.line_begin.push_back(i);
    for (std::uint32_t b = 0; b < widths[k]; ++b, ++i) {
      p.line.push_back(k);
      p.beam.push_back(b);
      p.range.push_back(static_cast<float>(i));
      p.bearing.push_back(0.1f * static_cast<float>(b));
      p.amplitude.push_back(100.0f + static_cast<float>(i));
      p.nod.push_back(0.01f * static_cast<float>(k));
      p.stamp.push_back(1000.0 + static_cast<double>(i));
      p.label.push_back(i % 2 ? Label::kMixedPixel : Label::kKept);
      p.flags.push_back(static_cast<std::uint8_t>(i % 3));
      p.x.push_back(static_cast<double>(i));
      p.y.push_back(-static_cast<double>(i));
      p.z.push_back(0.5 * static_cast<double>(i));
      for (int c = 0; c < 6; ++c) p.cov.push_back(static_cast<float>(10 * i + static_cast<std::size_t>(c)));
      p.extra[0].data.push_back(static_cast<std::uint8_t>(i));
      p.extra[0].data.push_back(static_cast<std::uint8_t>(200 + i));
    }
  }
  p.line_begin.push_back(i);
  return p;  // range_cal, nod_at_return and the origins not derived: empty
}
}  // namespace

TEST(Pass, LinesOfCutsEveryColumnItHoldsToThoseLines) {
  const Pass p = three_lines();
  const Pass w = lines_of(p, 1, 3);  // lines 1 and 2: returns 2..8
  EXPECT_EQ(w.index, 7u);
  EXPECT_EQ(w.source, "three.pcd");
  EXPECT_FALSE(w.organized);
  ASSERT_EQ(w.size(), 7u);
  EXPECT_EQ(w.line_begin, (std::vector<std::size_t>{0, 3, 7}));
  for (std::size_t j = 0; j < w.size(); ++j) {
    const std::size_t i = j + 2;
    EXPECT_EQ(w.range[j], p.range[i]);
    EXPECT_EQ(w.line[j], p.line[i]);
    EXPECT_EQ(w.beam[j], p.beam[i]);
    EXPECT_EQ(w.stamp[j], p.stamp[i]);
    EXPECT_EQ(w.label[j], p.label[i]);
    EXPECT_EQ(w.flags[j], p.flags[i]);
    EXPECT_EQ(w.x[j], p.x[i]);
    EXPECT_EQ(w.z[j], p.z[i]);
    for (int c = 0; c < 6; ++c) EXPECT_EQ(w.cov[6 * j + c], p.cov[6 * i + c]);
    EXPECT_EQ(w.extra[0].data[2 * j + 1], static_cast<std::uint8_t>(200 + i));
  }
  // Columns not derived stay empty; the cut is a pass of its own.
  EXPECT_TRUE(w.range_cal.empty());
  EXPECT_TRUE(w.ox.empty());
  EXPECT_EQ(w.line_count(), 2u);
  // One line, and none.
  EXPECT_EQ(lines_of(p, 0, 1).range, (std::vector<float>{0.0f, 1.0f}));
  const Pass none = lines_of(p, 2, 2);
  EXPECT_EQ(none.size(), 0u);
  EXPECT_EQ(none.line_count(), 0u);
  EXPECT_THROW(lines_of(p, 2, 4), std::out_of_range);
  EXPECT_THROW(lines_of(p, 2, 1), std::out_of_range);
  // A pass with no lines at all, and an extra field of the wrong size.
  EXPECT_EQ(lines_of(Pass{}, 0, 0).line_count(), 0u);
  EXPECT_THROW(lines_of(Pass{}, 0, 1), std::out_of_range);
  Pass bad = p;
  bad.extra[0].data.pop_back();
  EXPECT_THROW(lines_of(bad, 0, 1), std::logic_error);
}
