// Charts as PNG figures for people (calibration reports): panels stacked
// vertically sharing one x axis, each with its own y axis, drawn with axes,
// tick labels, a title and a legend. Text is drawn with stb_easy_font (a
// public-domain bitmap-ish vector font from the stb collection, Debian
// libstb-dev), scaled up 2x; no font files are needed. The font covers
// printable ASCII only: any other byte (UTF-8 included) is drawn as '?'.
#pragma once

#include "xgauge/image/preview.h"  // Rgb8

#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

struct PlotSeries {
  // Same size. A point with a non-finite x or y is skipped: a line joins the
  // finite points on either side of it.
  std::vector<double> x, y;
  enum class Style { kLine, kPoints } style = Style::kLine;
  Rgb8 colour{0, 0, 0};
  std::string label;  // legend text; empty = not in the legend
};

struct PlotPanel {
  std::string title;    // drawn above the panel
  std::string y_label;  // drawn at the top-left of the panel, next to the y axis
  std::vector<PlotSeries> series;
  // y range: automatic (min..max of the finite points, padded 5 %) unless
  // y_min < y_max. Points outside a fixed range are clipped.
  double y_min = 0.0, y_max = 0.0;
  bool zero_line = false;      // draw a thin grey horizontal line at y = 0 (residual panels)
  double height_weight = 1.0;  // share of the figure's plot height (> 0)
};

struct PlotFigure {
  std::string x_label;
  std::vector<PlotPanel> panels;   // at least one
  int width = 1200, height = 900;  // pixels, each in [200, 8000]
};

// Draws the figure into an RGB PNG at `path`, written atomically. The x range
// is the min..max of every finite x of every series (padded 2 %). Ticks: "nice"
// steps (1, 2, 5 x 10^k), about 6-8 per axis (fewer where the labels would not
// fit), labels formatted with %g-like short text. Lines are drawn as connected
// polylines in x order as given (anti-aliasing not required; 2 px wide),
// points as 3x3 px squares. Each panel's legend goes into the corner of its
// plot area that hides the fewest data pixels. Throws Error (naming the file)
// if there are no panels, a series' x and y differ in size, a panel has no
// finite point at all, sizes are out of range, a height_weight is not > 0, or
// the file cannot be written; also if a fixed y range is not finite or the
// figure is too small to give every panel a usable plot area.
void writePlotPng(const std::filesystem::path& path, const PlotFigure& figure);

}  // namespace xgauge
