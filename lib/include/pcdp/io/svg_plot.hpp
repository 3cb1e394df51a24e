// Minimal line plots as SVG (axes, ticks, legend, optional horizontal threshold line, optional
// logarithmic y axis), for the pictures the CLI draws (amplitude model, error budget). Series are
// drawn in order: the last is on top. No dependency beyond the standard library.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace pcdp::io {

struct PlotSeries {
  std::string label;
  std::vector<std::pair<double, double>> points;
  std::string color = "#1f77b4";
  bool dashed = false;
  bool markers = false;  ///< draw points (scatter) instead of a line
  double radius = 1.2;
  double width = 2;       ///< the line's stroke width (px), in the plot and the legend
  std::string end_note{}; ///< written beside the line's last point (e.g. its value there)
};

struct PlotSpec {
  std::string title, xlabel, ylabel;
  bool equal_axes = false;  ///< same scale on x and y (maps, top views)
  /// A logarithmic y axis (decades labelled, 2 and 5 between them as grid lines): curves that
  /// differ by orders of magnitude all stay readable. Points with y <= 0 are left out.
  bool log_y = false;
  std::vector<PlotSeries> series;
  std::optional<double> hline;  ///< e.g. the minimum detectable amplitude
  std::string hline_label;
};

std::string svg_line_plot(const PlotSpec& spec, int width = 760, int height = 460);

}  // namespace pcdp::io
