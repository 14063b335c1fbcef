// The front door's radiographs (xgauge/radiographs.h): conversion,
// normalization, rendering and the derivatives' check over the image, xray
// and material modules. `xgauge convert`, `normalize`, `render` and
// `check-gradients` are these calls and a print.
#include "xgauge/radiographs.h"

#include "guard.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/radiograph.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <optional>

namespace xgauge {

namespace {

ConversionSummary convertOrThrow(const ConversionOptions& options) {
  writableFormatOf(options.output);  // an unknown extension fails before the read
  checkOutputFile(options.output);
  const RadiographFile in = readRadiograph(options.input);
  TiffFormat samples =
      options.samples == SampleFormat::kUInt16 ? TiffFormat::kUInt16 : TiffFormat::kFloat32;
  if (options.samples == SampleFormat::kAuto) {
    const auto pixels = in.image.pixels();
    const bool whole = std::all_of(pixels.begin(), pixels.end(), [](float v) {
      return v >= 0.0f && v <= 65535.0f && std::nearbyint(v) == v;
    });
    samples = whole ? TiffFormat::kUInt16 : TiffFormat::kFloat32;
  }
  writeRadiograph(options.output, in.image, samples);
  spdlog::info("{} ({}, {}x{}{}) -> {} ({}, {})", options.input, toString(in.format),
               in.image.width(), in.image.height(),
               in.frames > 1 ? fmt::format(", mean of {} frames", in.frames) : std::string(),
               options.output.string(), toString(writableFormatOf(options.output)),
               samples == TiffFormat::kUInt16 ? "16-bit unsigned" : "32-bit float");
  ConversionSummary summary;
  summary.termination = RunTermination::kDone;
  summary.width = in.image.width(), summary.height = in.image.height();
  summary.frames = in.frames;
  summary.samples = samples == TiffFormat::kUInt16 ? SampleFormat::kUInt16 : SampleFormat::kFloat32;
  return summary;
}

// The white region's spread, before the clamp hides its upper half.
void logWhiteRegion(const NormalizedRadiograph& normalized, const PixelRect& white) {
  const Image region = normalized.image.crop(white);
  spdlog::info(
      "white region: mean {:.6g}; normalized min / 0.1 / 50 / 99.9 % / max: "
      "{:.4f} / {:.4f} / {:.4f} / {:.4f} / {:.4f} (before clamping)",
      normalized.white_mean, percentileOf(region, 0.0), percentileOf(region, 0.1),
      percentileOf(region, 50.0), percentileOf(region, 99.9), percentileOf(region, 100.0));
}

NormalizationSummary normalizeOrThrow(const NormalizationOptions& options) {
  checkOutputFile(options.output);
  if (!options.png.empty()) checkOutputFile(options.png);
  OutputTransaction outputs;
  if (options.dark.empty() && options.white.empty())
    fail("give --dark and --flat, or --white, or both: otherwise there is nothing to normalize by");
  if (options.dark.empty() != options.flat.empty()) fail("give --dark and --flat together");
  if (!options.white.empty() && options.white.size() != 4)
    fail("the white region is x y width height");
  std::optional<Image> dark, flat;
  if (!options.dark.empty())
    dark = readRadiograph(options.dark).image, flat = readRadiograph(options.flat).image;
  std::optional<PixelRect> white;
  if (!options.white.empty())
    white = PixelRect{options.white[0], options.white[1], options.white[2], options.white[3]};
  RadiographFrames frames;
  frames.dark = dark ? &*dark : nullptr;
  frames.flat = flat ? &*flat : nullptr;
  NormalizedRadiograph normalized = normalizeRadiograph(readRadiograph(options.raw).image, frames,
                                                        white, ClampPolicy::kNone, options.raw);
  if (dark)
    spdlog::info("flat-field corrected; {} bad pixels repaired from their neighbours",
                 normalized.repaired_pixels);
  if (white) {
    logWhiteRegion(normalized, *white);
    clampToOne(normalized.image);
  }
  const Image& image = normalized.image;
  writeTiff(options.output, image, TiffFormat::kFloat32);
  spdlog::info("wrote {}", options.output.string());
  if (!options.png.empty()) {
    Image preview = image;
    for (int bin = options.png_bin; bin > 1; bin /= 2) preview = downsample2x(preview);
    writePreviewPng(options.png, preview);
    spdlog::info("wrote {}", options.png.string());
  }
  outputs.commit();
  NormalizationSummary summary;
  summary.termination = RunTermination::kDone;
  summary.repaired_pixels = normalized.repaired_pixels;
  return summary;
}

std::map<std::string, double> parseOverrides(const std::vector<std::string>& items) {
  std::map<std::string, double> out;
  for (const auto& item : items) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0) fail("--set '{}': expected name=value", item);
    const std::string name = item.substr(0, eq), text = item.substr(eq + 1);
    size_t used = 0;
    double value = 0.0;
    try {
      value = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != text.size() || text.empty() || !std::isfinite(value))
      fail("--set '{}': '{}' is not a finite number", item, text);
    if (!out.emplace(name, value).second) fail("--set: dimension '{}' given twice", name);
  }
  return out;
}

Pose scenePose(const RenderingOptions& options) {
  if (!options.pose.empty()) return loadPose(options.pose);
  if (options.rotation_deg.size() == 3 && options.translation_mm.size() == 3)
    return Pose::fromEulerDeg(
        {options.rotation_deg[0], options.rotation_deg[1], options.rotation_deg[2]},
        {options.translation_mm[0], options.translation_mm[1], options.translation_mm[2]});
  fail("give the part's pose: --pose FILE, or --rotation-deg and --translation-mm");
}

RenderOptions sceneOptions(const RenderingOptions& options) {
  RenderOptions render_options;
  render_options.samples_per_axis = options.samples;
  render_options.edge_samples_per_axis = options.edge_samples;
  if (options.region.size() == 4)
    render_options.region = {options.region[0], options.region[1], options.region[2],
                             options.region[3]};
  return render_options;
}

// The posed part must lie in the beam and cast its shadow on the detector.
void checkInBeam(const Machine& machine, const std::vector<Vec3>& world) {
  if (auto why = outsideBeam(machine, world)) fail("{}: check the pose", *why);
  if (auto why = shadowMissesDetector(machine, world))
    fail("{}: check the pose (the part must be in the beam)", *why);
}

std::string gradientTable(const GradientCheck& check, double tolerance, bool& pass) {
  std::string table = fmt::format("{:<24} {:>12} {:>12} {:>12} {:>10}\n", "parameter", "largest",
                                  "worst", "norm error", "left out");
  pass = true;
  for (const GradientColumn& c : check.columns) {
    const bool moves = c.scale > GradientCheck::kMovesNothing;
    const bool ok = !moves || c.worst <= tolerance;
    pass = pass && ok;
    if (!moves) {
      table += fmt::format("{:<24} {:>12.4g} {:>12} {:>12} {:>10}  moves nothing in this view\n",
                           c.name, c.scale, "-", "-", "-");
      continue;
    }
    table += fmt::format("{:<24} {:>12.4g} {:>12.3g} {:>12.3g} {:>10}{}\n", c.name, c.scale,
                         c.worst, c.norm_error, c.kinked, ok ? "" : "  DISAGREES");
  }
  return table +
         "largest: the largest |central difference| (intensity per mm or deg); worst: the largest "
         "|analytic - difference| over it, on the pixels where differences with steps h and h/2 "
         "agree; left out: pixels where they do not (an edge crossed a sample within the step)\n";
}

GradientCheckSummary checkGradientsOrThrow(const GradientCheckOptions& options) {
  const RenderingOptions& scene = options.scene;
  const PartModel part = PartModel::fromFile(scene.part);
  const std::vector<double> values = part.values(parseOverrides(scene.dimensions));
  const Pose pose = scenePose(scene);
  const Machine machine = Machine::load(scene.machine);
  const ExponentialSum material = ExponentialSum::load(scene.material);
  {
    std::vector<Vec3> world;
    poseVertices(pose, part.mesh(values).vertices, world);
    checkInBeam(machine, world);
  }
  const GradientCheck check = checkPartGradients(
      machine, part, values, pose.eulerDeg(), pose.translation_mm, material, sceneOptions(scene));
  GradientCheckSummary summary;
  summary.termination = RunTermination::kDone;
  summary.report = gradientTable(check, options.tolerance, summary.agrees);
  summary.worst = check.worst();
  summary.message =
      summary.agrees
          ? fmt::format(
                "every derivative agrees with central differences within {:.3g} (worst "
                "{:.3g})",
                options.tolerance, check.worst())
          : fmt::format("the derivatives disagree with central differences beyond {:.3g}",
                        options.tolerance);
  return summary;
}

// The rendered image written as the options ask, each file atomically.
void writeRendering(const RenderingOptions& options, const Image& image, bool intensity) {
  if (intensity && options.format == SampleFormat::kUInt16) {
    Image scaled = image;
    for (float& p : scaled.pixels()) p *= 65535.0f;
    writeTiff(options.output, scaled, TiffFormat::kUInt16);
  } else {
    writeTiff(options.output, image, TiffFormat::kFloat32);
  }
  spdlog::info("wrote {}", options.output.string());
  if (!options.png.empty()) {
    writePreviewPng(options.png, image);
    spdlog::info("wrote {}", options.png.string());
  }
}

RenderingSummary renderOrThrow(const RenderingOptions& options) {
  checkOutputFile(options.output);
  if (!options.png.empty()) checkOutputFile(options.png);
  OutputTransaction outputs;
  // Inputs: part, dimension values, pose, machine, material.
  const PartModel part = PartModel::fromFile(options.part);
  const std::vector<double> values = part.values(parseOverrides(options.dimensions));
  const TriangleMesh mesh = part.mesh(values);
  const Pose pose = scenePose(options);
  const Machine machine = Machine::load(options.machine);
  const bool intensity = options.quantity == RenderedQuantity::kIntensity;
  if (intensity && options.material.empty()) fail("--quantity intensity needs --material FILE");
  if (!intensity && options.format == SampleFormat::kUInt16)
    fail("--format u16 is for intensity; use f32 for path");

  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  const WorldMesh posed{world, mesh.triangles, mesh.csg.get()};
  checkInBeam(machine, world);
  const auto start = std::chrono::steady_clock::now();
  Image image;
  if (intensity) {
    const ExponentialSum material = ExponentialSum::load(options.material);
    const double longest = boundingBox(mesh).diagonal() + 1.0;
    renderIntensity(machine, posed, TransmissionTable::forMaterial(material, longest),
                    sceneOptions(options), image);
  } else {
    renderPathLength(machine, posed, sceneOptions(options), image);
  }
  RenderingSummary summary;
  summary.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("rendered {} ({} triangles) at {}x{} with {}x{} samples in {:.1f} ms", part.name(),
               mesh.triangles.size(), image.width(), image.height(), options.samples,
               options.samples, summary.milliseconds);
  writeRendering(options, image, intensity);
  outputs.commit();
  summary.termination = RunTermination::kDone;
  summary.width = image.width(), summary.height = image.height();
  return summary;
}

}  // namespace

ConversionSummary convert(const ConversionOptions& options) {
  return api::guarded<ConversionSummary>([&] { return convertOrThrow(options); });
}

NormalizationSummary normalize(const NormalizationOptions& options) {
  return api::guarded<NormalizationSummary>([&] { return normalizeOrThrow(options); });
}

RenderingSummary render(const RenderingOptions& options) {
  return api::guarded<RenderingSummary>([&] { return renderOrThrow(options); });
}

GradientCheckSummary checkGradients(const GradientCheckOptions& options) {
  return api::guarded<GradientCheckSummary>([&] { return checkGradientsOrThrow(options); });
}

}  // namespace xgauge
