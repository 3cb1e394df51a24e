#include "elevation_png.hpp"

#include <png.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"
#include "rename_into_place.hpp"

namespace pcdp::io {

namespace {
using detail::rename_into_place;

struct Rgb {
  double r, g, b;
};
constexpr Rgb kBlack{0, 0, 0}, kWhite{255, 255, 255};
Rgb rgb(const detail::Rgb8& c) { return {double(c.r), double(c.g), double(c.b)}; }

Rgb ramp(double t) {  // a perceptual ramp (viridis-like control points)
  static const Rgb k[] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  t = std::clamp(t, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(t));
  const double f = t - i;
  return {k[i].r + f * (k[i + 1].r - k[i].r), k[i].g + f * (k[i + 1].g - k[i].g), k[i].b + f * (k[i + 1].b - k[i].b)};
}

// A 5 x 8 bitmap font (5 x 7 glyphs, the 8th row for descenders): each row's five bits, the
// leftmost the highest. Characters without a glyph are drawn blank.
const std::array<std::uint8_t, 8>& glyph(char c) {
  struct G {
    char c;
    std::array<std::uint8_t, 8> rows;
  };
  static const G font[] = {
      {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E, 0}},
      {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E, 0}},
      {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F, 0}},
      {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E, 0}},
      {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02, 0}},
      {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E, 0}},
      {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E, 0}},
      {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08, 0}},
      {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E, 0}},
      {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C, 0}},
      {'A', {0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0}},
      {'B', {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E, 0}},
      {'C', {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E, 0}},
      {'D', {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C, 0}},
      {'E', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F, 0}},
      {'F', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10, 0}},
      {'G', {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F, 0}},
      {'H', {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11, 0}},
      {'I', {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E, 0}},
      {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C, 0}},
      {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11, 0}},
      {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F, 0}},
      {'M', {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11, 0}},
      {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0}},
      {'O', {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E, 0}},
      {'P', {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10, 0}},
      {'Q', {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D, 0}},
      {'R', {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11, 0}},
      {'S', {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E, 0}},
      {'T', {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0}},
      {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E, 0}},
      {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04, 0}},
      {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A, 0}},
      {'X', {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11, 0}},
      {'Y', {0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0}},
      {'Z', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F, 0}},
      {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F, 0}},
      {'b', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E, 0}},
      {'c', {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E, 0}},
      {'d', {0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F, 0}},
      {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E, 0}},
      {'f', {0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08, 0}},
      {'g', {0x00, 0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
      {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11, 0}},
      {'i', {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E, 0}},
      {'j', {0x02, 0x00, 0x06, 0x02, 0x02, 0x02, 0x12, 0x0C}},
      {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12, 0}},
      {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E, 0}},
      {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11, 0}},
      {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11, 0}},
      {'o', {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E, 0}},
      {'p', {0x00, 0x00, 0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10}},
      {'q', {0x00, 0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x01}},
      {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10, 0}},
      {'s', {0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E, 0}},
      {'t', {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06, 0}},
      {'u', {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D, 0}},
      {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04, 0}},
      {'w', {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A, 0}},
      {'x', {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0}},
      {'y', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
      {'z', {0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F, 0}},
      {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C, 0}},
      {',', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}},
      {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00, 0}},
      {'+', {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00, 0}},
      {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00, 0}},
      {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00, 0}},
      {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02, 0}},
      {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08, 0}},
      {'<', {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02, 0}},
      {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08, 0}},
      {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00, 0}},
      {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03, 0}},
      {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F, 0}},
  };
  static const std::array<std::uint8_t, 8> blank{};
  for (const G& g : font)
    if (g.c == c) return g.rows;
  return blank;
}

constexpr int kText = 2;               // text is drawn at 2 x its font's size
constexpr int kAdvance = 6 * kText;    // a character's width with its spacing
constexpr int kCap = 7 * kText;        // the height of a capital
constexpr int kLine = 8 * kText;       // a line of text, descenders included
int text_width(const std::string& s) { return static_cast<int>(s.size()) * kAdvance - kText; }

struct Canvas {  // 8-bit RGB, interleaved row by row (libpng's PNG_FORMAT_RGB)
  int w, h;
  std::vector<std::uint8_t>& rgb;
  Canvas(int W, int H, std::vector<std::uint8_t>& out) : w(W), h(H), rgb(out) {
    rgb.assign(static_cast<std::size_t>(W) * static_cast<std::size_t>(H) * 3, 255);
  }
  void put(int x, int y, const Rgb& c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    std::uint8_t* p = &rgb[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x))];
    p[0] = static_cast<std::uint8_t>(std::clamp(c.r, 0.0, 255.0));
    p[1] = static_cast<std::uint8_t>(std::clamp(c.g, 0.0, 255.0));
    p[2] = static_cast<std::uint8_t>(std::clamp(c.b, 0.0, 255.0));
  }
  void fill(int x, int y, int fw, int fh, const Rgb& c) {
    for (int j = 0; j < fh; ++j)
      for (int i = 0; i < fw; ++i) put(x + i, y + j, c);
  }
  void frame(int x, int y, int fw, int fh) {  // a 1-pixel black line just outside the rectangle
    fill(x - 1, y - 1, fw + 2, 1, kBlack);
    fill(x - 1, y + fh, fw + 2, 1, kBlack);
    fill(x - 1, y, 1, fh, kBlack);
    fill(x + fw, y, 1, fh, kBlack);
  }
  /// Text whose top-left corner is (x, y).
  void text(int x, int y, const std::string& s) {
    for (char ch : s) {
      const auto& g = glyph(ch);
      for (int row = 0; row < 8; ++row)
        for (int col = 0; col < 5; ++col)
          if (g[static_cast<std::size_t>(row)] & (0x10 >> col)) fill(x + col * kText, y + row * kText, kText, kText, kBlack);
      x += kAdvance;
    }
  }
  /// Text whose capitals are centred vertically on y.
  void text_mid(int x, int y, const std::string& s) { text(x, y - kCap / 2, s); }
};

std::string fixed(double v, int decimals) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  std::string s = b;
  if (s.find_first_not_of("-0.") == std::string::npos && s[0] == '-') s.erase(0, 1);  // no "-0.00"
  return s;
}
std::string shortest(double v) {  // "5", "0.5", "0.25"
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

/// The smallest of 1, 2, 5 x 10^k at least x (> 0).
double nice_at_least(double x) {
  const double mag = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= x * (1 - 1e-9)) return m * mag;
  return 10 * mag;
}
/// The largest of 1, 2, 5 x 10^k at most x (> 0).
double nice_at_most(double x) {
  const double mag = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * mag <= x * (1 + 1e-9)) return m * mag;
  return mag;
}
/// Decimals that show multiples of `step` (a 1, 2, 5 x 10^k) exactly.
int decimals_of(double step) { return step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9)); }
}  // namespace

namespace detail {

ElevationPicture render_elevation(const ElevationGrid& grid) {
  ElevationPicture pic;
  std::int64_t ix0 = 0, iy0 = 0, ix1 = 0, iy1 = 0;
  if (!grid.bounds(ix0, iy0, ix1, iy1)) ix0 = iy0 = ix1 = iy1 = 0;
  // A picture more than kPngMaxSide pixels across helps nobody, and its memory grows with the
  // area: past that, each pixel shows the mean surface of `down` x `down` cells, at most
  // kPngDownSide pixels across (noted on the picture).
  const std::int64_t side = std::max(ix1 - ix0, iy1 - iy0) + 1;
  const std::int64_t down = side <= kPngMaxSide ? 1 : (side + kPngDownSide - 1) / kPngDownSide;
  const int nx = static_cast<int>((ix1 - ix0) / down + 1), ny = static_cast<int>((iy1 - iy0) / down + 1);
  const std::size_t npx = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  std::vector<double> z(npx, std::numeric_limits<double>::quiet_NaN());
  std::vector<std::uint32_t> n(down > 1 ? npx : 0, 0);  // cells averaged into each pixel
  // What a pixel shows: 0 no cell with a return, 1 returns but no surface (too few), 2 a surface
  // (of any of its cells, when downsampled).
  std::vector<std::uint8_t> state(npx, 0);
  std::vector<double> vals;
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  grid.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    if (c.empty()) return;
    const std::size_t at = static_cast<std::size_t>((iy1 - iy) / down) * static_cast<std::size_t>(nx) + static_cast<std::size_t>((ix - ix0) / down);
    double e = 0, var = 0;
    if (!grid.surface(c, e, var)) {
      state[at] = std::max<std::uint8_t>(state[at], 1);
      return;
    }
    state[at] = 2;
    if (down == 1) {
      z[at] = e;
    } else {
      z[at] = n[at] ? z[at] + e : e;
      ++n[at];
    }
    vals.push_back(e);
    zmin = std::min(zmin, e);
    zmax = std::max(zmax, e);
  });
  for (std::size_t i = 0; i < n.size(); ++i)
    if (n[i]) z[i] /= n[i];

  // The colour range: the 2nd and 98th percentiles, so that a few outliers do not wash out the
  // colours; the bar says so where they clip. Under a millimetre of relief the map is "flat".
  using Bar = ElevationPicture::Bar;
  double lo = 0, hi = 1;
  if (vals.empty()) {
    pic.bar = Bar::kNoData;
  } else if (zmax - zmin < 1e-3) {
    pic.bar = Bar::kFlat;
    lo = zmin;
    hi = zmax;
  } else {
    pic.bar = Bar::kRamp;
    // The same order statistics a full sort gives, selected: the lower first, then the upper
    // among the values above it.
    const std::size_t ilo = vals.size() * 2 / 100, ihi = std::min(vals.size() - 1, vals.size() * 98 / 100);
    std::nth_element(vals.begin(), vals.begin() + static_cast<std::ptrdiff_t>(ilo), vals.end());
    lo = vals[ilo];
    if (ihi > ilo)
      std::nth_element(vals.begin() + static_cast<std::ptrdiff_t>(ilo) + 1, vals.begin() + static_cast<std::ptrdiff_t>(ihi), vals.end());
    hi = vals[ihi];
    if (hi - lo < 1e-3) {  // most cells at one height, a few apart: a millimetre around it
      hi = std::min(zmax, lo + 1e-3);
      lo = hi - 1e-3;
    }
    pic.clipped_low = zmin < lo;
    pic.clipped_high = zmax > hi;
  }
  pic.lo = lo;
  pic.hi = hi;
  pic.zmin = vals.empty() ? 0 : zmin;
  pic.zmax = vals.empty() ? 0 : zmax;
  std::vector<double>().swap(vals);

  // ---- layout ----
  const int scale = std::max(1, std::min(8, 900 / std::max(nx, ny)));
  const int mapw = nx * scale, maph = ny * scale;
  const double res = grid.resolution();
  const double ppm = scale / (res * static_cast<double>(down));  // picture pixels per map metre
  const double west = static_cast<double>(ix0) * res, north = static_cast<double>(iy1 + 1) * res;
  const double east = west + mapw / ppm, south = north - maph / ppm;
  // Ticks every `step` map metres (1, 2 or 5 x 10^k), the labels at least two characters apart.
  double step = nice_at_least(100.0 / ppm);
  for (int guard = 0; guard < 64; ++guard) {
    const int d = decimals_of(step);
    int widest = 0;
    for (double v : {west, east, north, south}) widest = std::max(widest, text_width(fixed(v, d)));
    if (step * ppm >= widest + 2 * kAdvance) break;
    step = nice_at_least(step * 1.5);
  }
  const int dec = decimals_of(step);
  struct Tick {
    double px;  // along the axis, from the map's west (north) edge
    std::string text;
  };
  const auto ticks = [&](double from, double to, bool northing) {
    std::vector<Tick> out;
    const double k0 = std::ceil(from / step - 1e-9), k1 = std::floor(to / step + 1e-9);
    for (double k = k0; k <= k1 && out.size() < 1000; ++k) {
      const double v = k * step;
      out.push_back({northing ? (north - v) * ppm : (v - west) * ppm, fixed(v, dec)});
    }
    if (out.empty()) {  // a map smaller than a step: its centre, to the cell
      const double v = 0.5 * (from + to);
      out.push_back({northing ? (north - v) * ppm : (v - west) * ppm, fixed(v, decimals_of(nice_at_most(res)))});
    }
    return out;
  };
  const std::vector<Tick> east_ticks = ticks(west, east, false), north_ticks = ticks(south, north, true);
  int north_w = 0, east_w = 0;
  for (const Tick& t : north_ticks) north_w = std::max(north_w, text_width(t.text));
  for (const Tick& t : east_ticks) east_w = std::max(east_w, text_width(t.text));

  const int margin = 10, tick_len = 5;
  const int L = std::max(margin + north_w + 6 + tick_len + 1, margin + east_w / 2 + 1);
  const int T = margin + kLine + 10;  // the axis titles' row above the map
  // The colour bar: right of the map, clear of the last easting label; triangles at its ends
  // where the colours clip.
  const int tri = 14, bar_w = 20;
  const int bar_left = std::max(L + mapw + std::max(24, east_w / 2 + 12), margin + text_width("northing (m)") + 24);
  const int bar_top = T + tri + 2;
  const int bar_h = std::max(100, maph - 2 * (tri + 2));
  const int bar_label_x = bar_left + bar_w + 4 + 6;
  // The rows under the map: easting labels, the axis title, the scale bar, the legend.
  const int row_ticks = T + maph + 1 + tick_len + 6;
  const int row_title = row_ticks + kLine + 6;
  const int row_scale = row_title + kLine + 12;
  const int row_legend = row_scale + kLine + 12;

  // The colour bar's labels: text, the y of its tick on the bar (-1: none), the y of its centre.
  struct BarLabel {
    std::string text;
    int tick, y;
  };
  std::vector<BarLabel> bar_labels;
  const int bar_bottom = bar_top + bar_h - 1;
  const auto y_of = [&](double v) { return bar_top + static_cast<int>(std::lround((hi - v) / (hi - lo) * (bar_h - 1))); };
  if (pic.bar == Bar::kRamp) {
    const double zstep = nice_at_least((hi - lo) / std::max(2, bar_h / 70));
    const int zd = std::min(4, std::max(2, decimals_of(zstep)));  // at least to the cm
    // The ends say what they are: the true extreme, or the percentile the colours clip at (the
    // triangle beyond it gives the extreme).
    // The end labels sit just inside the bar's ends (their ticks at the ends), those of the
    // triangles beside them.
    bar_labels.push_back({fixed(hi, zd) + (pic.clipped_high ? " (98th pct)" : " max"), bar_top, bar_top + 3 + kCap / 2});
    bar_labels.push_back({fixed(lo, zd) + (pic.clipped_low ? " (2nd pct)" : " min"), bar_bottom, bar_bottom - 3 - kCap / 2});
    if (pic.clipped_high) bar_labels.push_back({"max " + fixed(zmax, zd), -1, bar_top - 2 - tri / 2});
    if (pic.clipped_low) bar_labels.push_back({"min " + fixed(zmin, zd), -1, bar_bottom + 2 + tri / 2});
    for (double k = std::ceil(lo / zstep); k * zstep < hi; ++k) {
      const int y = y_of(k * zstep);
      if (y - bar_top > kLine + 8 && bar_bottom - y > kLine + 8) bar_labels.push_back({fixed(k * zstep, zd), y, y});
    }
  } else if (pic.bar == Bar::kFlat) {
    bar_labels.push_back({"flat: z = " + fixed(0.5 * (zmin + zmax), 3) + " m", -1, bar_top + bar_h / 2});
  } else {
    bar_labels.push_back({"no data", -1, bar_top + bar_h / 2});
  }
  int bar_text_w = text_width("elevation (m)") - (bar_label_x - bar_left);
  for (const BarLabel& b : bar_labels) bar_text_w = std::max(bar_text_w, text_width(b.text));

  // The scale bar: a round length of about a fifth of the map.
  const double len = nice_at_most(std::max(mapw / ppm / 5.0, 1e-9));
  const int len_px = std::max(1, static_cast<int>(std::lround(len * ppm)));
  std::string scale_text = shortest(len) + " m   cells " + shortest(res) + " m";
  if (down > 1) scale_text += "   1 px = " + std::to_string(down) + " x " + std::to_string(down) + " cells";
  // The legend: the two colours that are not heights.
  const std::string unseen_text = "unseen (no return)";
  const std::string few_text = "too few returns (min_support " + std::to_string(grid.min_support()) + ")";
  const int sw = kLine;  // a swatch's side
  const int few_x = margin + sw + 8 + text_width(unseen_text) + 24;
  const int legend_w = few_x + sw + 8 + text_width(few_text);

  const int W = std::max({bar_label_x + bar_text_w + margin, margin + len_px + 10 + text_width(scale_text) + margin,
                          legend_w + margin, L + mapw + east_w / 2 + margin});
  const int H = std::max(row_legend + kLine + margin, bar_bottom + 2 + tri + kLine / 2 + margin);
  Canvas cv(W, H, pic.rgb);

  // ---- the map ----
  const auto at = [&](int col, int row) {
    col = std::clamp(col, 0, nx - 1);
    row = std::clamp(row, 0, ny - 1);
    return z[static_cast<std::size_t>(row) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(col)];
  };
  const double pres = res * static_cast<double>(down);  // of a pixel
  for (int row = 0; row < ny; ++row)
    for (int col = 0; col < nx; ++col) {
      const std::uint8_t s = state[static_cast<std::size_t>(row) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(col)];
      Rgb c = rgb(s == 0 ? kUnseenColour : kFewReturnsColour);
      if (s == 2) {
        const double e = at(col, row);
        c = ramp(pic.bar == Bar::kFlat ? 0.5 : (e - lo) / (hi - lo));
        // Hillshade: light from the north-west, 45 deg up.
        double dzdx = at(col + 1, row) - at(col - 1, row), dzdy = at(col, row - 1) - at(col, row + 1);
        if (!std::isfinite(dzdx)) dzdx = 0;
        if (!std::isfinite(dzdy)) dzdy = 0;
        dzdx /= 2 * pres;
        dzdy /= 2 * pres;
        const double slope = std::atan(std::hypot(dzdx, dzdy)), aspect = std::atan2(dzdy, -dzdx);
        const double zen = 0.785398, az = 2.356194;
        const double hs = std::cos(zen) * std::cos(slope) + std::sin(zen) * std::sin(slope) * std::cos(az - aspect);
        const double f = 0.55 + 0.45 * std::clamp(hs, 0.0, 1.0);
        c = {c.r * f, c.g * f, c.b * f};
      }
      cv.fill(L + col * scale, T + row * scale, scale, scale, c);
    }
  cv.frame(L, T, mapw, maph);

  // ---- the axes: eastings under the map, northings left of it, in map metres ----
  for (const Tick& t : east_ticks) {
    const int x = L + static_cast<int>(std::floor(t.px));
    cv.fill(x, T + maph + 1, 1, tick_len, kBlack);
    cv.text(x - text_width(t.text) / 2, row_ticks, t.text);
    pic.eastings.push_back({t.text, x});
  }
  for (const Tick& t : north_ticks) {
    const int y = T + static_cast<int>(std::floor(t.px));
    cv.fill(L - 1 - tick_len, y, tick_len, 1, kBlack);
    cv.text_mid(L - 1 - tick_len - 6 - text_width(t.text), y, t.text);
    pic.northings.push_back({t.text, y});
  }
  cv.text(margin, margin, "northing (m)");
  const std::string east_title = "easting (m)";
  cv.text(L + std::max(0, (mapw - text_width(east_title)) / 2), row_title, east_title);

  // ---- the colour bar ----
  cv.text(bar_left, margin, "elevation (m)");
  if (pic.bar == Bar::kRamp) {
    for (int y = 0; y < bar_h; ++y) cv.fill(bar_left, bar_top + y, bar_w, 1, ramp(1.0 - static_cast<double>(y) / (bar_h - 1)));
    // Triangles beyond the clipped ends, in the end's colour, outlined.
    const auto triangle = [&](int base_y, int dir, const Rgb& c) {  // dir -1: pointing up
      for (int r = 0; r < tri; ++r) {
        const int half = (bar_w / 2) * (tri - r) / tri, y = base_y + dir * r;
        cv.fill(bar_left + bar_w / 2 - half, y, 2 * half, 1, c);
        cv.put(bar_left + bar_w / 2 - half - 1, y, kBlack);
        cv.put(bar_left + bar_w / 2 + half, y, kBlack);
      }
      cv.fill(bar_left - 1, base_y, bar_w + 2, 1, kBlack);
    };
    if (pic.clipped_high) triangle(bar_top - 2, -1, ramp(1.0));
    if (pic.clipped_low) triangle(bar_bottom + 2, 1, ramp(0.0));
  } else if (pic.bar == Bar::kFlat) {
    cv.fill(bar_left, bar_top, bar_w, bar_h, ramp(0.5));
  }
  cv.frame(bar_left, bar_top, bar_w, bar_h);
  for (const BarLabel& b : bar_labels) {
    if (b.tick >= 0) cv.fill(bar_left + bar_w + 1, b.tick, 4, 1, kBlack);
    cv.text_mid(bar_label_x, b.y, b.text);
    pic.bar_labels.push_back({b.text, b.y});
  }

  // ---- the scale bar and the legend ----
  cv.fill(margin, row_scale + kCap / 2 - 2, len_px, 4, kBlack);
  cv.fill(margin, row_scale, 1, kCap, kBlack);
  cv.fill(margin + len_px - 1, row_scale, 1, kCap, kBlack);
  cv.text(margin + len_px + 10, row_scale, scale_text);
  const auto swatch = [&](int x, const detail::Rgb8& c, const std::string& label) {
    cv.fill(x, row_legend, sw, sw, rgb(c));
    cv.frame(x, row_legend, sw, sw);
    cv.text(x + sw + 8, row_legend + 1, label);
    pic.legend.push_back(label);
  };
  swatch(margin, kUnseenColour, unseen_text);
  swatch(few_x, kFewReturnsColour, few_text);

  pic.width = W;
  pic.height = H;
  pic.cells_per_pixel = static_cast<int>(down);
  pic.scale = scale;
  pic.map_left = L;
  pic.map_top = T;
  pic.map_width = mapw;
  pic.map_height = maph;
  pic.ix0 = ix0;
  pic.iy1 = iy1;
  pic.bar_left = bar_left;
  pic.bar_top = bar_top;
  pic.bar_width = bar_w;
  pic.bar_height = bar_h;
  return pic;
}

}  // namespace detail

int write_elevation_png(const ElevationGrid& grid, const std::string& path) {
  const detail::ElevationPicture pic = detail::render_elevation(grid);
  // libpng's simplified writer, which reports errors by return value (no longjmp through our
  // frames), with PNG_IMAGE_FLAG_FAST: no row filters, zlib level 3. It is a preview, not an
  // archive: a picture of 664 x 860 pixels (the 8-pass bench grid's map) encodes in 4.5 ms for 79.4 kB, where
  // GDAL's PNG driver at zlib level 3 (adaptive filters) took 12.3 ms for 73.8 kB.
  const std::string tmp = path + ".tmp-png";
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  img.width = static_cast<png_uint_32>(pic.width);
  img.height = static_cast<png_uint_32>(pic.height);
  img.format = PNG_FORMAT_RGB;
  img.flags = PNG_IMAGE_FLAG_FAST;
  if (!png_image_write_to_file(&img, tmp.c_str(), 0, pic.rgb.data(), 0, nullptr)) {
    const std::string why = img.message;
    png_image_free(&img);
    std::remove(tmp.c_str());
    throw OutputError(path + ": cannot write the PNG (" + why + ")");
  }
  rename_into_place(tmp, path);
  return pic.cells_per_pixel;
}

}  // namespace pcdp::io
