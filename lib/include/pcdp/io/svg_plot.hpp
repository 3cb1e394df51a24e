// Minimal line plots as SVG (axes, ticks, legend, optional horizontal threshold line), for the
// pictures the CLI draws (amplitude model, error budget). No dependency beyond the standard library.
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
};

struct PlotSpec {
  std::string title, xlabel, ylabel;
  bool equal_axes = false;  ///< same scale on x and y (maps, top views)
  std::vector<PlotSeries> series;
  std::optional<double> hline;  ///< e.g. the minimum detectable amplitude
  std::string hline_label;
};

std::string svg_line_plot(const PlotSpec& spec, int width = 760, int height = 460);

}  // namespace pcdp::io
