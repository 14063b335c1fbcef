#include "render_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>

namespace xgauge::cli {

namespace {

// The options `render` and `check-gradients` share: part, dimensions, pose,
// machine, material, sampling.
void addSceneOptions(CLI::App* cmd, RenderArguments& args) {
  cmd->add_option("part", args.part, "Part model (.json) or mesh (.stl)")->required();
  cmd->add_option("-m,--machine", args.machine, "Machine geometry (JSON)")->required();
  auto* pose = cmd->add_option("-p,--pose", args.pose, "Part pose (JSON)");
  auto* rot = cmd->add_option("--rotation-deg", args.rotation_deg, "Pose rotation rx ry rz (deg)")
                  ->expected(3);
  auto* trans =
      cmd->add_option("--translation-mm", args.translation_mm, "Pose translation tx ty tz (mm)")
          ->expected(3);
  pose->excludes(rot)->excludes(trans);
  cmd->add_option("-s,--set", args.set, "Dimension value, name=value (mm); repeatable");
  cmd->add_option("-n,--samples", args.samples, "n x n samples per pixel (area sampling)")
      ->check(CLI::Range(1, 16));
  cmd->add_option("--region", args.region, "Render only x y width height (pixels)")->expected(4);
}

}  // namespace

void addGradientCommand(CLI::App& app, GradientArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "check-gradients",
      "Check a part model's radiograph derivatives (dimensions and pose) against central "
      "differences of rendered images");
  addSceneOptions(cmd, args.scene);
  cmd->add_option("--material", args.scene.material, "Material (JSON)")->required();
  cmd->add_option("--tolerance", args.tolerance,
                  "Largest difference allowed, as a fraction of each column's largest value")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
}

void addRenderCommand(CLI::App& app, RenderArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "render", "Simulate one radiograph of a part model (intensity or path length)");
  addSceneOptions(cmd, args);
  cmd->add_option(
         "--edge-samples", args.edge_samples,
         "Sample again with m x m (more than n, up to 32) the pixels where the n x n image "
         "bends (walls seen edge-on, silhouettes); 0: off")
      ->check(CLI::Range(0, 32));
  cmd->add_option("--material", args.material, "Material (JSON); required for intensity");
  cmd->add_option("--quantity", args.quantity, "intensity or path (path length in mm)")
      ->check(CLI::IsMember({"intensity", "path"}));
  cmd->add_option("--format", args.format,
                  "TIFF sample format: f32, or u16 (intensity x 65535, intensity only)")
      ->check(CLI::IsMember({"u16", "f32"}));
  cmd->add_option("-o,--output", args.output, "Output TIFF")->required();
  cmd->add_option("--png", args.png, "Also write an 8-bit PNG preview");
}

namespace {

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

Pose scenePose(const RenderArguments& args) {
  if (!args.pose.empty()) return loadPose(args.pose);
  if (args.rotation_deg.size() == 3 && args.translation_mm.size() == 3)
    return Pose::fromEulerDeg(
        {args.rotation_deg[0], args.rotation_deg[1], args.rotation_deg[2]},
        {args.translation_mm[0], args.translation_mm[1], args.translation_mm[2]});
  fail("give the part's pose: --pose FILE, or --rotation-deg and --translation-mm");
}

RenderOptions sceneOptions(const RenderArguments& args) {
  RenderOptions options;
  options.samples_per_axis = args.samples;
  options.edge_samples_per_axis = args.edge_samples;
  if (args.region.size() == 4)
    options.region = {args.region[0], args.region[1], args.region[2], args.region[3]};
  return options;
}

}  // namespace

int runGradientCheck(const GradientArguments& args) {
  const RenderArguments& scene = args.scene;
  const PartModel part = PartModel::fromFile(scene.part);
  const std::vector<double> values = part.values(parseOverrides(scene.set));
  const Pose pose = scenePose(scene);
  const Machine machine = Machine::load(scene.machine);
  const ExponentialSum material = ExponentialSum::load(scene.material);
  {
    std::vector<Vec3> world;
    poseVertices(pose, part.mesh(values).vertices, world);
    if (auto why = outsideBeam(machine, world)) fail("{}: check the pose", *why);
    if (auto why = shadowMissesDetector(machine, world))
      fail("{}: check the pose (the part must be in the beam)", *why);
  }
  const GradientCheck check = checkPartGradients(
      machine, part, values, pose.eulerDeg(), pose.translation_mm, material, sceneOptions(scene));
  fmt::print("{:<24} {:>12} {:>12} {:>12} {:>10}\n", "parameter", "largest", "worst", "norm error",
             "left out");
  bool pass = true;
  for (const GradientColumn& c : check.columns) {
    const bool moves = c.scale > GradientCheck::kMovesNothing;
    const bool ok = !moves || c.worst <= args.tolerance;
    pass = pass && ok;
    if (!moves) {
      fmt::print("{:<24} {:>12.4g} {:>12} {:>12} {:>10}  moves nothing in this view\n", c.name,
                 c.scale, "-", "-", "-");
      continue;
    }
    fmt::print("{:<24} {:>12.4g} {:>12.3g} {:>12.3g} {:>10}{}\n", c.name, c.scale, c.worst,
               c.norm_error, c.kinked, ok ? "" : "  DISAGREES");
  }
  fmt::print(
      "largest: the largest |central difference| (intensity per mm or deg); worst: the largest "
      "|analytic - difference| over it, on the pixels where differences with steps h and h/2 "
      "agree; left out: pixels where they do not (an edge crossed a sample within the step)\n");
  std::fflush(stdout);
  if (!pass) {
    spdlog::error("the derivatives disagree with central differences beyond {:.3g}",
                  args.tolerance);
    return 4;
  }
  spdlog::info("every derivative agrees with central differences within {:.3g} (worst {:.3g})",
               args.tolerance, check.worst());
  return 0;
}

void runRender(const RenderArguments& args) {
  checkOutputFile(args.output);
  if (!args.png.empty()) checkOutputFile(args.png);
  OutputTransaction outputs;
  // Inputs: part, dimension values, pose, machine, material.
  const PartModel part = PartModel::fromFile(args.part);
  const std::vector<double> values = part.values(parseOverrides(args.set));
  const TriangleMesh mesh = part.mesh(values);
  const Pose pose = scenePose(args);
  const Machine machine = Machine::load(args.machine);
  const bool intensity = args.quantity == "intensity";
  if (intensity && args.material.empty()) fail("--quantity intensity needs --material FILE");
  if (!intensity && args.format == "u16") fail("--format u16 is for intensity; use f32 for path");

  const RenderOptions options = sceneOptions(args);

  // Render.
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  const WorldMesh posed{world, mesh.triangles, mesh.csg.get()};
  if (auto why = outsideBeam(machine, world)) fail("{}: check the pose", *why);
  if (auto why = shadowMissesDetector(machine, world))
    fail("{}: check the pose (the part must be in the beam)", *why);
  const auto start = std::chrono::steady_clock::now();
  Image image;
  if (intensity) {
    const ExponentialSum material = ExponentialSum::load(args.material);
    const double longest = boundingBox(mesh).diagonal() + 1.0;
    renderIntensity(machine, posed, TransmissionTable::forMaterial(material, longest), options,
                    image);
  } else {
    renderPathLength(machine, posed, options, image);
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("rendered {} ({} triangles) at {}x{} with {}x{} samples in {:.1f} ms", part.name(),
               mesh.triangles.size(), image.width(), image.height(), args.samples, args.samples,
               ms);

  // Outputs, each written atomically.
  if (intensity && args.format == "u16") {
    Image scaled = image;
    for (float& p : scaled.pixels()) p *= 65535.0f;
    writeTiff(args.output, scaled, TiffFormat::kUInt16);
  } else {
    writeTiff(args.output, image, TiffFormat::kFloat32);
  }
  spdlog::info("wrote {}", args.output);
  if (!args.png.empty()) {
    writePreviewPng(args.png, image);
    spdlog::info("wrote {}", args.png);
  }
  outputs.commit();
}

}  // namespace xgauge::cli
