#include "xgauge/image/scatter.h"

#include "xgauge/image/blur.h"
#include "xgauge/image/stats.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace xgauge {

const char* toString(HaloShape shape) {
  switch (shape) {
    case HaloShape::kGaussian:
      return "gaussian";
    case HaloShape::kGaussExp:
      return "gauss_exp";
    case HaloShape::kTwoGauss:
      return "two_gauss";
  }
  return "?";
}

const char* toString(HaloBorder border) { return border == HaloBorder::kOpen ? "open" : "mirror"; }

namespace {

HaloShape shapeFrom(const ConfigNode& node) {
  const std::string name = node.string();
  if (name == "gaussian") return HaloShape::kGaussian;
  if (name == "gauss_exp") return HaloShape::kGaussExp;
  if (name == "two_gauss") return HaloShape::kTwoGauss;
  node.fail("unknown halo shape '" + name + "' (gaussian, gauss_exp, two_gauss)");
}

HaloBorder borderFrom(const ConfigNode& node) {
  const std::string name = node.string();
  if (name == "mirror") return HaloBorder::kMirror;
  if (name == "open") return HaloBorder::kOpen;
  node.fail("unknown halo border '" + name + "' (mirror, open)");
}

// An optional uncertainty key, `fallback` when absent.
double uncertainty(const ConfigNode& node, const char* key, double fallback, double max) {
  if (auto u = node.find(key)) return u->number(0.0, max);
  return fallback;
}

// A two-width kernel's alternative of `shape`: its weight, widths and
// share, and the u it stands for.
HaloKernelEnd kernelFrom(const ConfigNode& node, HaloShape shape) {
  if (shape == HaloShape::kGaussian) node.fail("an alternative kernel has two widths");
  HaloKernelEnd k;
  k.shape = shape;
  k.weight = node.at("weight").number(0.0, 0.9);
  k.sigma_mm = node.at(shape == HaloShape::kTwoGauss ? "sigma1_mm" : "sigma_mm").number(0.01, 1e4);
  if (shape == HaloShape::kGaussExp) {
    k.tail_fraction = node.at("tail_fraction").number(0.0, 1.0);
    k.tail_length_mm = node.at("tail_length_mm").number(0.01, 1e4);
  } else {
    k.sigma2_mm = node.at("sigma2_mm").number(0.01, 1e4);
    k.fraction2 = node.at("fraction2").number(0.0, 1.0);
  }
  k.equivalent_sigma_uncertainty_mm = node.at("equivalent_sigma_uncertainty_mm").number(0.0, 1e4);
  return k;
}

nlohmann::json kernelJson(const HaloKernelEnd& k, bool with_shape) {
  const bool two = k.shape == HaloShape::kTwoGauss;
  nlohmann::json out = {{"weight", k.weight}, {two ? "sigma1_mm" : "sigma_mm", k.sigma_mm}};
  if (with_shape) out["shape"] = toString(k.shape);
  if (two)
    out["sigma2_mm"] = k.sigma2_mm, out["fraction2"] = k.fraction2;
  else
    out["tail_fraction"] = k.tail_fraction, out["tail_length_mm"] = k.tail_length_mm;
  out["equivalent_sigma_uncertainty_mm"] = k.equivalent_sigma_uncertainty_mm;
  return out;
}

}  // namespace

ScatterModel ScatterModel::fromConfig(const ConfigNode& node) {
  ScatterModel out;
  out.weight = node.at("weight").number(0.0, 0.9);
  if (auto shape = node.find("shape")) out.shape = shapeFrom(*shape);
  if (auto border = node.find("border")) out.border = borderFrom(*border);
  const char* sigma_key = out.shape == HaloShape::kTwoGauss ? "sigma1_mm" : "sigma_mm";
  out.sigma_mm = node.at(sigma_key).number(0.01, 1e4);
  // The defaults: 5 % of the weight and 10 % of a width, what a fit of the
  // halo around an edge typically leaves; fractions +- 0.05.
  out.weight_uncertainty = uncertainty(node, "weight_uncertainty", 0.05 * out.weight, 0.5);
  out.sigma_uncertainty_mm = uncertainty(node, "sigma_uncertainty_mm", 0.1 * out.sigma_mm, 1e4);
  if (out.shape == HaloShape::kGaussExp) {
    out.tail_fraction = node.at("tail_fraction").number(0.0, 1.0);
    out.tail_length_mm = node.at("tail_length_mm").number(0.01, 1e4);
    out.tail_fraction_uncertainty = uncertainty(node, "tail_fraction_uncertainty", 0.05, 1.0);
    out.tail_length_uncertainty_mm =
        uncertainty(node, "tail_length_uncertainty_mm", 0.1 * out.tail_length_mm, 1e4);
  } else if (out.shape == HaloShape::kTwoGauss) {
    out.sigma2_mm = node.at("sigma2_mm").number(0.01, 1e4);
    out.fraction2 = node.at("fraction2").number(0.0, 1.0);
    out.sigma2_uncertainty_mm =
        uncertainty(node, "sigma2_uncertainty_mm", 0.1 * out.sigma2_mm, 1e4);
    out.fraction2_uncertainty = uncertainty(node, "fraction2_uncertainty", 0.05, 1.0);
  }
  if (out.shape != HaloShape::kGaussian) {
    if (auto end = node.find("equivalent_end")) out.equivalent_end = kernelFrom(*end, out.shape);
    if (auto other = node.find("kernel_choice"))
      out.kernel_choice = kernelFrom(*other, shapeFrom(other->at("shape")));
  } else if (node.has("equivalent_end") || node.has("kernel_choice")) {
    node.fail(
        "a Gaussian kernel has no equivalent_end or kernel_choice (its width's u is "
        "sigma_uncertainty_mm)");
  }
  return out;
}

nlohmann::json ScatterModel::toJson() const {
  nlohmann::json out = {{"weight", weight}, {"weight_uncertainty", weight_uncertainty}};
  const bool two = shape == HaloShape::kTwoGauss;
  out[two ? "sigma1_mm" : "sigma_mm"] = sigma_mm;
  out["sigma_uncertainty_mm"] = sigma_uncertainty_mm;
  if (isMirroredGaussian()) return out;  // the four keys it always wrote
  out["shape"] = toString(shape);
  out["border"] = toString(border);
  if (shape == HaloShape::kGaussExp) {
    out["tail_fraction"] = tail_fraction;
    out["tail_length_mm"] = tail_length_mm;
    out["tail_fraction_uncertainty"] = tail_fraction_uncertainty;
    out["tail_length_uncertainty_mm"] = tail_length_uncertainty_mm;
  } else if (two) {
    out["sigma2_mm"] = sigma2_mm;
    out["fraction2"] = fraction2;
    out["sigma2_uncertainty_mm"] = sigma2_uncertainty_mm;
    out["fraction2_uncertainty"] = fraction2_uncertainty;
  }
  if (equivalent_end) out["equivalent_end"] = kernelJson(*equivalent_end, false);
  if (kernel_choice) out["kernel_choice"] = kernelJson(*kernel_choice, true);
  return out;
}

std::vector<GaussianTerm> ScatterModel::components() const {
  switch (shape) {
    case HaloShape::kGaussian:
      return {{1.0, sigma_mm}};
    case HaloShape::kTwoGauss:
      return {{1.0 - fraction2, sigma_mm}, {fraction2, sigma2_mm}};
    case HaloShape::kGaussExp: {
      std::vector<GaussianTerm> out{{1.0 - tail_fraction, sigma_mm}};
      double sum = 0.0;
      for (const GaussianTerm& t : kExponentialTailMixture) sum += t.fraction;
      for (const GaussianTerm& t : kExponentialTailMixture)
        out.push_back({tail_fraction * t.fraction / sum, t.sigma * tail_length_mm});
      return out;
    }
  }
  return {};
}

double ScatterModel::equivalentSigmaMm() const {
  // E[r^2] of a 2-D Gaussian is 2 sigma^2, of the exponential 6 lambda^2:
  // closed forms, not the mixture's.
  switch (shape) {
    case HaloShape::kGaussian:
      return sigma_mm;
    case HaloShape::kTwoGauss:
      return std::sqrt((1.0 - fraction2) * sigma_mm * sigma_mm + fraction2 * sigma2_mm * sigma2_mm);
    case HaloShape::kGaussExp:
      return std::sqrt((1.0 - tail_fraction) * sigma_mm * sigma_mm +
                       3.0 * tail_fraction * tail_length_mm * tail_length_mm);
  }
  return sigma_mm;
}

bool ScatterModel::sameKernel(const ScatterModel& other) const {
  auto same = [](double a, double b) {
    return std::abs(a - b) <= 1e-9 * std::max({std::abs(a), std::abs(b), 1e-12});
  };
  return shape == other.shape && border == other.border && same(weight, other.weight) &&
         same(sigma_mm, other.sigma_mm) && same(sigma2_mm, other.sigma2_mm) &&
         same(fraction2, other.fraction2) && same(tail_fraction, other.tail_fraction) &&
         same(tail_length_mm, other.tail_length_mm);
}

ScatterModel ScatterModel::as(const HaloKernelEnd& k) const {
  ScatterModel out = *this;
  out.shape = k.shape;
  out.weight = k.weight, out.sigma_mm = k.sigma_mm;
  out.tail_fraction = k.tail_fraction, out.tail_length_mm = k.tail_length_mm;
  out.sigma2_mm = k.sigma2_mm, out.fraction2 = k.fraction2;
  out.equivalent_end.reset(), out.kernel_choice.reset();
  return out;
}

std::vector<HaloAlternative> ScatterModel::alternatives() const {
  std::vector<HaloAlternative> out;
  for (const bool end : {true, false}) {
    const std::optional<HaloKernelEnd>& kernel = end ? equivalent_end : kernel_choice;
    if (!kernel) continue;
    HaloAlternative a{end ? "scatter kernel" : "scatter kernel choice", end, as(*kernel),
                  kernel->equivalent_sigma_uncertainty_mm, 0.0};
    const double reach = a.kernel.equivalentSigmaMm() - equivalentSigmaMm();
    if (!(a.u > 0.0) || !(std::abs(reach) > 0.0)) continue;
    a.scale = a.u / reach;
    out.push_back(std::move(a));
  }
  return out;
}

namespace {

// total += f * blurred (total empty: f * blurred): one Gaussian component of
// a kernel's blur added to the others'.
void addWeighted(Image& total, Image blurred, float f) {
  if (total.empty()) {
    for (float& value : blurred.pixels()) value *= f;
    total = std::move(blurred);
    return;
  }
  auto t = total.pixels();
  const auto b = blurred.pixels();
  for (size_t i = 0; i < t.size(); ++i) t[i] += f * b[i];
}

}  // namespace

Image ScatterModel::spread(Image image, double pitch_mm, float outside) const {
  const bool open = border == HaloBorder::kOpen;
  const BlurBorder blur_border = open ? BlurBorder::kZero : BlurBorder::kMirror;
  if (open)
    for (float& value : image.pixels()) value -= outside;
  Image total;
  for (const GaussianTerm& term : components()) {
    if (term.fraction <= 0.0) continue;
    Image blurred = gaussianBlur(image, term.sigma / pitch_mm, blur_border);
    addWeighted(total, std::move(blurred), static_cast<float>(term.fraction));
  }
  if (open)
    for (float& value : total.pixels()) value += outside;
  return total;
}

Image ScatterModel::spreadAround(const Image& image, double pitch_mm, float outside,
                                 double sigma_shrink_px2) const {
  const BlurBorder blur_border =
      border == HaloBorder::kOpen ? BlurBorder::kZero : BlurBorder::kMirror;
  Image total;
  for (const GaussianTerm& term : components()) {
    if (term.fraction <= 0.0) continue;
    const double sigma = term.sigma / pitch_mm;
    Image blurred = gaussianBlurAround(
        image, std::sqrt(std::max(sigma * sigma - sigma_shrink_px2, 0.25 * sigma * sigma)), outside,
        blur_border);
    if (term.fraction == 1.0) return blurred;  // a single Gaussian: as it always was
    addWeighted(total, std::move(blurred), static_cast<float>(term.fraction));
  }
  return total;
}

HaloField ScatterModel::haloField(const OpenBeamField& field, int width, int height,
                                  double pitch_mm, double scale) const {
  HaloField out;
  if (field.uniform()) return out;
  out.open = field.sampled(width, height, scale);
  for (const GaussianTerm& term : components()) {
    if (term.fraction <= 0.0) continue;
    Image halo = border == HaloBorder::kOpen
                     ? field.blurredOverThePlane(width, height, scale, term.sigma)
                     : gaussianBlur(out.open, term.sigma / pitch_mm, BlurBorder::kMirror);
    addWeighted(out.open_halo, std::move(halo), static_cast<float>(term.fraction));
  }
  out.flat = Image(width, height);
  const auto o = out.open.pixels(), k = out.open_halo.pixels();
  auto f = out.flat.pixels();
  for (size_t i = 0; i < f.size(); ++i)
    f[i] = static_cast<float>(mix(1.0, static_cast<double>(k[i]) / static_cast<double>(o[i])));
  return out;
}

namespace {

// (I - outside) O: what the halo spreads besides the open beam's own.
Image timesField(const Image& image, float outside, const HaloField& field) {
  Image out = image;
  auto v = out.pixels();
  const auto o = field.open.pixels();
  for (size_t i = 0; i < v.size(); ++i) v[i] = (v[i] - outside) * o[i];
  return out;
}

// (total + outside K * O) / O, in place.
void intoField(Image& total, float outside, const HaloField& field) {
  auto t = total.pixels();
  const auto o = field.open.pixels(), k = field.open_halo.pixels();
  for (size_t i = 0; i < t.size(); ++i) t[i] = (t[i] + outside * k[i]) / o[i];
}

// The halo of `image` in the open beam's field, (K * ((I - outside) O) +
// outside K * O) / O, each of the kernel's Gaussian terms by `blur`.
template <typename Blur>
Image spreadInField(const Image& image, float outside, const HaloField& field,
                    const std::vector<GaussianTerm>& terms, HaloBorder border, const Blur& blur) {
  const BlurBorder blur_border =
      border == HaloBorder::kOpen ? BlurBorder::kZero : BlurBorder::kMirror;
  const Image shifted = timesField(image, outside, field);
  Image total;
  for (const GaussianTerm& term : terms)
    if (term.fraction > 0.0)
      addWeighted(total, blur(shifted, term.sigma, blur_border), static_cast<float>(term.fraction));
  intoField(total, outside, field);
  return total;
}

}  // namespace

Image ScatterModel::spreadIn(const Image& image, double pitch_mm, float outside,
                             const HaloField& field) const {
  if (field.uniform()) return spread(image, pitch_mm, outside);
  return spreadInField(image, outside, field, components(), border,
                       [&](const Image& shifted, double term_sigma_mm, BlurBorder blur_border) {
                         return gaussianBlur(shifted, term_sigma_mm / pitch_mm, blur_border);
                       });
}

Image ScatterModel::spreadAroundIn(const Image& image, double pitch_mm, float outside,
                                   const HaloField& field, double sigma_shrink_px2) const {
  if (field.uniform()) return spreadAround(image, pitch_mm, outside, sigma_shrink_px2);
  return spreadInField(
      image, outside, field, components(), border,
      [&](const Image& shifted, double term_sigma_mm, BlurBorder blur_border) {
        const double sigma = term_sigma_mm / pitch_mm;
        return gaussianBlurAround(
            shifted, std::sqrt(std::max(sigma * sigma - sigma_shrink_px2, 0.25 * sigma * sigma)),
            0.0f, blur_border);
      });
}

Image ScatterModel::apply(Image image, double pitch_mm, float outside) const {
  if (isMirroredGaussian()) return scatterBlur(std::move(image), weight, sigmaPx(pitch_mm));
  if (!(weight >= 0.0 && weight <= 1.0)) fail("scatter weight must be in [0, 1], got {}", weight);
  if (weight == 0.0 || image.empty()) return image;
  const Image spreaded = spread(image, pitch_mm, outside);
  auto out = image.pixels();
  const auto g = spreaded.pixels();
  for (size_t i = 0; i < out.size(); ++i)
    out[i] = static_cast<float>(mix(static_cast<double>(out[i]), static_cast<double>(g[i])));
  return image;
}

Image ScatterModel::remove(const Image& normalized, double pitch_mm, const PixelRect& white,
                           int iterations) const {
  if (!(weight >= 0.0 && weight <= 0.9)) fail("scatter weight must be in [0, 0.9], got {}", weight);
  if (white.empty() || !normalized.rect().contains(white))
    fail("white region {} lies outside the {}x{} image", toString(white), normalized.width(),
         normalized.height());
  Image estimate = normalized;
  if (weight == 0.0) return estimate;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    // The estimate is a transmission: the open beam beyond the panel is 1.
    const Image spreaded = isMirroredGaussian() ? gaussianBlur(estimate, sigmaPx(pitch_mm))
                                                : spread(estimate, pitch_mm, 1.0f);
    const double open = mix(1.0, meanOf(spreaded, white));
    const auto n = normalized.pixels();
    const auto g = spreaded.pixels();
    auto out = estimate.pixels();
    for (size_t i = 0; i < out.size(); ++i)
      out[i] = static_cast<float>(
          unmix(static_cast<double>(n[i]), static_cast<double>(g[i]), open));
  }
  return estimate;
}

Image ScatterModel::remove(const Image& normalized, double pitch_mm, const PixelRect& white,
                           const OpenBeamField& field, int iterations) const {
  if (field.uniform() || weight == 0.0) return remove(normalized, pitch_mm, white, iterations);
  if (!(weight >= 0.0 && weight <= 0.9)) fail("scatter weight must be in [0, 0.9], got {}", weight);
  if (white.empty() || !normalized.rect().contains(white))
    fail("white region {} lies outside the {}x{} image", toString(white), normalized.width(),
         normalized.height());
  const HaloField halo_field = haloField(field, normalized.width(), normalized.height(), pitch_mm);
  const auto f = halo_field.flat.pixels();
  Image estimate = normalized;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const Image spreaded = spreadIn(estimate, pitch_mm, 1.0f, halo_field);
    const auto g = spreaded.pixels();
    // The white region's level: the open beam (I = 1) with the halo there.
    double open = 0.0;
    for (int y = white.y; y < white.bottom(); ++y)
      for (int x = white.x; x < white.right(); ++x) {
        const auto i = static_cast<size_t>(y) * static_cast<size_t>(normalized.width()) +
                       static_cast<size_t>(x);
        open += mix(1.0, static_cast<double>(g[i])) / static_cast<double>(f[i]);
      }
    open /= static_cast<double>(white.area());
    const auto n = normalized.pixels();
    auto out = estimate.pixels();
    for (size_t i = 0; i < out.size(); ++i)
      out[i] = static_cast<float>(unmix(static_cast<double>(n[i]), static_cast<double>(g[i]),
                                        open * static_cast<double>(f[i])));
  }
  return estimate;
}

}  // namespace xgauge
