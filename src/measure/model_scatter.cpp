// The forward model's scintillator scatter (model.h, job "scatter"): the halo
// G(I) of a coarse render of the whole detector, added to the simulated
// radiograph with the measured image's white-region normalization, and the
// same halo of the render's derivative images for the Jacobian.
#include "xgauge/measure/model.h"

#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/renderer.h"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace xgauge {

ScatterEstimate::Tap ScatterEstimate::tap(double u_level, double v_level) const {
  // Bilinear in coarse pixel-centre units.
  const double u = u_level * ratio - 0.5, v = v_level * ratio - 0.5;
  const double x = std::clamp(u, 0.0, blurred.width() - 1.0);
  const double y = std::clamp(v, 0.0, blurred.height() - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  return {
      x0,     y0,    std::min(x0 + 1, blurred.width() - 1), std::min(y0 + 1, blurred.height() - 1),
      x - x0, y - y0};
}

RenderOptions ForwardModel::scatterRenderOptions() const {
  // The coarse render's pixels must be the area means of the fine image, as
  // the scintillator blurs it: sampled at their centres only, an edge's share
  // of the halo moves by up to half a coarse pixel, by a different amount at
  // each position of the part (a transmission error of several 1e-4 per
  // shot). The edges sampled 8 x 8 leave 1/16 of a coarse pixel; inside the
  // path is smooth and one sample per pixel does (measure_test: within 1e-6
  // of the exact blur, as with 4 x 4 and 16 x 16, at a fifth of the cost).
  // That is for the stages whose own edges are refined (setEdgeSamples: the
  // final stage, the budget, the self-checks). Before them the image's own
  // edge pixels are point samples, whose error dwarfs a quarter of a coarse
  // pixel's, and the edges take 2 x 2: at the pose searches' 256 px, where
  // the coarse render refines nearly every pixel of the part, 8 x 8 made
  // the scatter cost nine times the image it is added to.
  RenderOptions options;
  options.samples_per_axis = 1;
  options.edge_samples_per_axis = edge_samples_ > 0 ? 8 : 2;
  return options;
}

ScatterEstimate ForwardModel::scatter(std::span<const double> theta, int radiograph, int level) {
  XG_CHECK(job().scatter.enabled(), "the job models no scatter");
  useMaterialOf(theta);
  return scatterOf(posedMesh(theta, radiograph), radiograph, level);
}

ScatterEstimate ForwardModel::scatterOf(const WorldMesh& mesh, int radiograph, int level) {
  // The kernel is hundreds of pixels wide: a coarse render of the whole
  // detector carries all of G(I).
  const int coarse_level = scatterLevel(level);
  renderIntensity(machineAt(coarse_level), mesh, transmission_, scatterRenderOptions(), coarse_);
  return spreadOf(coarse_, coarse_level, radiograph, level, false);
}

std::shared_ptr<const HaloField> ForwardModel::haloFieldOf(int radiograph, int coarse_level,
                                                           int width, int height,
                                                           double pitch_mm) const {
  const std::lock_guard lock(halo_fields_->mutex);
  HaloFields::Made& made = halo_fields_->fields[{radiograph, coarse_level}];
  // A detector pose that moves changes neither the coarse grid nor its
  // pitch; made again should either ever differ.
  if (!made.field || made.width != width || made.height != height || made.pitch_mm != pitch_mm)
    made = {
        width, height, pitch_mm,
        std::make_shared<const HaloField>(job().scatter.haloField(
            this->radiograph(radiograph).open_beam, width, height, pitch_mm, 1 << coarse_level))};
  return made.field;
}

ScatterEstimate ForwardModel::spreadOf(const Image& coarse, int coarse_level, int radiograph,
                                       int level, bool derivative) const {
  ScatterEstimate out;
  // The coarse pixels' area (a box of 1/12 coarse pixel^2 of variance) and
  // the bilinear interpolation back (1/6) widen the kernel: taken off here,
  // as blur.cpp's reduced blur does.
  // Outside the part's shadow the render is the open beam (1) and a
  // derivative image 0: only the shadow's rows and columns are summed. With
  // an open border the world beyond the panel is that level too.
  // In the open beam's field (decision 0041) the halo is K * (I O) / O, a
  // derivative's K * (dI O) / O.
  const ScatterModel& scatter = job().scatter;
  const double coarse_pitch = machineAt(coarse_level).pitch_u_mm;
  const std::shared_ptr<const HaloField> field =
      haloFieldOf(radiograph, coarse_level, coarse.width(), coarse.height(), coarse_pitch);
  out.blurred =
      scatter.spreadAroundIn(coarse, coarse_pitch, derivative ? 0.0f : 1.0f, *field, 0.25);
  out.flat = field->flat;
  // The model's open-beam level in the white region (full-size coordinates).
  const PixelRect white = spec(radiograph).white_region;
  const double full_to_coarse = 1.0 / static_cast<double>(1 << coarse_level);
  // at() maps pixels of a level to the coarse one: first full-size pixels,
  // for the white region, then the level asked for.
  out.ratio = full_to_coarse;
  double white_sum = 0.0;
  constexpr int kGrid = 8;
  const double w = scatter.weight;
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      const ScatterEstimate::Tap t = out.tap(white.x + (i + 0.5) * white.width / kGrid,
                                             white.y + (j + 0.5) * white.height / kGrid);
      white_sum += out.flat.empty()
                       ? out.at(t)
                       : ((derivative ? 0.0 : 1.0 - w) + w * out.at(t)) / out.flatAt(t);
    }
  out.open = out.flat.empty() ? (derivative ? 0.0 : 1.0 - w) + w * white_sum / (kGrid * kGrid)
                              : white_sum / (kGrid * kGrid);
  out.ratio = static_cast<double>(1 << level) / static_cast<double>(1 << coarse_level);
  return out;
}

void ForwardModel::addScatter(const WorldMesh& mesh, int radiograph, int level,
                              const PixelRect& region, Image& image) {
  // The scintillator scatter, with the same white-region normalization as the
  // measured image.
  const ScatterModel& scatter = job().scatter;
  const ScatterEstimate spread = scatterOf(mesh, radiograph, level);
  tbb::parallel_for(0, image.height(), [&](int y) {
    for (int x = 0; x < image.width(); ++x)
      image(x, y) = spread.simulated(scatter, static_cast<double>(image(x, y)), region.x + x + 0.5,
                                     region.y + y + 0.5);
  });
}

ScatterEstimate ForwardModel::scatterWithRates(const WorldMesh& mesh, int radiograph, int level,
                                               std::span<const Vec3> velocities, int count,
                                               std::vector<ScatterEstimate>& rates) {
  const int coarse_level = scatterLevel(level);
  IntensityDerivatives coarse;
  // Point samples alone: refined, these rates made the 512 px joint stage
  // of a 4096^2 Prism A pair take 16 iterations instead of 5 for the same
  // loss, at a higher cost each.
  RenderOptions coarse_options = scatterRenderOptions();
  coarse_options.edge_samples_per_axis = 0;
  renderIntensityDerivatives(machineAt(coarse_level), mesh, transmission_, coarse_options,
                             velocities, count, coarse);
  // The value from the render whose edges are refined (scatterOf), as
  // residuals() has it: the render with derivatives samples each pixel
  // once, which is the per-shot error scatterRenderOptions() removes.
  ScatterEstimate spread = scatterOf(mesh, radiograph, level);
  rates.clear();
  for (const Image& rate : coarse.per_parameter) {
    rates.push_back(spreadOf(rate, coarse_level, radiograph, level, true));
    // The image's interpolation taps serve every rate's (model_derivatives.cpp).
    XG_CHECK(rates.back().blurred.width() == spread.blurred.width() &&
                 rates.back().blurred.height() == spread.blurred.height() &&
                 rates.back().ratio == spread.ratio,
             "a derivative's scatter estimate on another grid than the image's");
  }
  return spread;
}

}  // namespace xgauge
