// The pictures through the CLI (issue 34 item 8): error-budget's SVG shows the user's own curve.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;
using test::run_cli;

namespace {
// The y coordinates of an SVG polyline's points.
std::vector<double> ys_of(const std::string& polyline) {
  std::vector<double> ys;
  const std::string pts = polyline.substr(polyline.find("points='") + 8);
  for (std::size_t at = 0; (at = pts.find(',', at)) != std::string::npos; ++at) ys.push_back(std::stod(pts.substr(at + 1)));
  return ys;
}
}  // namespace

TEST(Pictures, ErrorBudgetDrawsTheUsersCurveVisiblyAndNamesItInTheLegend) {
  const std::string dir = test::fresh_dir();
  const auto res = run_cli({"error-budget", std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml", "--svg", dir + "/e.svg"});
  ASSERT_EQ(res.exit_code, 0) << res.err;
  EXPECT_NE(res.out.find("      30        5.3        0.0       10.9          8.7       15.0       21.1"), std::string::npos) << res.out;
  const std::string svg = test::read_text(dir + "/e.svg");
  // Seven curves (1-6 degrees, then the user's); the user's is the last drawn (on top), black and
  // thicker than the others.
  std::vector<std::string> lines;
  for (std::size_t at = 0; (at = svg.find("<polyline", at)) != std::string::npos; ++at)
    lines.push_back(svg.substr(at, svg.find("/>", at) - at));
  ASSERT_EQ(lines.size(), 7u);
  EXPECT_NE(lines.back().find("stroke='#000000' stroke-width='3.5'"), std::string::npos) << lines.back();
  for (std::size_t k = 0; k + 1 < lines.size(); ++k) EXPECT_NE(lines[k].find("stroke-width='2'"), std::string::npos) << lines[k];
  // Visible: its 10-21 mm lie well above the frame's bottom (y = 400) on the log axis, where on a
  // linear axis up to the 6-degree curve's 4.4 m they lay within 3 pixels of it; and it rises
  // with range.
  const std::vector<double> ys = ys_of(lines.back());
  ASSERT_EQ(ys.size(), 60u);  // 0.5 .. 30 m
  for (double y : ys) EXPECT_LT(y, 370.0);
  EXPECT_GT(ys.front() - ys.back(), 10.0);
  // Named in the legend, beside a line as thick as the curve's, and its value at 30 m at its end.
  EXPECT_NE(svg.find(">your sensor (1 sigma)</text>"), std::string::npos);
  EXPECT_NE(svg.find("stroke='#000000' stroke-width='3.5'/>"), std::string::npos);
  EXPECT_NE(svg.find(">21 mm at 30 m</text>"), std::string::npos);
  EXPECT_NE(svg.find("log scale"), std::string::npos);
}
