#include "checks.h"

#include "xgauge/image/stats.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace xgauge {

namespace {

// A refined rate scale beyond this many of its prior's standard
// uncertainties is warned about (a 3-sigma event of a correct calibration).
constexpr double kRefinementWarnPriors = 3.0;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// The magnification of the part's reference centre in radiograph r (the
// detector at z = 0, the source at z = source-detector distance).
double magnificationOf(const ForwardModel& model, std::span<const double> theta, int r) {
  const double d = model.machine().source_detector_distance_mm;
  const Vec3 centre = model.pose(theta, r).apply(model.referenceCentre());
  return d / std::max(1e-6, d - centre.z());
}

// The pixels of a path image that lie on the shadow (path > 0) or within
// `margin_px` of it (Chebyshev distance: a square dilation by separable
// running maxima, which a margin of a few pixels does not need to be round).
std::vector<uint8_t> nearShadow(const Image& paths, double margin_px) {
  const int w = paths.width(), h = paths.height();
  const int m = std::max(0, static_cast<int>(std::ceil(margin_px)));
  std::vector<uint8_t> on(static_cast<size_t>(w) * static_cast<size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) on[static_cast<size_t>(y * w + x)] = paths(x, y) > 0.0f;
  std::vector<uint8_t> rows(on.size());
  for (int y = 0; y < h; ++y) {
    int last = -1 - m;  // the last shadow pixel at or left of x
    for (int x = 0; x < w; ++x) {
      if (on[static_cast<size_t>(y * w + x)]) last = x;
      rows[static_cast<size_t>(y * w + x)] = x - last <= m;
    }
    last = w + m;  // the last shadow pixel at or right of x
    for (int x = w - 1; x >= 0; --x) {
      if (on[static_cast<size_t>(y * w + x)]) last = x;
      rows[static_cast<size_t>(y * w + x)] |= last - x <= m;
    }
  }
  std::vector<uint8_t> out(on.size());
  for (int x = 0; x < w; ++x) {
    int last = -1 - m;
    for (int y = 0; y < h; ++y) {
      if (rows[static_cast<size_t>(y * w + x)]) last = y;
      out[static_cast<size_t>(y * w + x)] = y - last <= m;
    }
    last = h + m;
    for (int y = h - 1; y >= 0; --y) {
      if (rows[static_cast<size_t>(y * w + x)]) last = y;
      out[static_cast<size_t>(y * w + x)] |= last - y <= m;
    }
  }
  return out;
}

// Where the ray from the source to a detector point passes through the
// fitted part: the middle of its first entry and last exit, in part
// coordinates (Moeller-Trumbore on every triangle: a part has thousands).
std::optional<Vec3> middleOfPath(const TriangleMesh& mesh, const Pose& pose, const Vec3& source,
                                 const Vec3& target) {
  const Mat3 back = pose.rotation.transpose();
  const Vec3 o = back * (source - pose.translation_mm);
  const Vec3 dir = back * (target - source);
  double first = std::numeric_limits<double>::infinity(), last = -first;
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3 e1 = mesh.vertices[t[1]] - a, e2 = mesh.vertices[t[2]] - a;
    const Vec3 p = dir.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) continue;
    const Vec3 s = o - a;
    const double u = s.dot(p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const Vec3 q = s.cross(e1);
    const double v = dir.dot(q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double h = e2.dot(q) / det;
    first = std::min(first, h), last = std::max(last, h);
  }
  if (!(last > first)) return std::nullopt;
  return o + 0.5 * (first + last) * dir;
}

// Parameters at a bound: the true value may lie beyond it, and the fit's
// minimum is not one (a pose in a wrong basin often ends at a bound).
void checkBounds(const ForwardModel& model, std::span<const double> theta,
                 const AcceptanceRule& rule, SelfCheck& check) {
  const ParameterLayout& layout = model.parameters();
  std::vector<std::string>& at_bound = rule.fail_at_bound ? check.failures : check.warnings;
  for (int i : model.leastSquaresIndices()) {
    const auto k = static_cast<size_t>(i);
    const double lo = model.lower()[k], hi = model.upper()[k], range = hi - lo;
    if (!(range > 0.0)) continue;
    const std::string& full = layout[i].name;  // "dim/width", "t00/position/x"
    const std::string name = full.rfind("dim/", 0) == 0 ? full.substr(4) : full;
    if (theta[k] - lo <= 1e-4 * range)
      at_bound.push_back(
          fmt::format("{} = {:.4f} is at its lower bound {:.4f}: the true "
                      "value may lie below it; widen the bounds",
                      name, theta[k], lo));
    if (hi - theta[k] <= 1e-4 * range)
      at_bound.push_back(
          fmt::format("{} = {:.4f} is at its upper bound {:.4f}: the true "
                      "value may lie above it; widen the bounds",
                      name, theta[k], hi));
  }
}

// A refinement that moves the curve far beyond what its calibration
// stated: the calibration does not hold here (another set-up, another
// alloy), or the part's model misses something the curve now hides.
void checkRefinement(const ForwardModel& model, std::span<const double> theta, SelfCheck& check) {
  if (const int i = model.rateScaleIndex(); i >= 0) {
    const double e = theta[static_cast<size_t>(i)], u = model.rateScalePrior();
    if (std::abs(e) > kRefinementWarnPriors * u)
      check.warnings.push_back(fmt::format(
          "the material refined in situ: its rates moved by {:+.2f} %, {:.1f} times the "
          "calibration's stated uncertainty ({:.2f} %): the calibration may not hold for this "
          "set-up or material, or the part differs from its model where the curve now hides it",
          100.0 * e, std::abs(e) / u, 100.0 * u));
  }
}

// The residual image of one radiograph's roi, unscaled, with the sums of
// its absolute values and squares.
struct ResidualImage {
  Image image;
  double sum_abs = 0.0, sum_squares = 0.0;
};

ResidualImage residualImage(const LinearizedFit& fit, const ResidualSegment& segment) {
  const PixelRect roi = segment.roi;
  const double unscale = std::sqrt(static_cast<double>(roi.area()));
  ResidualImage out;
  out.image = Image(roi.width, roi.height);
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const double v = unscale * fit.residuals(static_cast<Eigen::Index>(segment.first) +
                                               static_cast<Eigen::Index>(y) * roi.width + x);
      out.image(x, y) = static_cast<float>(v);
      out.sum_abs += std::abs(v), out.sum_squares += v * v;
    }
  return out;
}

// The residual of one radiograph against the noise of its open beam (the
// white region at the fit's level).
RadiographCheck misfitCheck(const ForwardModel& model, int level, const ResidualSegment& segment,
                            const ResidualImage& residual, const AcceptanceRule& rule,
                            SelfCheck& check) {
  const double scale = static_cast<double>(1 << level);
  const RadiographSpec& spec = model.spec(segment.radiograph);
  const Image& measured = model.radiograph(segment.radiograph).levels[static_cast<size_t>(level)];
  const PixelRect& white_full = spec.white_region;
  const PixelRect white{static_cast<int>(white_full.x / scale),
                        static_cast<int>(white_full.y / scale),
                        std::max(2, static_cast<int>(white_full.width / scale)),
                        std::max(1, static_cast<int>(white_full.height / scale))};
  const PixelRect roi = segment.roi;
  RadiographCheck rc;
  rc.name = spec.name;
  rc.noise_sigma = neighbourNoise(measured, white.intersect(measured.rect()));
  rc.mean_abs_residual = residual.sum_abs / static_cast<double>(roi.area());
  rc.rms_residual = std::sqrt(residual.sum_squares / static_cast<double>(roi.area()));
  rc.misfit_ratio = rc.noise_sigma > 0.0 ? rc.rms_residual / rc.noise_sigma : 0.0;
  if (rc.misfit_ratio > rule.max_misfit_ratio)
    check.failures.push_back(fmt::format(
        "{}: the fit leaves an rms residual of {:.3g} per pixel, {:.1f} times what the noise of "
        "its open beam explains ({:.3g}), above the {:.1f} times a measurement may leave: the "
        "pose may lie in a wrong minimum, or the part, the material, the scatter or the "
        "machine differ from their models",
        spec.name, rc.rms_residual, rc.misfit_ratio, rc.noise_sigma, rule.max_misfit_ratio));
  else if (rc.misfit_ratio > kMisfitRatio)
    check.warnings.push_back(fmt::format(
        "{}: the fit leaves an rms residual of {:.3g} per pixel, {:.1f} times what the noise "
        "of its open beam explains ({:.3g}): the part, the material, the scatter or the "
        "machine may differ from their models, or a dimension is held at a wrong value",
        spec.name, rc.rms_residual, rc.misfit_ratio, rc.noise_sigma));
  return rc;
}

// The paths through the fitted part over one radiograph's roi: its shadow's
// area, longest path and share of paths below the material's calibrated
// range into `rc`. Returns the pixels on or next to the shadow.
std::vector<uint8_t> checkPaths(ForwardModel& model, std::span<const double> theta, int level,
                                const ResidualSegment& segment,
                                const std::optional<std::array<double, 2>>& calibrated,
                                RadiographCheck& rc) {
  const int r = segment.radiograph;
  const PixelRect roi = segment.roi;
  const double scale = static_cast<double>(1 << level);
  const Machine& machine = model.machine();
  const Image paths = model.pathLengths(theta, r, level, roi);
  int64_t through = 0, short_paths = 0;
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const auto p = static_cast<double>(paths(x, y));
      rc.longest_path_mm = std::max(rc.longest_path_mm, p);
      if (p > 0.0) ++through, short_paths += calibrated && p < (*calibrated)[0];
    }
  rc.shadow_area_mm2 =
      static_cast<double>(through) * scale * scale * machine.pitch_u_mm * machine.pitch_v_mm;
  std::vector<uint8_t> near_part = nearShadow(
      paths, kRegionPartMarginMm * magnificationOf(model, theta, r) / (machine.pitch_u_mm * scale));
  rc.below_range_fraction =
      through > 0 ? static_cast<double>(short_paths) / static_cast<double>(through) : 0.0;
  return near_part;
}

// Paths beyond the material's calibrated range: one warning naming every
// radiograph that has them (and one for paths below it), so that a
// measurement says it once.
void checkCalibratedRange(const std::optional<std::array<double, 2>>& calibrated,
                          SelfCheck& check) {
  if (!calibrated) return;
  std::vector<std::string> beyond, below;
  for (const RadiographCheck& rc : check.radiographs) {
    if (rc.longest_path_mm > (*calibrated)[1] * (1.0 + kBeyondRange))
      beyond.push_back(fmt::format("{} {:.2f} mm", rc.name, rc.longest_path_mm));
    if (rc.below_range_fraction > kBelowRangeFraction)
      below.push_back(fmt::format("{} {:.0f} %", rc.name, 100.0 * rc.below_range_fraction));
  }
  if (!beyond.empty())
    check.warnings.push_back(fmt::format(
        "the part has paths beyond the {:.2f} mm the material was calibrated to (the longest: {}): "
        "the curve is extrapolated there; calibrate over longer paths",
        (*calibrated)[1], fmt::join(beyond, ", ")));
  if (!below.empty())
    check.warnings.push_back(fmt::format(
        "of the pixels that see the part, more than {:.0f} % have paths below the {:.2f} mm the "
        "material was calibrated from ({}): the curve is interpolated towards I(0) = 1 there; "
        "calibrate over shorter paths",
        100.0 * kBelowRangeFraction, (*calibrated)[0], fmt::join(below, ", ")));
}

// The mean of each pixel's 3 x 3 neighbourhood (within the image).
Image mean3x3(const Image& image) {
  const int w = image.width(), h = image.height();
  Image out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0.0;
      int count = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          s += static_cast<double>(image(xx, yy)), ++count;
        }
      out(x, y) = static_cast<float>(s / count);
    }
  return out;
}

// The pixels of one residual region, grown from its seed, and their sums.
struct GrownRegion {
  int count = 0, strong = 0, on_part = 0, xmin = 0, xmax = 0, ymin = 0, ymax = 0;
  double sw = 0.0, sx = 0.0, sy = 0.0, peak = 0.0;
};

// Labels `next` the region of `mean3` (sign times it above `grow`) that
// holds the seed (x0, y0).
GrownRegion growRegion(const Image& mean3, int x0, int y0, double sign, double threshold,
                       double grow, const std::vector<uint8_t>& near_part, int next,
                       std::vector<int>& label) {
  const int width = mean3.width(), height = mean3.height();
  std::vector<std::pair<int, int>> stack{{x0, y0}};
  label[static_cast<size_t>(y0 * width + x0)] = next;
  GrownRegion g;
  g.xmin = x0, g.xmax = x0, g.ymin = y0, g.ymax = y0;
  while (!stack.empty()) {
    const auto [x, y] = stack.back();
    stack.pop_back();
    const double v = sign * static_cast<double>(mean3(x, y));
    ++g.count, g.strong += v > threshold;
    g.on_part += near_part[static_cast<size_t>(y * width + x)];
    g.sw += v, g.sx += v * (x + 0.5), g.sy += v * (y + 0.5), g.peak = std::max(g.peak, v);
    g.xmin = std::min(g.xmin, x), g.xmax = std::max(g.xmax, x), g.ymin = std::min(g.ymin, y),
    g.ymax = std::max(g.ymax, y);
    // Grown through neighbours above the lower threshold
    // (hysteresis): a band of residuals along a wall, which breaks up
    // where the noise dips below the seed's threshold, is one region.
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
        int& l = label[static_cast<size_t>(yy * width + xx)];
        if (l || sign * static_cast<double>(mean3(xx, yy)) <= grow) continue;
        l = next;
        stack.emplace_back(xx, yy);
      }
  }
  return g;
}

// A grown region as reported: on the full-size detector, on the part's
// shadow, and where its ray passes through the fitted part.
ResidualRegion placeRegion(const ForwardModel& model, std::span<const double> theta,
                           const TriangleMesh& mesh, int level, const ResidualSegment& segment,
                           const GrownRegion& g, double sign, double sigma) {
  const double scale = static_cast<double>(1 << level);
  const Machine& machine = model.machine();
  const PixelRect roi = segment.roi;
  ResidualRegion region;
  region.radiograph = model.spec(segment.radiograph).name;
  region.centre_px = Vec2((roi.x + g.sx / g.sw) * scale, (roi.y + g.sy / g.sw) * scale);
  region.box_px = {static_cast<int>((roi.x + g.xmin) * scale),
                   static_cast<int>((roi.y + g.ymin) * scale),
                   static_cast<int>((g.xmax - g.xmin + 1) * scale),
                   static_cast<int>((g.ymax - g.ymin + 1) * scale)};
  const double pixel_mm2 = scale * scale * machine.pitch_u_mm * machine.pitch_v_mm;
  region.area_mm2 = g.count * pixel_mm2;
  region.part_area_mm2 = g.on_part * pixel_mm2;
  region.peak = g.peak;
  region.sigmas = g.peak / sigma;
  // simulated - measured > 0: the radiograph is darker than the model.
  region.sign = sign > 0 ? "darker" : "brighter";
  region.part_mm = middleOfPath(mesh, model.pose(theta, segment.radiograph), machine.sourceWorld(),
                                machine.detectorPoint(region.centre_px.x(), region.centre_px.y()));
  return region;
}

// Residual regions of one radiograph: where the smoothed residual stands
// out from its robust spread, seeded above kRegionSigmas and grown above
// kRegionGrowSigmas; `region_pixels` (optional) flags their pixels.
void findResidualRegions(const ForwardModel& model, std::span<const double> theta,
                         const TriangleMesh& mesh, int level, const ResidualSegment& segment,
                         const Image& residual, const std::vector<uint8_t>& near_part,
                         SelfCheck& check, std::vector<char>* region_pixels) {
  const PixelRect roi = segment.roi;
  const Image mean3 = mean3x3(residual);
  std::vector<double> magnitudes;
  magnitudes.reserve(static_cast<size_t>(roi.area()));
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x)
      magnitudes.push_back(std::abs(static_cast<double>(mean3(x, y))));
  const double sigma = 1.4826 * median(std::move(magnitudes));
  if (!(sigma > 0.0)) return;
  const double threshold = kRegionSigmas * sigma, grow = kRegionGrowSigmas * sigma;
  std::vector<int> label(static_cast<size_t>(roi.area()), 0);
  int next = 0;
  for (int y0 = 0; y0 < roi.height; ++y0)
    for (int x0 = 0; x0 < roi.width; ++x0) {
      const auto v0 = static_cast<double>(mean3(x0, y0));
      if (std::abs(v0) <= threshold || label[static_cast<size_t>(y0 * roi.width + x0)]) continue;
      const double sign = v0 > 0 ? 1.0 : -1.0;
      ++next;
      const GrownRegion g =
          growRegion(mean3, x0, y0, sign, threshold, grow, near_part, next, label);
      if (g.strong < kRegionMinPixels) continue;
      if (region_pixels)
        for (int y = g.ymin; y <= g.ymax; ++y)
          for (int x = g.xmin; x <= g.xmax; ++x)
            if (label[static_cast<size_t>(y * roi.width + x)] == next)
              (*region_pixels)[segment.first + static_cast<size_t>(y * roi.width + x)] = 1;
      check.regions.push_back(placeRegion(model, theta, mesh, level, segment, g, sign, sigma));
    }
}

// Regions that together cover much of the shadow: not a defect of the
// part but a fit that does not explain the radiographs.
void checkRegionShare(const AcceptanceRule& rule, SelfCheck& check) {
  double region_area = 0.0, shadow_area = 0.0;
  for (const ResidualRegion& region : check.regions) region_area += region.part_area_mm2;
  for (const RadiographCheck& rc : check.radiographs) shadow_area += rc.shadow_area_mm2;
  check.region_share = shadow_area > 0.0 ? region_area / shadow_area : 0.0;
  if (check.region_share > rule.max_region_share)
    check.failures.push_back(fmt::format(
        "residual regions cover {:.1f} mm^2 on or next to the part's shadows, {:.1f} % of them "
        "({:.1f} mm^2), above "
        "the {:.1f} % a measurement may leave: the part differs from its model over much of it, "
        "or the fit is in a wrong minimum",
        region_area, 100.0 * check.region_share, shadow_area, 100.0 * rule.max_region_share));
}

// A region as a warning's words: where it is and how strong.
std::string describeRegion(const ResidualRegion& region) {
  return fmt::format(
      "{} at pixel ({:.0f}, {:.0f}), {:.2f} mm^2 on the detector{}, {:.1f} sigmas, {} than the "
      "model{}",
      region.radiograph, region.centre_px.x(), region.centre_px.y(), region.area_mm2,
      region.part_area_mm2 > 0.0
          ? fmt::format(" ({:.2f} mm^2 on or next to the part's shadow)", region.part_area_mm2)
          : std::string(" in the open beam (a detector effect the model leaves out)"),
      region.sigmas, region.sign,
      region.part_mm ? fmt::format(" (part coordinates ({:.2f}, {:.2f}, {:.2f}) mm)",
                                   region.part_mm->x(), region.part_mm->y(), region.part_mm->z())
                     : std::string());
}

// The regions, strongest first; one warning for those of kRegionWarnSigmas
// or more (the rest are in the result and the report, not warned about:
// parts that match their model show them too).
void warnRegions(SelfCheck& check) {
  std::sort(check.regions.begin(), check.regions.end(),
            [](const ResidualRegion& a, const ResidualRegion& b) { return a.sigmas > b.sigmas; });
  // Sorted, the strong ones come first: the three strongest are named.
  const auto strong = static_cast<size_t>(
      std::count_if(check.regions.begin(), check.regions.end(),
                    [](const ResidualRegion& r) { return r.sigmas >= kRegionWarnSigmas; }));
  if (strong == 0) return;
  constexpr size_t kNamed = 3;
  std::vector<std::string> named;
  for (size_t i = 0; i < std::min(kNamed, strong); ++i)
    named.push_back(describeRegion(check.regions[i]));
  std::string text = fmt::format(
      "{} residual region(s) of {:.0f} sigmas or more, where the part may differ from its model "
      "(a void, a chip, a burr, a feature the model lacks): {}",
      strong, kRegionWarnSigmas, fmt::join(named, "; "));
  if (strong > kNamed) text += fmt::format("; and {} more", strong - kNamed);
  check.warnings.push_back(std::move(text));
}

// One radiograph much worse than the others.
void checkWorseRadiograph(SelfCheck& check) {
  if (check.radiographs.size() < 2) return;
  for (const RadiographCheck& rc : check.radiographs) {
    std::vector<double> others;
    for (const RadiographCheck& o : check.radiographs)
      if (&o != &rc) others.push_back(o.mean_abs_residual);
    const double typical = median(others);
    if (typical > 0.0 && rc.mean_abs_residual > kWorseRatio * typical)
      check.warnings.push_back(fmt::format(
          "{}: its fit is {:.1f} times worse than the other radiographs' (mean |residual| "
          "{:.3g} against {:.3g}): check that shot",
          rc.name, rc.mean_abs_residual / typical, rc.mean_abs_residual, typical));
  }
}

}  // namespace

SelfCheck checkMeasurement(ForwardModel& model, std::span<const double> theta,
                           const LinearizedFit& fit, const AcceptanceRule& rule,
                           std::vector<char>* region_pixels) {
  SelfCheck check;
  if (region_pixels) region_pixels->assign(static_cast<size_t>(fit.residuals.size()), 0);
  checkBounds(model, theta, rule, check);
  checkRefinement(model, theta, check);
  // Per radiograph: the residual against the noise, the paths against the
  // material's calibrated range, and residual regions.
  const TriangleMesh mesh = model.part().mesh(theta.first(model.part().dimensions().size()));
  const std::optional<std::array<double, 2>> calibrated = model.materialOf(theta).calibratedRange();
  for (const ResidualSegment& segment : fit.segments) {
    const ResidualImage residual = residualImage(fit, segment);
    RadiographCheck rc = misfitCheck(model, fit.level, segment, residual, rule, check);
    const std::vector<uint8_t> near_part =
        checkPaths(model, theta, fit.level, segment, calibrated, rc);
    check.radiographs.push_back(rc);
    findResidualRegions(model, theta, mesh, fit.level, segment, residual.image, near_part, check,
                        region_pixels);
  }
  checkCalibratedRange(calibrated, check);
  checkRegionShare(rule, check);
  warnRegions(check);
  checkWorseRadiograph(check);
  return check;
}

double SelfCheck::worstMisfitRatio() const {
  double worst = 0.0;
  for (const RadiographCheck& rc : radiographs) worst = std::max(worst, rc.misfit_ratio);
  return worst;
}

std::string discrepancyReason(const DimensionUncertainty& u, double coverage_factor,
                              const Tolerance& tolerance, const SelfCheck& check) {
  double discrepancy = 0.0;
  for (const UncertaintyComponent& c : u.components)
    if (c.name == "misfit") discrepancy = c.contribution;
  if (discrepancy <= 0.0 || check.regions.empty()) return {};
  const double without =
      coverage_factor * std::sqrt(std::max(0.0, u.combined * u.combined - discrepancy * discrepancy));
  if (without > tolerance.width() / 3.0) return {};
  std::vector<std::string> named;
  for (const ResidualRegion& r : check.regions) {
    if (named.size() == 3) break;
    named.push_back(fmt::format("{} at pixel ({:.0f}, {:.0f}), {:.0f} sigmas {}", r.radiograph,
                                r.centre_px.x(), r.centre_px.y(), r.sigmas, r.sign));
  }
  const size_t more = check.regions.size() - named.size();
  return fmt::format(
      "the model discrepancy: its component \"misfit\" ({:.4f}) makes U {:.4f} where it would "
      "be {:.4f} without; the part differs from its model at the residual region(s) {}{}",
      discrepancy, u.expanded, without, fmt::join(named, "; "),
      more ? fmt::format(" and {} more", more) : std::string());
}

}  // namespace xgauge
