#include "xgauge/calibrate/ramp.h"

#include "xgauge/core/error.h"
#include "xgauge/image/pyramid.h"

#include <algorithm>
#include <cmath>

namespace xgauge {

namespace {

constexpr int kCoarseWidth = 256;
constexpr double kBandShrink = 0.15;

double median(std::vector<double> values) {
  XG_CHECK(!values.empty(), "median of nothing");
  const auto middle = values.begin() + static_cast<ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// Median of profile[first, last], clipped to the profile.
double medianOf(const std::vector<double>& p, int first, int last) {
  first = std::max(first, 0);
  last = std::min(last, static_cast<int>(p.size()) - 1);
  if (first > last)
    return p[static_cast<size_t>(std::clamp(first, 0, static_cast<int>(p.size()) - 1))];
  return median(std::vector<double>(p.begin() + first, p.begin() + last + 1));
}

// The open beam's level in a profile: its brightest value, but at most 1 (a
// noisy or over-corrected bright spot would lift it above the open beam
// around it) and 1 when even that is below kOpenFloor (no open beam at all).
// A flat panel's signal-dependent column darkening lowers the open beam in
// the columns that see the wedge by about a percent, below a fixed threshold
// near 1.
constexpr double kOpenFloor = 0.95;
double openLevel(double brightest) {
  return brightest >= kOpenFloor ? std::min(brightest, 1.0) : 1.0;
}
double brightestOf(const std::vector<double>& p) {
  double out = 0.0;
  for (double v : p) out = std::max(out, v);
  return out;
}

// Contrast along each column of the coarse image: mean of the first quarter of
// its shadow (rows 0.01 below the column's open beam) minus the mean of the
// last quarter. Positive when the column darkens downwards.
std::vector<double> columnContrast(const Image& coarse) {
  std::vector<double> out(static_cast<size_t>(coarse.width()), 0.0);
  for (int x = 0; x < coarse.width(); ++x) {
    // The column's open beam: its 90th percentile (its maximum would be
    // lifted by the noise).
    std::vector<double> column(static_cast<size_t>(coarse.height()));
    for (int y = 0; y < coarse.height(); ++y)
      column[static_cast<size_t>(y)] = static_cast<double>(coarse(x, y));
    const auto high = column.begin() + static_cast<std::ptrdiff_t>(0.9 * (column.size() - 1));
    std::nth_element(column.begin(), high, column.end());
    const double shadow = openLevel(*high) - 0.01;
    int first = -1, last = -1, count = 0;
    for (int y = 0; y < coarse.height(); ++y)
      if (static_cast<double>(coarse(x, y)) < shadow) {
        if (first < 0) first = y;
        last = y, ++count;
      }
    if (count < std::max(4, coarse.height() / 10)) continue;
    const int quarter = std::max(1, (last - first + 1) / 4);
    double head = 0.0, tail = 0.0;
    for (int k = 0; k < quarter; ++k)
      head += static_cast<double>(coarse(x, first + k)),
          tail += static_cast<double>(coarse(x, last - k));
    out[static_cast<size_t>(x)] = (head - tail) / quarter;
  }
  return out;
}

// The continuous coordinate nearest `near` where the profile crosses `level`
// between two row centres.
std::optional<double> crossingNear(const std::vector<double>& p, double level, int near,
                                   int reach) {
  std::optional<double> best;
  for (int i = std::max(0, near - reach); i + 1 < static_cast<int>(p.size()) && i <= near + reach;
       ++i) {
    const double a = p[static_cast<size_t>(i)] - level, b = p[static_cast<size_t>(i) + 1] - level;
    if ((a >= 0.0) == (b >= 0.0)) continue;
    const double at = i + 0.5 + a / (a - b);
    if (!best || std::abs(at - near) < std::abs(*best - near)) best = at;
  }
  return best;
}

struct Line {
  double slope = 0.0, intercept = 0.0;  // value = slope * (row + 0.5) + intercept
};

Line fitLine(const std::vector<double>& p, int first, int last) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (int i = first; i <= last; ++i) {
    const double x = i + 0.5, y = p[static_cast<size_t>(i)];
    n += 1, sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return {slope, (sy - slope * sx) / n};
}

// Thin and thick end of the ramp in a profile whose thin end is at the top
// (small rows). Throws with `name` when there is none or it runs off the image.
std::array<double, 2> findRampRows(const std::vector<double>& p, double noise,
                                   const std::string& name, const std::string& thin_side,
                                   const std::string& thick_side) {
  const int n = static_cast<int>(p.size());
  // A running median of 7 rows: less noise, and the edges stay where they are.
  std::vector<double> ps(p.size());
  for (int i = 0; i < n; ++i) ps[static_cast<size_t>(i)] = medianOf(p, i - 3, i + 3);
  // The shadow: the longest run of rows clearly below the open beam.
  const double threshold = openLevel(brightestOf(ps)) - std::max(0.003, 6.0 * noise);
  int best_first = -1, best_last = -2;
  for (int i = 0; i < n;) {
    if (!(ps[static_cast<size_t>(i)] < threshold)) {
      ++i;
      continue;
    }
    int j = i;
    while (j + 1 < n && ps[static_cast<size_t>(j) + 1] < threshold) ++j;
    if (j - i > best_last - best_first) best_first = i, best_last = j;
    i = j + 1;
  }
  if (best_last - best_first + 1 < 20)
    fail("{}: no ramp found: the band's profile has no shadow of 20 rows or more below {:.4f}",
         name, threshold);
  const int a = best_first, b = best_last;
  if (a <= 2)
    fail(
        "{}: the ramp runs off the image at its {} edge (its shadow begins at row {}): the "
        "radiograph must show the whole wedge, thin end to x_max, with open beam beyond both ends",
        name, thin_side, a);
  if (b >= n - 3)
    fail(
        "{}: the ramp runs off the image at its {} edge (its shadow ends at row {}): the "
        "radiograph must show the whole wedge, thin end to x_max, with open beam beyond both ends",
        name, thick_side, b);
  // The minimum: the thick end is at it or, with a rise, near it.
  const std::vector<double>& pm = ps;
  int m = a;
  for (int i = a; i <= b; ++i)
    if (pm[static_cast<size_t>(i)] < pm[static_cast<size_t>(m)]) m = i;
  const double start_level = medianOf(p, a + 3, a + 12);
  const double lowest = pm[static_cast<size_t>(m)];
  const double fall = start_level - lowest;
  if (m - a < 10 || fall < std::max(0.05, 20.0 * noise))
    fail(
        "{}: no ramp found: the shadow (rows {}..{}) does not darken along the band (from {:.4f} "
        "to {:.4f})",
        name, a, b, start_level, lowest);

  // Thin end: the step from the open beam, half-way between the open beam
  // and the ramp's value at the step (a line through the ramp's first rows,
  // extrapolated: where the ramp is steep a median would sit too low).
  const double outside = medianOf(p, a - 12, a - 3);
  const Line head = fitLine(p, a + 2, a + 12);
  const double inside_at_step = head.slope * a + head.intercept;
  const double thin = crossingNear(p, 0.5 * (outside + inside_at_step), a, 8).value_or(a);

  // Thick end. A step back to the open beam (the shadow ends within a few
  // rows of the minimum): its half-way crossing. Otherwise a kink: where the
  // line through the end of the fall meets the line through the start of the
  // rise (its first 5 %, 4 to 40 rows), refined once around the intersection.
  double thick = b + 1.0;
  if (b - m < 8) {
    const Line tail = fitLine(p, std::max(a + 2, m - 12), std::max(a + 3, m - 2));
    const double inside = tail.slope * (b + 1.0) + tail.intercept;
    const double after = medianOf(p, b + 3, b + 12);
    thick = crossingNear(p, 0.5 * (inside + after), b, 10).value_or(b + 1.0);
  } else {
    double kink = m + 0.5;
    for (int pass = 0; pass < 2; ++pass) {
      const int k = static_cast<int>(kink);
      int rise_end = k + 2;
      while (rise_end < b && rise_end < k + 42 &&
             p[static_cast<size_t>(rise_end)] < lowest + 0.05 * (1.0 - lowest))
        ++rise_end;
      rise_end = std::max(rise_end, k + 6);
      const Line fall_line = fitLine(p, std::max(a + 3, k - 60), std::max(a + 4, k - 2));
      const Line rise_line = fitLine(p, k + 2, std::min(rise_end, n - 1));
      const double dslope = rise_line.slope - fall_line.slope;
      if (!(dslope > 0.0)) break;
      kink = std::clamp((fall_line.intercept - rise_line.intercept) / dslope, m - 8.0, m + 8.0);
    }
    thick = kink;
  }
  return {thin, thick};
}

}  // namespace

RampDetection detectRamp(const Image& normalized, const RampOptions& options,
                         const std::string& name) {
  if (normalized.width() < 8 || normalized.height() < 64)
    fail("{}: a {}x{} image is too small to hold a wedge's ramp", name, normalized.width(),
         normalized.height());
  for (float v : normalized.pixels())
    if (!std::isfinite(v)) fail("{}: the normalized image has a non-finite pixel", name);
  RampDetection out;
  bool thin_on_top = true;
  if (options.columns) {
    const auto [begin, end] = *options.columns;
    if (!(begin >= 0 && begin < end && end <= normalized.width()))
      fail("{}: ramp columns [{}, {}) lie outside the image's 0..{}", name, begin, end,
           normalized.width());
    out.column_begin = begin, out.column_end = end;
    out.automatic_columns = false;
  } else {
    int levels = 1;
    while ((normalized.width() >> (levels - 1)) > kCoarseWidth &&
           (normalized.height() >> levels) >= 32)
      ++levels;
    const std::vector<Image> pyramid = buildPyramid(normalized, levels);
    const Image& coarse = pyramid.back();
    const std::vector<double> contrast = columnContrast(coarse);
    size_t strongest = 0;
    for (size_t x = 0; x < contrast.size(); ++x)
      if (std::abs(contrast[x]) > std::abs(contrast[strongest])) strongest = x;
    const double peak = contrast[strongest];
    if (!(std::abs(peak) >= 0.1))
      fail(
          "{}: no ramp found: no column's shadow changes by more than 0.1 along it (largest "
          "change {:.4f})",
          name, std::abs(peak));
    thin_on_top = peak > 0.0;
    int first = static_cast<int>(strongest), last = static_cast<int>(strongest);
    auto strong = [&](int x) {
      return contrast[static_cast<size_t>(x)] * (thin_on_top ? 1 : -1) >= 0.5 * std::abs(peak);
    };
    while (first > 0 && strong(first - 1)) --first;
    while (last + 1 < coarse.width() && strong(last + 1)) ++last;
    const int shrink = static_cast<int>(kBandShrink * (last - first + 1));
    const int scale = normalized.width() / coarse.width();
    out.column_begin = (first + shrink) * scale;
    out.column_end = std::min(normalized.width(), (last + 1 - shrink) * scale);
    if (out.column_end <= out.column_begin) out.column_end = out.column_begin + 1;
  }

  // The profile: mean over the band of every row.
  out.profile.assign(static_cast<size_t>(normalized.height()), 0.0);
  for (int y = 0; y < normalized.height(); ++y) {
    double sum = 0.0;
    for (int x = out.column_begin; x < out.column_end; ++x)
      sum += static_cast<double>(normalized(x, y));
    out.profile[static_cast<size_t>(y)] = sum / (out.column_end - out.column_begin);
  }
  std::vector<double> second;
  for (size_t i = 1; i + 1 < out.profile.size(); ++i)
    second.push_back(std::abs(out.profile[i - 1] - 2.0 * out.profile[i] + out.profile[i + 1]));
  out.row_noise = 1.4826 * median(second) / std::sqrt(6.0);

  if (options.rows) {
    const auto [thin, thick] = *options.rows;
    const double h = normalized.height();
    if (!(thin >= 0.0 && thin <= h && thick >= 0.0 && thick <= h && std::abs(thick - thin) >= 10.0))
      fail("{}: ramp rows [{}, {}] must lie in the image's 0..{} and at least 10 rows apart", name,
           thin, thick, normalized.height());
    out.thin_row = thin, out.thick_row = thick;
    out.automatic_rows = false;
    return out;
  }
  // Orient so that the thin end is at the top; if the columns were given,
  // the side whose shadow starts brighter is the thin end.
  std::vector<double> oriented = out.profile;
  if (options.columns) {
    const int n = static_cast<int>(oriented.size());
    const double shadow = openLevel(brightestOf(oriented)) - 0.01;
    int first = 0, last = n - 1;
    while (first < n && oriented[static_cast<size_t>(first)] >= shadow) ++first;
    while (last > first && oriented[static_cast<size_t>(last)] >= shadow) --last;
    if (last - first < 20)
      fail("{}: no ramp found in columns [{}, {})", name, out.column_begin, out.column_end);
    thin_on_top = medianOf(oriented, first, first + (last - first) / 4) >=
                  medianOf(oriented, last - (last - first) / 4, last);
  }
  if (!thin_on_top) std::reverse(oriented.begin(), oriented.end());
  const auto rows = findRampRows(oriented, out.row_noise, name, thin_on_top ? "top" : "bottom",
                                 thin_on_top ? "bottom" : "top");
  const double h = normalized.height();
  out.thin_row = thin_on_top ? rows[0] : h - rows[0];
  out.thick_row = thin_on_top ? rows[1] : h - rows[1];
  return out;
}

}  // namespace xgauge
