#include "pcdp/io/svg_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "xml_escape.hpp"

namespace pcdp::io {

namespace {
double nice_step(double span, int target) {
  const double raw = span / std::max(1, target);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * mag >= raw) return m * mag;
  return 10 * mag;
}


std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", std::fabs(v) < 1e-12 ? 0.0 : v);
  return b;
}
}  // namespace

std::string svg_line_plot(const PlotSpec& spec, int width, int height) {
  const bool lg = spec.log_y;
  // A point is drawn when finite (and, on a log axis, y > 0).
  const auto drawn = [lg](double x, double y) { return std::isfinite(x) && std::isfinite(y) && (!lg || y > 0); };
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const auto& s : spec.series)
    for (const auto& [x, y] : s.points) {
      if (!drawn(x, y)) continue;
      x0 = std::min(x0, x);
      x1 = std::max(x1, x);
      y0 = std::min(y0, y);
      y1 = std::max(y1, y);
    }
  if (spec.hline && drawn(0, *spec.hline)) {
    y0 = std::min(y0, *spec.hline);
    y1 = std::max(y1, *spec.hline);
  }
  if (!(x1 >= x0)) {  // nothing to draw
    x0 = 0;
    x1 = 1;
  } else if (!(x1 > x0)) {
    x1 = x0 + 1;
  }
  if (lg) {  // whole decades (log10 of the axis' ends), a curve not on the frame
    if (!(y1 >= y0)) y0 = y1 = 1;  // nothing to draw
    y0 = std::floor(std::log10(y0) - 0.15);
    y1 = std::max(y0 + 1, std::ceil(std::log10(y1) + 0.05));
  } else {
    if (!(y1 >= y0)) {
      y0 = 0;
      y1 = 1;
    } else if (!(y1 > y0)) {
      y1 = y0 + 1;
    }
    if (!spec.equal_axes) y0 = std::min(y0, 0.0);
  }
  const int L0 = 80, R0 = 200, T0 = 50, B0 = 60;
  if (spec.equal_axes && !lg) {  // grow the narrower range so that one metre is as long on both axes
    const double pw0 = width - L0 - R0, ph0 = height - T0 - B0;
    const double sx = (x1 - x0) / pw0, sy = (y1 - y0) / ph0;
    if (sx > sy) {
      const double c = 0.5 * (y0 + y1), h = 0.5 * sx * ph0;
      y0 = c - h;
      y1 = c + h;
    } else {
      const double c = 0.5 * (x0 + x1), h = 0.5 * sy * pw0;
      x0 = c - h;
      x1 = c + h;
    }
  }
  const double ys = lg ? 1.0 : nice_step(y1 - y0, 6), xs = nice_step(x1 - x0, 8);
  if (!spec.equal_axes && !lg) {
    y1 = std::ceil(y1 / ys) * ys;
    y0 = std::floor(y0 / ys) * ys;
  }
  const int L = L0, R = R0, T = T0, B = B0;
  const double pw = width - L - R, ph = height - T - B;
  const auto px = [&](double x) { return L + (x - x0) / (x1 - x0) * pw; };
  // On a log axis y0 and y1 are decades (log10) and a value is placed by its log10.
  const auto py = [&](double y) { return T + (1.0 - ((lg ? std::log10(y) : y) - y0) / (y1 - y0)) * ph; };

  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
    << "' font-family='sans-serif' font-size='13'>\n<rect width='100%' height='100%' fill='white'/>\n";
  o << "<text x='" << width / 2 << "' y='28' text-anchor='middle' font-size='16'>" << detail::xml_escape(spec.title) << "</text>\n";
  if (lg) {
    for (double d = y0; d <= y1 + 1e-9; ++d) {
      const double y = std::pow(10.0, d);
      o << "<line x1='" << L << "' x2='" << L + pw << "' y1='" << py(y) << "' y2='" << py(y) << "' stroke='#d9d9d9'/>";
      o << "<text x='" << L - 8 << "' y='" << py(y) + 4 << "' text-anchor='end'>" << num(y) << "</text>\n";
      if (d < y1 - 0.5)
        for (double m : {2.0, 5.0})
          o << "<line x1='" << L << "' x2='" << L + pw << "' y1='" << py(m * y) << "' y2='" << py(m * y) << "' stroke='#f0f0f0'/>";
    }
  } else {
    for (double y = std::ceil(y0 / ys) * ys; y <= y1 + 1e-9 * ys; y += ys) {
      o << "<line x1='" << L << "' x2='" << L + pw << "' y1='" << py(y) << "' y2='" << py(y) << "' stroke='#e5e5e5'/>";
      o << "<text x='" << L - 8 << "' y='" << py(y) + 4 << "' text-anchor='end'>" << num(y) << "</text>\n";
    }
  }
  for (double x = std::ceil(x0 / xs) * xs; x <= x1 + 1e-9 * xs; x += xs) {
    o << "<line x1='" << px(x) << "' x2='" << px(x) << "' y1='" << T << "' y2='" << T + ph << "' stroke='#f0f0f0'/>";
    o << "<text x='" << px(x) << "' y='" << T + ph + 18 << "' text-anchor='middle'>" << num(x) << "</text>\n";
  }
  o << "<rect x='" << L << "' y='" << T << "' width='" << pw << "' height='" << ph << "' fill='none' stroke='black'/>\n";
  o << "<text x='" << L + pw / 2 << "' y='" << height - 15 << "' text-anchor='middle'>" << detail::xml_escape(spec.xlabel) << "</text>\n";
  o << "<text transform='translate(20," << T + ph / 2 << ") rotate(-90)' text-anchor='middle'>" << detail::xml_escape(spec.ylabel)
    << "</text>\n";
  int row = 0;
  for (const auto& s : spec.series) {
    if (s.markers) {
      o << "<g fill='" << s.color << "'>";
      char b[96];
      for (const auto& [x, y] : s.points)
        if (drawn(x, y)) {
          std::snprintf(b, sizeof b, "<circle cx='%.1f' cy='%.1f' r='%.1f'/>", px(x), py(y), s.radius);
          o << b;
        }
      o << "</g>\n";
    } else {
      o << "<polyline fill='none' stroke='" << s.color << "' stroke-width='" << s.width << "'"
        << (s.dashed ? " stroke-dasharray='6,4'" : "") << " stroke-linejoin='round' points='";
      const std::pair<double, double>* last = nullptr;
      for (const auto& p : s.points)
        if (drawn(p.first, p.second)) {
          o << px(p.first) << ',' << py(p.second) << ' ';
          last = &p;
        }
      o << "'/>\n";
      if (last && !s.end_note.empty())
        o << "<text x='" << px(last->first) - 4 << "' y='" << py(last->second) - 8 << "' text-anchor='end' fill='" << s.color
          << "' font-weight='bold'>" << detail::xml_escape(s.end_note) << "</text>\n";
    }
    const double ly = T + 10 + 22 * row++;
    o << "<line x1='" << L + pw + 12 << "' x2='" << L + pw + 40 << "' y1='" << ly << "' y2='" << ly << "' stroke='" << s.color
      << "' stroke-width='" << (s.markers ? 2.0 : s.width) << "'" << (s.dashed ? " stroke-dasharray='6,4'" : "") << "/>";
    o << "<text x='" << L + pw + 46 << "' y='" << ly + 4 << "'>" << detail::xml_escape(s.label) << "</text>\n";
  }
  if (spec.hline && drawn(0, *spec.hline)) {
    o << "<line x1='" << L << "' x2='" << L + pw << "' y1='" << py(*spec.hline) << "' y2='" << py(*spec.hline)
      << "' stroke='#d62728' stroke-dasharray='3,3'/>";
    const double ly = T + 10 + 22 * row;
    o << "<line x1='" << L + pw + 12 << "' x2='" << L + pw + 40 << "' y1='" << ly << "' y2='" << ly
      << "' stroke='#d62728' stroke-dasharray='3,3'/><text x='" << L + pw + 46 << "' y='" << ly + 4 << "'>"
      << detail::xml_escape(spec.hline_label) << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

}  // namespace pcdp::io
