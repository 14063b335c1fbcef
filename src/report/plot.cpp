#include "xgauge/report/plot.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

// Header-only with every function static (since v1.1), so there is no
// implementation macro to define once.
#include <stb_easy_font.h>

// The PNG encoder's functions stay private to this file (STATIC), like in
// preview.cpp, so the two copies do not clash at link time. GCC inlines the
// encoder differently here than in preview.cpp and then reports a "potential
// null pointer dereference" inside stb's growable buffer (its allocation
// results are not checked); being a middle-end warning it escapes the
// system-header exemption, so it is silenced for stb's code only.
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace xgauge {
namespace {

// stb_easy_font draws on a grid of font units: capitals and digits span rows
// 0..7, descenders reach row 9, and lines are 12 units apart. Scaled 2x it
// reads well in reports at the default 1200 x 900.
constexpr int kFontScale = 2;
constexpr int kTextHeight = 10 * kFontScale;  // rows 0..9, descenders included
constexpr int kCapHeight = 7 * kFontScale;
// Any character beyond this would start past the widest allowed figure (the
// narrowest glyph advances 3 units), so longer text is cut; this also keeps
// the vertex buffer bounded.
constexpr size_t kMaxTextLength = 8000 / (3 * kFontScale) + 1;

constexpr Rgb8 kInk{0, 0, 0};
constexpr Rgb8 kPaper{255, 255, 255};
constexpr Rgb8 kGrid{225, 225, 225};
constexpr Rgb8 kZeroLine{140, 140, 140};
constexpr Rgb8 kLegendBorder{160, 160, 160};

constexpr int kMinSize = 200;
constexpr int kMaxSize = 8000;
constexpr int kMargin = 10;       // around the figure
constexpr int kTickLength = 5;    // outward tick marks
constexpr int kLabelGap = 4;      // between a tick mark and its label
constexpr int kPanelGap = 12;     // between a panel and the next one's header
constexpr int kMinPlotSize = 20;  // smallest usable plot area side
// A tick count of about 7: enough to read values off, few enough that the
// labels stay apart.
constexpr int kTargetTicks = 7;

// Everything beyond this many pixels outside the figure is clamped, so that
// points far outside a fixed y range neither overflow int nor make the line
// rasterizer walk millions of steps.
constexpr double kFarAway = 1e6;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct Range {
  double lo = 0.0;
  double hi = 1.0;
  double span() const { return hi - lo; }
};

// Inclusive pixel rectangle.
struct Rect {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
  bool contains(int x, int y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

Rect intersect(const Rect& a, const Rect& b) {
  return {std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
}

bool finitePoint(const PlotSeries& series, size_t i) {
  return std::isfinite(series.x[i]) && std::isfinite(series.y[i]);
}

// stb_easy_font indexes its tables with (character - 32) and reads one entry
// past it, so anything outside printable ASCII would read out of bounds.
std::string printable(const std::string& text) {
  std::string safe = text.substr(0, std::min(text.size(), kMaxTextLength));
  for (char& c : safe)
    if (c < 32 || c > 126) c = '?';
  return safe;
}

int textWidth(const std::string& text) {
  std::string safe = printable(text);
  return stb_easy_font_width(safe.data()) * kFontScale;
}

// An RGB canvas plus a mask of the pixels that show data, which decides
// where a legend hides the least.
class Canvas {
 public:
  Canvas(int width, int height)
      : width_(width),
        height_(height),
        rgb_(3 * static_cast<size_t>(width) * static_cast<size_t>(height), 255),
        data_(static_cast<size_t>(width) * static_cast<size_t>(height), 0) {}

  int width() const { return width_; }
  int height() const { return height_; }
  Rect bounds() const { return {0, 0, width_ - 1, height_ - 1}; }
  const std::vector<uint8_t>& rgb() const { return rgb_; }

  void fill(const Rect& rect, Rgb8 colour) { paint(intersect(rect, bounds()), colour, false); }
  // The same for data, kept inside `clip`, the plot area.
  void fillData(const Rect& rect, const Rect& clip, Rgb8 colour) {
    paint(intersect(intersect(rect, clip), bounds()), colour, true);
  }
  void outline(const Rect& rect, Rgb8 colour) {
    fill({rect.x0, rect.y0, rect.x1, rect.y0}, colour);
    fill({rect.x0, rect.y1, rect.x1, rect.y1}, colour);
    fill({rect.x0, rect.y0, rect.x0, rect.y1}, colour);
    fill({rect.x1, rect.y0, rect.x1, rect.y1}, colour);
  }
  int dataPixelsIn(const Rect& rect) const {
    const Rect r = intersect(rect, bounds());
    int count = 0;
    for (int y = r.y0; y <= r.y1; ++y)
      for (int x = r.x0; x <= r.x1; ++x) count += data_[index(x, y)];
    return count;
  }

  // Text with its top-left corner at (x, y); the font's quads are filled at
  // kFontScale.
  void text(int x, int y, const std::string& text, Rgb8 colour) {
    std::string safe = printable(text);
    if (safe.empty()) return;
    // At most 16 quads of 4 vertices of 4 floats (x, y, z, colour) per glyph.
    std::vector<float> vertices(safe.size() * 16 * 4 * 4);
    const int quads = stb_easy_font_print(0.0f, 0.0f, safe.data(), nullptr, vertices.data(),
                                          static_cast<int>(vertices.size() * sizeof(float)));
    for (int q = 0; q < quads; ++q) {
      // Vertices 0 and 2 are opposite corners of an axis-aligned quad.
      const float* corner = vertices.data() + static_cast<size_t>(q) * 16;
      const int qx0 = static_cast<int>(std::lround(corner[0]));
      const int qy0 = static_cast<int>(std::lround(corner[1]));
      const int qx1 = static_cast<int>(std::lround(corner[8]));
      const int qy1 = static_cast<int>(std::lround(corner[9]));
      fill({x + std::min(qx0, qx1) * kFontScale, y + std::min(qy0, qy1) * kFontScale,
            x + std::max(qx0, qx1) * kFontScale - 1, y + std::max(qy0, qy1) * kFontScale - 1},
           colour);
    }
  }

 private:
  size_t index(int x, int y) const {
    return static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x);
  }
  void paint(const Rect& r, Rgb8 colour, bool is_data) {
    for (int y = r.y0; y <= r.y1; ++y)
      for (int x = r.x0; x <= r.x1; ++x) {
        const size_t i = index(x, y);
        rgb_[3 * i] = colour.r;
        rgb_[3 * i + 1] = colour.g;
        rgb_[3 * i + 2] = colour.b;
        if (is_data) data_[i] = 1;
      }
  }

  int width_;
  int height_;
  std::vector<uint8_t> rgb_;
  std::vector<uint8_t> data_;
};

// ---- Ranges and ticks ----

SourceLocation where(const std::filesystem::path& path) {
  return SourceLocation::inFile(path.string());
}

// lo..hi widened by `fraction` of the span on each side. A single value gets
// +-5 % of itself (+-0.5 around 0) so that it lands mid-axis.
Range padded(const std::filesystem::path& path, double lo, double hi, double fraction,
             const char* axis) {
  Range range;
  if (hi > lo) {
    const double pad = (hi - lo) * fraction;
    range = {lo - pad, hi + pad};
  } else {
    const double pad = std::abs(lo) * 0.05;
    range = {lo - pad, lo + pad};
    if (!(range.hi > range.lo)) range = {lo - 0.5, lo + 0.5};
  }
  if (!std::isfinite(range.span()))
    failAt(where(path), "the {} values span too wide a range to plot: [{}, {}]", axis, lo, hi);
  return range;
}

struct Ticks {
  std::vector<double> values;
  std::vector<std::string> labels;
};

// %g with just enough significant digits to tell ticks `step` apart, so that
// 0.1 + 0.2 shows as 0.3 and 100000.5 is not rounded to 100000.
std::string tickLabel(double value, double step, double max_abs) {
  if (value == 0.0) return "0";
  const auto exponent = [](double v) { return std::floor(std::log10(v) + 1e-9); };
  const double digits = std::clamp(exponent(max_abs) - exponent(step) + 1.0, 1.0, 17.0);
  return fmt::format("{:.{}g}", value, static_cast<int>(digits));
}

// Ticks on multiples of a nice step (1, 2 or 5 x 10^k) inside `range`: the
// step whose tick count is nearest kTargetTicks among those whose labels fit
// `length_px` pixels (label_extent gives a label's size along the axis); if
// none fits, the one with the fewest ticks.
template <typename LabelExtent>
Ticks makeTicks(const Range& range, int length_px, LabelExtent label_extent) {
  std::optional<Ticks> best;
  double best_score = 0.0;
  const double top_exponent = std::floor(std::log10(range.span()));
  for (int k = -3; k <= 1; ++k) {
    for (const double mantissa : {1.0, 2.0, 5.0}) {
      const double step = mantissa * std::pow(10.0, top_exponent + k);
      const double first = std::ceil(range.lo / step - 1e-9);
      const double last = std::floor(range.hi / step + 1e-9);
      const double count = last - first + 1.0;
      if (count < 1.0 || count > 100.0) continue;
      Ticks ticks;
      double max_abs = 0.0;
      for (double multiple = first; multiple <= last; ++multiple) {
        double value = multiple * step;
        if (std::abs(value) < step * 1e-9) value = 0.0;  // no "-0" or "1e-17"
        ticks.values.push_back(value);
        max_abs = std::max(max_abs, std::abs(value));
      }
      int widest = 0;
      for (const double value : ticks.values) {
        ticks.labels.push_back(tickLabel(value, step, max_abs));
        widest = std::max(widest, label_extent(ticks.labels.back()));
      }
      const double step_px = step / range.span() * length_px;
      const bool fits = step_px >= widest;
      const double score = fits ? std::abs(count - kTargetTicks) : 1000.0 + count;
      // Ties go to the larger step (fewer labels): steps grow in this loop.
      if (!best || score <= best_score) {
        best = std::move(ticks);
        best_score = score;
      }
    }
  }
  XG_CHECK(best.has_value(), "no tick step for [{}, {}]", range.lo, range.hi);
  return std::move(*best);
}

Ticks xTicks(const Range& range, int length_px) {
  return makeTicks(range, length_px,
                   [](const std::string& label) { return textWidth(label) + 16; });
}
Ticks yTicks(const Range& range, int length_px) {
  return makeTicks(range, length_px, [](const std::string&) { return kTextHeight + 6; });
}

// ---- Data ----

// Maps data coordinates to pixel coordinates (pixel centres at integers).
struct Mapping {
  Rect area;
  Range x, y;
  double px(double value) const {
    const double p = area.x0 + (value - x.lo) / x.span() * (area.x1 - area.x0);
    return std::clamp(p, -kFarAway, kFarAway);
  }
  double py(double value) const {  // image rows grow downward
    const double p = area.y1 - (value - y.lo) / y.span() * (area.y1 - area.y0);
    return std::clamp(p, -kFarAway, kFarAway);
  }
};

// The 2 px line brush covers [x - 1, x + 1] x [y - 1, y + 1].
void brush(Canvas& canvas, const Rect& clip, double x, double y, Rgb8 colour) {
  const int px = static_cast<int>(std::floor(x - 0.5));
  const int py = static_cast<int>(std::floor(y - 0.5));
  canvas.fillData({px, py, px + 1, py + 1}, clip, colour);
}

// Liang-Barsky: cuts the segment a-b to `rect` (widened by the brush), so that
// only visible parts are walked. False if nothing is left.
bool clipSegment(const Rect& rect, double& ax, double& ay, double& bx, double& by) {
  const double dx = bx - ax;
  const double dy = by - ay;
  double t0 = 0.0;
  double t1 = 1.0;
  const std::array<double, 4> p = {-dx, dx, -dy, dy};
  const std::array<double, 4> q = {ax - (rect.x0 - 2), (rect.x1 + 2) - ax, ay - (rect.y0 - 2),
                                   (rect.y1 + 2) - ay};
  for (size_t i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0.0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  const double x0 = ax + t0 * dx, y0 = ay + t0 * dy;
  bx = ax + t1 * dx;
  by = ay + t1 * dy;
  ax = x0;
  ay = y0;
  return true;
}

void drawSegment(Canvas& canvas, const Rect& clip, double ax, double ay, double bx, double by,
                 Rgb8 colour) {
  if (!clipSegment(clip, ax, ay, bx, by)) return;
  // One brush dab per pixel along the longer axis leaves no gaps.
  const int steps =
      std::max(1, static_cast<int>(std::ceil(std::max(std::abs(bx - ax), std::abs(by - ay)))));
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / steps;
    brush(canvas, clip, ax + t * (bx - ax), ay + t * (by - ay), colour);
  }
}

void drawPoint(Canvas& canvas, const Rect& clip, double x, double y, Rgb8 colour) {
  const int px = static_cast<int>(std::lround(x));
  const int py = static_cast<int>(std::lround(y));
  canvas.fillData({px - 1, py - 1, px + 1, py + 1}, clip, colour);
}

void drawSeries(Canvas& canvas, const Mapping& map, const PlotSeries& series) {
  bool have_previous = false;
  double previous_x = 0.0, previous_y = 0.0;
  int drawn = 0;
  for (size_t i = 0; i < series.x.size(); ++i) {
    if (!finitePoint(series, i)) continue;
    const double x = map.px(series.x[i]);
    const double y = map.py(series.y[i]);
    if (series.style == PlotSeries::Style::kPoints) {
      drawPoint(canvas, map.area, x, y, series.colour);
    } else if (have_previous) {
      drawSegment(canvas, map.area, previous_x, previous_y, x, y, series.colour);
    }
    previous_x = x;
    previous_y = y;
    have_previous = true;
    ++drawn;
  }
  // A line through a single point would draw nothing: show it as a dot.
  if (series.style == PlotSeries::Style::kLine && drawn == 1)
    brush(canvas, map.area, previous_x, previous_y, series.colour);
}

// ---- Legend ----

void drawLegend(Canvas& canvas, const Rect& area, const PlotPanel& panel) {
  std::vector<const PlotSeries*> entries;
  int text_width = 0;
  for (const PlotSeries& series : panel.series) {
    if (series.label.empty()) continue;
    entries.push_back(&series);
    text_width = std::max(text_width, textWidth(series.label));
  }
  if (entries.empty()) return;
  constexpr int kPad = 6, kSwatch = 28, kRow = kTextHeight + 4, kInset = 6;
  const int width = kPad + kSwatch + kPad + text_width + kPad;
  const int height = kPad + static_cast<int>(entries.size()) * kRow;
  // Top-right first (the usual place), then the other corners.
  const std::array<Rect, 4> corners = {{
      {area.x1 - kInset - width + 1, area.y0 + kInset, area.x1 - kInset,
       area.y0 + kInset + height - 1},
      {area.x0 + kInset, area.y0 + kInset, area.x0 + kInset + width - 1,
       area.y0 + kInset + height - 1},
      {area.x1 - kInset - width + 1, area.y1 - kInset - height + 1, area.x1 - kInset,
       area.y1 - kInset},
      {area.x0 + kInset, area.y1 - kInset - height + 1, area.x0 + kInset + width - 1,
       area.y1 - kInset},
  }};
  Rect box = corners[0];
  int hidden = canvas.dataPixelsIn(box);
  for (size_t i = 1; i < corners.size(); ++i) {
    const int count = canvas.dataPixelsIn(corners[i]);
    if (count < hidden) {
      box = corners[i];
      hidden = count;
    }
  }
  // A legend larger than the plot area is cut at its edges rather than spill
  // over the tick labels.
  const Rect shown = intersect(box, area);
  canvas.fill(shown, kPaper);
  canvas.outline(shown, kLegendBorder);
  for (size_t i = 0; i < entries.size(); ++i) {
    const PlotSeries& series = *entries[i];
    const int top = box.y0 + kPad + static_cast<int>(i) * kRow;
    const int middle = top + kCapHeight / 2;
    const int swatch_x = box.x0 + kPad;
    if (series.style == PlotSeries::Style::kLine) {
      drawSegment(canvas, shown, swatch_x, middle, swatch_x + kSwatch - 1, middle, series.colour);
    } else {
      for (const int dx : {4, kSwatch / 2, kSwatch - 5})
        drawPoint(canvas, shown, swatch_x + dx, middle, series.colour);
    }
    // Text is clipped to the figure only; a legend cut by a tiny plot area
    // may let a long label run past it, which is still readable.
    if (top + kTextHeight <= shown.y1)
      canvas.text(swatch_x + kSwatch + kPad, top, series.label, kInk);
  }
}

// ---- Layout ----

struct PanelLayout {
  Rect area;  // inside the frame
  Range y;
  Ticks y_ticks;
};

void validate(const std::filesystem::path& path, const PlotFigure& figure) {
  if (figure.panels.empty()) failAt(where(path), "a plot needs at least one panel");
  for (const int size : {figure.width, figure.height})
    if (size < kMinSize || size > kMaxSize)
      failAt(where(path), "plot size {} x {} out of range: each side must be in [{}, {}]",
             figure.width, figure.height, kMinSize, kMaxSize);
  for (size_t p = 0; p < figure.panels.size(); ++p) {
    const PlotPanel& panel = figure.panels[p];
    if (!(panel.height_weight > 0.0 && std::isfinite(panel.height_weight)))
      failAt(where(path), "panel {}: height_weight {} must be finite and > 0", p + 1,
             panel.height_weight);
    if (panel.y_min < panel.y_max && !(std::isfinite(panel.y_min) && std::isfinite(panel.y_max) &&
                                       std::isfinite(panel.y_max - panel.y_min)))
      failAt(where(path), "panel {}: the y range [{}, {}] is not finite", p + 1, panel.y_min,
             panel.y_max);
    bool any_finite = false;
    for (size_t s = 0; s < panel.series.size(); ++s) {
      const PlotSeries& series = panel.series[s];
      if (series.x.size() != series.y.size())
        failAt(where(path), "panel {}, series {}: {} x values but {} y values", p + 1, s + 1,
               series.x.size(), series.y.size());
      for (size_t i = 0; i < series.x.size() && !any_finite; ++i)
        any_finite = finitePoint(series, i);
    }
    if (!any_finite)
      failAt(where(path), "panel {} ('{}') has no finite point to plot", p + 1, panel.title);
  }
}

Range xRange(const std::filesystem::path& path, const PlotFigure& figure) {
  double lo = kInfinity, hi = -kInfinity;
  for (const PlotPanel& panel : figure.panels)
    for (const PlotSeries& series : panel.series)
      for (const double x : series.x)
        if (std::isfinite(x)) {
          lo = std::min(lo, x);
          hi = std::max(hi, x);
        }
  return padded(path, lo, hi, 0.02, "x");
}

Range yRange(const std::filesystem::path& path, const PlotPanel& panel) {
  if (panel.y_min < panel.y_max) return {panel.y_min, panel.y_max};
  double lo = kInfinity, hi = -kInfinity;
  for (const PlotSeries& series : panel.series)
    for (size_t i = 0; i < series.x.size(); ++i)
      if (finitePoint(series, i)) {
        lo = std::min(lo, series.y[i]);
        hi = std::max(hi, series.y[i]);
      }
  return padded(path, lo, hi, 0.05, "y");
}

}  // namespace

void writePlotPng(const std::filesystem::path& path, const PlotFigure& figure) {
  validate(path, figure);
  const Range x_range = xRange(path, figure);
  const size_t panel_count = figure.panels.size();
  const int n = static_cast<int>(panel_count);

  // Vertical layout: per panel a header row (title, y label) above a framed
  // plot area; below the last one the x tick labels and the x label. The
  // plot areas share what is left in proportion to height_weight.
  const int header = kTextHeight + 8;
  const int bottom = kTickLength + kLabelGap + kTextHeight +
                     (figure.x_label.empty() ? 0 : 6 + kTextHeight) + kMargin;
  const int frames = 2 * n;  // one frame line above and below each plot area
  const int available =
      figure.height - kMargin - bottom - n * header - (n - 1) * kPanelGap - frames;
  if (available < n * kMinPlotSize)
    failAt(where(path), "a {} px high plot has no room for {} panels", figure.height, n);
  double total_weight = 0.0;
  for (const PlotPanel& panel : figure.panels) total_weight += panel.height_weight;

  std::vector<PanelLayout> layouts(panel_count);
  {
    double weight_so_far = 0.0;
    int used = 0;
    int top = kMargin;
    for (size_t p = 0; p < panel_count; ++p) {
      // Cumulative rounding: the heights add up to `available` exactly.
      weight_so_far += figure.panels[p].height_weight;
      const int end = static_cast<int>(std::lround(available * (weight_so_far / total_weight)));
      const int plot_height = std::max(1, end - used);
      used = end;
      top += header + 1;  // + the frame line
      layouts[p].area.y0 = top;
      layouts[p].area.y1 = top + plot_height - 1;
      top += plot_height + 1 + kPanelGap;
      layouts[p].y = yRange(path, figure.panels[p]);
      layouts[p].y_ticks = yTicks(layouts[p].y, plot_height);
    }
  }

  // Horizontal layout: the y tick labels set the left margin; the last x tick
  // label, centred on its tick, sets the right one.
  int widest_y_label = 0;
  for (const PanelLayout& layout : layouts)
    for (const std::string& label : layout.y_ticks.labels)
      widest_y_label = std::max(widest_y_label, textWidth(label));
  const int left = kMargin + widest_y_label + kLabelGap + kTickLength + 1;
  const auto rightMargin = [&](const Ticks& ticks) {
    int widest = 0;
    for (const std::string& label : ticks.labels) widest = std::max(widest, textWidth(label));
    return std::max(2 * kMargin, widest / 2 + kMargin);
  };
  const int right = rightMargin(xTicks(x_range, figure.width - left - 2 * kMargin));
  const int plot_width = figure.width - left - right - 1;
  if (plot_width < kMinPlotSize)
    failAt(where(path), "a {} px wide plot has no room for its tick labels", figure.width);
  const Ticks x_ticks = xTicks(x_range, plot_width);

  Canvas canvas(figure.width, figure.height);
  for (size_t p = 0; p < panel_count; ++p) {
    const PlotPanel& panel = figure.panels[p];
    PanelLayout& layout = layouts[p];
    layout.area.x0 = left;
    layout.area.x1 = left + plot_width - 1;
    const Rect& area = layout.area;
    const Mapping map{area, x_range, layout.y};

    // Grid and zero line first, so that data is drawn over them.
    for (const double x : x_ticks.values) {
      const int px = static_cast<int>(std::lround(map.px(x)));
      canvas.fill({px, area.y0, px, area.y1}, kGrid);
    }
    for (const double y : layout.y_ticks.values) {
      const int py = static_cast<int>(std::lround(map.py(y)));
      canvas.fill({area.x0, py, area.x1, py}, kGrid);
    }
    if (panel.zero_line && layout.y.lo <= 0.0 && 0.0 <= layout.y.hi) {
      const int py = static_cast<int>(std::lround(map.py(0.0)));
      canvas.fill({area.x0, py, area.x1, py}, kZeroLine);
    }
    for (const PlotSeries& series : panel.series) drawSeries(canvas, map, series);
    drawLegend(canvas, area, panel);
    canvas.outline({area.x0 - 1, area.y0 - 1, area.x1 + 1, area.y1 + 1}, kInk);

    // Ticks point outward, so they never cover data.
    for (size_t i = 0; i < layout.y_ticks.values.size(); ++i) {
      const int py = static_cast<int>(std::lround(map.py(layout.y_ticks.values[i])));
      canvas.fill({area.x0 - 1 - kTickLength, py, area.x0 - 2, py}, kInk);
      const std::string& label = layout.y_ticks.labels[i];
      canvas.text(area.x0 - 1 - kTickLength - kLabelGap - textWidth(label), py - kCapHeight / 2,
                  label, kInk);
    }
    const bool last = p + 1 == panel_count;
    for (size_t i = 0; i < x_ticks.values.size(); ++i) {
      const int px = static_cast<int>(std::lround(map.px(x_ticks.values[i])));
      canvas.fill({px, area.y1 + 2, px, area.y1 + 1 + kTickLength}, kInk);
      if (!last) continue;
      // Labels are centred on their ticks but kept inside the figure.
      const std::string& label = x_ticks.labels[i];
      const int width = textWidth(label);
      const int x = std::clamp(px - width / 2, 0, std::max(0, figure.width - width));
      canvas.text(x, area.y1 + 2 + kTickLength + kLabelGap, label, kInk);
    }

    // Header: the y label starts at the y axis, the title is centred over
    // the plot area unless that would run into the y label.
    const int header_top = area.y0 - 1 - header + 2;
    canvas.text(area.x0, header_top, panel.y_label, kInk);
    if (!panel.title.empty()) {
      const int y_label_end =
          panel.y_label.empty() ? area.x0 : area.x0 + textWidth(panel.y_label) + kTextHeight;
      const int title_width = textWidth(panel.title);
      const int centred = area.x0 + (area.width() - title_width) / 2;
      canvas.text(std::max(centred, y_label_end), header_top, panel.title, kInk);
    }
  }
  if (!figure.x_label.empty()) {
    const Rect& area = layouts.back().area;
    const int width = textWidth(figure.x_label);
    const int x = std::max(0, area.x0 + (area.width() - width) / 2);
    canvas.text(x, area.y1 + 2 + kTickLength + kLabelGap + kTextHeight + 6, figure.x_label, kInk);
  }

  // Encoded to memory and written with writeFileAtomically, as in
  // preview.cpp: stbi_write_png() would not notice a full disk.
  std::string png;
  const auto append = [](void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data),
                                               static_cast<size_t>(size));
  };
  if (stbi_write_png_to_func(append, &png, canvas.width(), canvas.height(), 3, canvas.rgb().data(),
                             canvas.width() * 3) == 0)
    failAt(where(path), "cannot encode the PNG image");
  writeFileAtomically(path, png);
}

}  // namespace xgauge
