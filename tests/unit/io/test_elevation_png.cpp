// elevation.png as a surveyor reads it (issue 34 item 8): map coordinates on the axes, a colour
// bar that shows the percentile clipping, unseen and too-few-returns cells in colours of their
// own with a legend, a bar that says "flat" or "no data" where there is no range. The PNG is
// decoded (libpng) and looked at where the picture's layout says its parts are.
#include <gtest/gtest.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "io/elevation_png.hpp"
#include "pcdp/fusion/elevation.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/io/svg_plot.hpp"
#include "test_support.hpp"

using namespace pcdp;
using io::detail::ElevationPicture;

namespace {

struct Decoded {
  int w = 0, h = 0;
  std::vector<std::uint8_t> px;
  const std::uint8_t* at(int x, int y) const {
    return &px[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x))];
  }
  bool is(int x, int y, const io::detail::Rgb8& c) const {
    const std::uint8_t* p = at(x, y);
    return p[0] == c.r && p[1] == c.g && p[2] == c.b;
  }
  bool white(int x, int y) const { return is(x, y, {255, 255, 255}); }
  bool ink(int x, int y) const {  // the text's and the frames' black
    const std::uint8_t* p = at(x, y);
    return p[0] < 40 && p[1] < 40 && p[2] < 40;
  }
  /// Black pixels in the rectangle [x0, x1) x [y0, y1).
  int ink_in(int x0, int y0, int x1, int y1) const {
    int n = 0;
    for (int y = std::max(0, y0); y < std::min(h, y1); ++y)
      for (int x = std::max(0, x0); x < std::min(w, x1); ++x) n += ink(x, y) ? 1 : 0;
    return n;
  }
};

// Writes the picture through write_elevation_png and decodes the file; the layout comes from
// the renderer the writer calls.
Decoded write_and_decode(const ElevationGrid& g, ElevationPicture& pic, int* returned = nullptr) {
  const std::string path = test::fresh_dir() + "/e.png";
  const int down = io::write_elevation_png(g, path);
  if (returned) *returned = down;
  pic = io::detail::render_elevation(g);
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  Decoded d;
  if (!png_image_begin_read_from_file(&img, path.c_str())) {
    ADD_FAILURE() << img.message;
    return d;
  }
  img.format = PNG_FORMAT_RGB;
  d.w = static_cast<int>(img.width);
  d.h = static_cast<int>(img.height);
  d.px.resize(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, d.px.data(), 0, nullptr)) ADD_FAILURE() << img.message;
  EXPECT_EQ(d.w, pic.width);
  EXPECT_EQ(d.h, pic.height);
  return d;
}

void observe(ElevationGrid& g, double x, double y, double z, int returns = 2) {
  for (int k = 0; k < returns; ++k) g.add(x, y, z, 1e-4, 0);
}

// No label is empty or says nan/inf.
void expect_sane_labels(const ElevationPicture& pic) {
  for (const auto* labels : {&pic.eastings, &pic.northings, &pic.bar_labels})
    for (const auto& l : *labels) {
      EXPECT_FALSE(l.text.empty());
      EXPECT_EQ(l.text.find("nan"), std::string::npos) << l.text;
      EXPECT_EQ(l.text.find("inf"), std::string::npos) << l.text;
    }
}

// Pixels of colour c outside the map's frame (the legend's swatches).
int outside_map(const Decoded& d, const ElevationPicture& pic, const io::detail::Rgb8& c) {
  int n = 0;
  for (int y = 0; y < d.h; ++y)
    for (int x = 0; x < d.w; ++x)
      if ((x < pic.map_left - 1 || x > pic.map_left + pic.map_width || y < pic.map_top - 1 || y > pic.map_top + pic.map_height) &&
          d.is(x, y, c))
        ++n;
  return n;
}

}  // namespace

TEST(ElevationPng, UnseenAndTooFewReturnsCellsHaveTheirOwnColoursAndALegend) {
  // 20 x 10 cells of 0.5 m, two returns each (min_support 2), but cell (5, 5) has none (unseen)
  // and cell (12, 3) one (too few for a surface).
  ElevationGrid g(0.5, 0.05);
  for (int ix = 0; ix < 20; ++ix)
    for (int iy = 0; iy < 10; ++iy) {
      if (ix == 5 && iy == 5) continue;
      observe(g, 0.5 * ix + 0.25, 0.5 * iy + 0.25, 0.02 * ix, ix == 12 && iy == 3 ? 1 : 2);
    }
  ElevationPicture pic;
  const Decoded d = write_and_decode(g, pic);
  ASSERT_EQ(pic.scale, 8);
  const auto unseen = io::detail::kUnseenColour, few = io::detail::kFewReturnsColour;
  EXPECT_FALSE(unseen.r == few.r && unseen.g == few.g && unseen.b == few.b);
  EXPECT_TRUE(d.is(pic.cell_x(5), pic.cell_y(5), unseen));
  EXPECT_TRUE(d.is(pic.cell_x(12), pic.cell_y(3), few));
  // A cell with a surface is neither; the neighbours of the two cells are surfaces.
  for (const auto& [ix, iy] : {std::pair{4, 5}, std::pair{6, 5}, std::pair{12, 4}, std::pair{11, 3}}) {
    EXPECT_FALSE(d.is(pic.cell_x(ix), pic.cell_y(iy), unseen)) << ix << ' ' << iy;
    EXPECT_FALSE(d.is(pic.cell_x(ix), pic.cell_y(iy), few)) << ix << ' ' << iy;
  }
  // The legend names both, each with a swatch of its colour (16 x 16 pixels) outside the map.
  ASSERT_EQ(pic.legend.size(), 2u);
  EXPECT_EQ(pic.legend[0], "unseen (no return)");
  EXPECT_EQ(pic.legend[1], "too few returns (min_support 2)");
  EXPECT_GE(outside_map(d, pic, unseen), 16 * 16);
  EXPECT_GE(outside_map(d, pic, few), 16 * 16);
  expect_sane_labels(pic);
}

TEST(ElevationPng, AxesCarryEastingsAndNorthingsInMapMetres) {
  // A UTM-sized grid (the grid and the GeoTIFF are absolute map metres): 40 x 20 cells of 0.5 m
  // from (512000, 5400000).
  ElevationGrid g(0.5, 0.05);
  const double e0 = 512000.0, n0 = 5400000.0;
  for (int ix = 0; ix < 40; ++ix)
    for (int iy = 0; iy < 20; ++iy) observe(g, e0 + 0.5 * ix + 0.25, n0 + 0.5 * iy + 0.25, 0.01 * iy);
  ElevationPicture pic;
  const Decoded d = write_and_decode(g, pic);
  expect_sane_labels(pic);
  ASSERT_GE(pic.eastings.size(), 2u);
  ASSERT_GE(pic.northings.size(), 2u);
  const double ppm = pic.scale / 0.5;  // pixels per map metre
  double step = 0;
  for (std::size_t k = 0; k < pic.eastings.size(); ++k) {
    const double v = std::stod(pic.eastings[k].text);
    EXPECT_GE(v, e0);
    EXPECT_LE(v, e0 + 20.0);
    EXPECT_NEAR(pic.eastings[k].at, pic.map_left + (v - e0) * ppm, 1.0) << pic.eastings[k].text;
    if (k == 1) step = v - std::stod(pic.eastings[0].text);
    if (k > 1) {
      EXPECT_DOUBLE_EQ(v - std::stod(pic.eastings[k - 1].text), step);
    }
    // The label is drawn: black pixels under the map around its tick.
    const int below = pic.map_top + pic.map_height + 1;
    EXPECT_GT(d.ink_in(pic.eastings[k].at - 20, below + 6, pic.eastings[k].at + 20, below + 30), 20) << pic.eastings[k].text;
  }
  EXPECT_GT(step, 0);
  for (const auto& l : pic.northings) {
    const double v = std::stod(l.text);
    EXPECT_GE(v, n0);
    EXPECT_LE(v, n0 + 10.0);
    EXPECT_NEAR(l.at, pic.map_top + (n0 + 10.0 - v) * ppm, 1.0) << l.text;
    EXPECT_EQ(l.text.substr(0, 4), "5400");
    EXPECT_GT(d.ink_in(0, l.at - 8, pic.map_left - 8, l.at + 8), 20) << l.text;
  }
  // Between the labels the axis rows are background: the ink is the labels', not noise.
  const int below = pic.map_top + pic.map_height + 1;
  const int gap_x = (pic.eastings[0].at + pic.eastings[1].at) / 2;
  EXPECT_EQ(d.ink_in(gap_x - 2, below + 6, gap_x + 3, below + 30), 0);
}

TEST(ElevationPng, TheColourBarShowsWhereTheColoursClip) {
  // A floor rising 0 .. 0.1 m (200 cells) and four boxes 1.06 m high: the 98th percentile is on
  // the floor, so the boxes are drawn in the top colour, and the bar says so: a triangle above
  // it, the true maximum beside that, the bar's top labelled as the percentile.
  ElevationGrid g(0.5, 0.05);
  for (int ix = 0; ix < 20; ++ix)
    for (int iy = 0; iy < 10; ++iy) observe(g, 0.5 * ix + 0.25, 0.5 * iy + 0.25, 0.1 * ix / 19.0);
  for (int k = 0; k < 4; ++k) observe(g, 0.5 * (25 + k) + 0.25, 0.25, 1.06);
  ElevationPicture pic;
  const Decoded d = write_and_decode(g, pic);
  expect_sane_labels(pic);
  EXPECT_EQ(pic.bar, ElevationPicture::Bar::kRamp);
  EXPECT_TRUE(pic.clipped_high);
  EXPECT_FALSE(pic.clipped_low);  // the 2nd percentile is the floor's lowest row: the minimum
  EXPECT_NEAR(pic.hi, 0.1, 1e-6);
  EXPECT_NEAR(pic.zmax, 1.06, 1e-6);
  std::vector<std::string> texts;
  for (const auto& l : pic.bar_labels) texts.push_back(l.text);
  const auto has = [&](const std::string& t) { return std::find(texts.begin(), texts.end(), t) != texts.end(); };
  EXPECT_TRUE(has("max 1.06")) << ::testing::PrintToString(texts);
  EXPECT_TRUE(has("0.10 (98th pct)")) << ::testing::PrintToString(texts);
  EXPECT_TRUE(has("0.00 min")) << ::testing::PrintToString(texts);
  // The triangle above the bar is drawn; below the bar there is none.
  const int mid = pic.bar_left + pic.bar_width / 2;
  EXPECT_FALSE(d.white(mid, pic.bar_top - 5));
  EXPECT_TRUE(d.white(mid, pic.bar_top + pic.bar_height + 5));
  // The box cells and the floor's top are drawn alike (clipped): the bar is what tells them apart.
  EXPECT_GT(d.ink_in(pic.bar_left + pic.bar_width + 6, pic.bar_top - 20, d.w, pic.bar_top - 2), 20);
}

TEST(ElevationPng, AFlatMapHasABarThatSaysFlat) {
  ElevationGrid g(0.1, 0.05);
  for (int ix = 0; ix < 10; ++ix)
    for (int iy = 0; iy < 10; ++iy) observe(g, 0.1 * ix + 0.05, 0.1 * iy + 0.05, 1.25);
  ElevationPicture pic;
  const Decoded d = write_and_decode(g, pic);
  expect_sane_labels(pic);
  EXPECT_EQ(pic.bar, ElevationPicture::Bar::kFlat);
  ASSERT_EQ(pic.bar_labels.size(), 1u);
  EXPECT_EQ(pic.bar_labels[0].text, "flat: z = 1.250 m");
  // A bar of one colour, not white, 20 pixels wide, framed; the label drawn beside it.
  ASSERT_EQ(pic.bar_width, 20);
  ASSERT_GE(pic.bar_height, 100);
  const std::uint8_t* c = d.at(pic.bar_left + 10, pic.bar_top + 5);
  EXPECT_FALSE(d.white(pic.bar_left + 10, pic.bar_top + 5));
  for (int y = pic.bar_top; y < pic.bar_top + pic.bar_height; y += 7)
    for (int x = pic.bar_left; x < pic.bar_left + pic.bar_width; x += 3)
      EXPECT_EQ(std::memcmp(d.at(x, y), c, 3), 0) << x << ' ' << y;
  EXPECT_TRUE(d.ink(pic.bar_left - 1, pic.bar_top + pic.bar_height / 2));
  EXPECT_GT(d.ink_in(pic.bar_left + pic.bar_width + 6, pic.bar_labels[0].at - 8, d.w, pic.bar_labels[0].at + 8), 50);
  // The map's cells are surfaces, drawn in the bar's colour (shaded alike: no slope).
  EXPECT_FALSE(d.is(pic.cell_x(5), pic.cell_y(5), io::detail::kUnseenColour));
  EXPECT_FALSE(d.is(pic.cell_x(5), pic.cell_y(5), io::detail::kFewReturnsColour));
}

TEST(ElevationPng, EmptyMapsSayNoData) {
  // No cell at all, and cells with returns but no surface: a framed empty bar and "no data",
  // no NaN anywhere.
  ElevationGrid empty(0.1, 0.05), sparse(0.1, 0.05);
  for (int k = 0; k < 30; ++k) observe(sparse, 0.3 * k + 0.05, 0.05, 0.1 * k, 1);
  for (const ElevationGrid* g : {&empty, &sparse}) {
    ElevationPicture pic;
    int down = 0;
    const Decoded d = write_and_decode(*g, pic, &down);
    EXPECT_EQ(down, 1);
    expect_sane_labels(pic);
    EXPECT_EQ(pic.bar, ElevationPicture::Bar::kNoData);
    ASSERT_EQ(pic.bar_labels.size(), 1u);
    EXPECT_EQ(pic.bar_labels[0].text, "no data");
    EXPECT_GE(pic.bar_width, 20);
    EXPECT_TRUE(d.ink(pic.bar_left - 1, pic.bar_top + pic.bar_height / 2));
    EXPECT_TRUE(d.ink(pic.bar_left + pic.bar_width, pic.bar_top + pic.bar_height / 2));
    EXPECT_TRUE(d.white(pic.bar_left + pic.bar_width / 2, pic.bar_top + pic.bar_height / 2));
    EXPECT_GT(d.ink_in(pic.bar_left + pic.bar_width + 6, pic.bar_labels[0].at - 8, d.w, pic.bar_labels[0].at + 8), 30);
    EXPECT_FALSE(pic.eastings.empty());
    EXPECT_FALSE(pic.northings.empty());
  }
  ElevationPicture pic;
  const Decoded d = write_and_decode(sparse, pic);
  EXPECT_TRUE(d.is(pic.cell_x(3), pic.cell_y(0), io::detail::kFewReturnsColour));
  EXPECT_TRUE(d.is(pic.cell_x(4), pic.cell_y(0), io::detail::kUnseenColour));
}

TEST(ElevationPng, ADownsampledPictureKeepsItsCoordinates) {
  // 5,001 cells across (> 4,096): 3 x 3 cells a pixel, at most 2,048 pixels across; the labels
  // still in map metres at the right pixels.
  ElevationGrid g(0.1, 0.05);
  observe(g, 0.05, 0.05, 1.0);
  observe(g, 500.05, 0.05, 2.0);
  ElevationPicture pic;
  int down = 0;
  write_and_decode(g, pic, &down);
  EXPECT_EQ(down, 3);
  EXPECT_EQ(pic.cells_per_pixel, 3);
  EXPECT_LE(pic.map_width, 2048);
  ASSERT_GE(pic.eastings.size(), 2u);
  for (const auto& l : pic.eastings) {
    const double v = std::stod(l.text);
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 500.2);
    EXPECT_NEAR(l.at, pic.map_left + v / 0.1 / 3 * pic.scale, 1.0) << l.text;
  }
  EXPECT_EQ(pic.bar, ElevationPicture::Bar::kRamp);
  expect_sane_labels(pic);
}

TEST(SvgPlot, ALogAxisKeepsASmallCurveOffTheFrameAndTheLastSeriesOnTop) {
  io::PlotSpec spec;
  spec.log_y = true;
  io::PlotSeries big{"big", {}, "#1f77b4", false}, user{"your sensor (1 sigma)", {}, "#000000", false};
  user.width = 3.5;
  user.end_note = "21 mm at 30 m";
  for (double r = 1; r <= 30; ++r) {
    big.points.emplace_back(r, 0.1 * r);
    user.points.emplace_back(r, 0.01 + 0.0004 * r);
  }
  spec.series = {big, user};
  const std::string svg = io::svg_line_plot(spec);  // 760 x 460: the frame's bottom at y = 400
  const std::size_t last = svg.rfind("<polyline");
  ASSERT_NE(last, std::string::npos);
  const std::string line = svg.substr(last, svg.find("/>", last) - last);
  EXPECT_NE(line.find("stroke='#000000' stroke-width='3.5'"), std::string::npos) << line;
  // Every point of the small curve at least 30 pixels above the frame's bottom (on a linear axis
  // from 0 to 3 m it lay within 4 pixels of it).
  const std::string pts = line.substr(line.find("points='") + 8);
  std::size_t n = 0;
  for (std::size_t at = 0; (at = pts.find(',', at)) != std::string::npos; ++at, ++n) EXPECT_LT(std::stod(pts.substr(at + 1)), 370.0);
  EXPECT_EQ(n, 30u);
  // The legend: its label beside a line as wide as the curve's; the note at its end.
  EXPECT_NE(svg.find(">your sensor (1 sigma)</text>"), std::string::npos);
  EXPECT_NE(svg.find("stroke='#000000' stroke-width='3.5'/>"), std::string::npos);
  EXPECT_NE(svg.find(">21 mm at 30 m</text>"), std::string::npos);
  // Decades labelled.
  EXPECT_NE(svg.find(">0.01</text>"), std::string::npos);
  EXPECT_NE(svg.find(">1</text>"), std::string::npos);
}
