#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "pcdp/models/line_recovery.hpp"

using namespace pcdp;

namespace {
Eigen::Vector3d point(double r, double b, double n) {
  return {r * std::cos(n) * std::cos(b), r * std::sin(b), r * std::sin(n) * std::cos(b)};
}
}  // namespace

TEST(LineRecovery, ANoddingScanComesBackLineByLineOnOneBeamGrid) {
  // 7 lines at nods -0.3 .. 0.3 rad, 41 beams from -1 to 1 rad, ranges varying along the line.
  std::vector<Eigen::Vector3d> pts;
  for (int l = 0; l < 7; ++l)
    for (int b = 0; b <= 40; ++b) pts.push_back(point(5.0 + 0.05 * b, -1.0 + 0.05 * b, -0.3 + 0.1 * l));
  std::vector<std::size_t> starts;
  const auto lines = split_lines(pts, &starts);
  ASSERT_EQ(lines.size(), 7u);
  EXPECT_EQ(starts, (std::vector<std::size_t>{0, 41, 82, 123, 164, 205, 246}));

  LineRecovery rec;
  const Pass p = sensor_lines_to_pass(lines, {}, 0, "synthetic", 0.02, false, rec);
  EXPECT_EQ(rec.lines, 7u);
  EXPECT_EQ(rec.loose_points, 0u);
  EXPECT_LT(rec.max_residual, 1e-9);
  EXPECT_TRUE(rec.organized);
  ASSERT_EQ(p.size(), pts.size());
  ASSERT_EQ(p.line_count(), 7u);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const std::size_t l = i / 41, b = i % 41;
    EXPECT_EQ(p.beam[i], b);
    EXPECT_NEAR(p.range[i], 5.0 + 0.05 * static_cast<double>(b), 1e-5);
    EXPECT_NEAR(p.bearing[i], -1.0 + 0.05 * static_cast<double>(b), 1e-6);
    EXPECT_NEAR(p.nod[i], -0.3 + 0.1 * static_cast<double>(l), 1e-6);
  }
  // Stamps are synthetic: kScanLinePeriod a line, increasing.
  EXPECT_NEAR(p.stamp[p.line_begin[1]] - p.stamp[p.line_begin[0]], kScanLinePeriod, 1e-9);
}

TEST(LineRecovery, APointOffItsLineBecomesALineOfItsOwn) {
  std::vector<std::vector<Eigen::Vector3d>> lines(1);
  for (int b = 0; b <= 20; ++b) lines[0].push_back(point(4.0, -0.5 + 0.05 * b, 0.2));
  lines[0][10] += Eigen::Vector3d(0.0, 0.0, 0.3);  // 0.3 m above the line's plane
  LineRecovery rec;
  const Pass p = sensor_lines_to_pass(lines, {}, 0, "synthetic", 0.02, false, rec);
  EXPECT_EQ(rec.split_lines, 1u);
  EXPECT_EQ(rec.loose_points, 1u);
  EXPECT_EQ(p.line_count(), 2u);
  EXPECT_EQ(p.size(), 21u);
  EXPECT_FALSE(rec.organized);
}
