#include "render_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/tiff.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>

namespace xgauge::cli {

void addRenderCommand(CLI::App& app, RenderArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "render", "Simulate one radiograph of a part model (intensity or path length)");
  cmd->add_option("part", args.part, "Part model (.json) or mesh (.stl)")->required();
  cmd->add_option("-m,--machine", args.machine, "Machine geometry (JSON)")->required();
  cmd->add_option("--material", args.material, "Material (JSON); required for intensity");
  auto* pose = cmd->add_option("-p,--pose", args.pose, "Part pose (JSON)");
  auto* rot = cmd->add_option("--rotation-deg", args.rotation_deg, "Pose rotation rx ry rz (deg)")
                  ->expected(3);
  auto* trans = cmd->add_option("--translation-mm", args.translation_mm,
                                "Pose translation tx ty tz (mm)")
                    ->expected(3);
  pose->excludes(rot)->excludes(trans);
  cmd->add_option("-s,--set", args.set, "Dimension value, name=value (mm); repeatable");
  cmd->add_option("--quantity", args.quantity, "intensity or path (path length in mm)")
      ->check(CLI::IsMember({"intensity", "path"}));
  cmd->add_option("--format", args.format,
                  "TIFF sample format: f32, or u16 (intensity x 65535, intensity only)")
      ->check(CLI::IsMember({"u16", "f32"}));
  cmd->add_option("-n,--samples", args.samples, "n x n samples per pixel (area sampling)")
      ->check(CLI::Range(1, 16));
  cmd->add_option("--region", args.region, "Render only x y width height (pixels)")->expected(4);
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

}  // namespace

void runRender(const RenderArguments& args) {
  checkOutputFile(args.output);
  if (!args.png.empty()) checkOutputFile(args.png);
  OutputTransaction outputs;
  // Inputs: part, dimension values, pose, machine, material.
  const bool stl = args.part.size() > 4 && args.part.substr(args.part.size() - 4) == ".stl";
  const PartModel part = stl ? PartModel::fromStl(args.part) : PartModel::load(args.part);
  const std::vector<double> values = part.values(parseOverrides(args.set));
  const TriangleMesh mesh = part.mesh(values);
  Pose pose;
  if (!args.pose.empty()) {
    pose = loadPose(args.pose);
  } else if (args.rotation_deg.size() == 3 && args.translation_mm.size() == 3) {
    pose = Pose::fromEulerDeg({args.rotation_deg[0], args.rotation_deg[1], args.rotation_deg[2]},
                              {args.translation_mm[0], args.translation_mm[1], args.translation_mm[2]});
  } else {
    fail("give the part's pose: --pose FILE, or --rotation-deg and --translation-mm");
  }
  const Machine machine = Machine::load(args.machine);
  const bool intensity = args.quantity == "intensity";
  if (intensity && args.material.empty()) fail("--quantity intensity needs --material FILE");
  if (!intensity && args.format == "u16") fail("--format u16 is for intensity; use f32 for path");

  RenderOptions options;
  options.samples_per_axis = args.samples;
  if (args.region.size() == 4)
    options.region = {args.region[0], args.region[1], args.region[2], args.region[3]};

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
  spdlog::info("rendered {} ({} triangles) at {}x{} with {}x{} samples in {:.1f} ms",
               part.name(), mesh.triangles.size(), image.width(), image.height(), args.samples,
               args.samples, ms);

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
