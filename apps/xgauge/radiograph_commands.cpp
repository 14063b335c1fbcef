// `xgauge render`, `check-gradients`, `convert` and `normalize`:
// xgauge/radiographs.h's calls and a print.
#include "commands.h"
#include "xgauge/radiographs.h"
#include "xgauge/runtime.h"

#include <cstdio>
#include <memory>
#include <string>

namespace xgauge::cli {

namespace {

// The scene's arguments that render's options do not hold as CLI11 takes them.
struct SceneArguments {
  std::string part, machine, material, pose;
  std::string quantity = "intensity";  // intensity | path
  std::string format = "f32";          // u16 | f32
  std::string output, png;
};

RenderingOptions& filled(RenderingOptions& options, const SceneArguments& args) {
  options.part = args.part;
  options.machine = args.machine;
  options.material = args.material;
  options.pose = args.pose;
  options.quantity =
      args.quantity == "path" ? RenderedQuantity::kPathLength : RenderedQuantity::kIntensity;
  options.format = args.format == "u16" ? SampleFormat::kUInt16 : SampleFormat::kFloat32;
  options.output = args.output;
  options.png = args.png;
  return options;
}

// The options `render` and `check-gradients` share: part, dimensions, pose,
// machine, material, sampling.
void addSceneOptions(CLI::App* cmd, RenderingOptions& options, SceneArguments& args) {
  cmd->add_option("part", args.part, "Part model (.json) or mesh (.stl)")->required();
  cmd->add_option("-m,--machine", args.machine, "Machine geometry (JSON)")->required();
  auto* pose = cmd->add_option("-p,--pose", args.pose, "Part pose (JSON)");
  auto* rot =
      cmd->add_option("--rotation-deg", options.rotation_deg, "Pose rotation rx ry rz (deg)")
          ->expected(3);
  auto* trans =
      cmd->add_option("--translation-mm", options.translation_mm, "Pose translation tx ty tz (mm)")
          ->expected(3);
  pose->excludes(rot)->excludes(trans);
  cmd->add_option("-s,--set", options.dimensions, "Dimension value, name=value (mm); repeatable");
  cmd->add_option("-n,--samples", options.samples, "n x n samples per pixel (area sampling)")
      ->check(CLI::Range(1, 16));
  cmd->add_option("--region", options.region, "Render only x y width height (pixels)")->expected(4);
}

}  // namespace

void addGradientCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<GradientCheckOptions>();
  auto args = std::make_shared<SceneArguments>();
  CLI::App* cmd = app.add_subcommand(
      "check-gradients",
      "Check a part model's radiograph derivatives (dimensions and pose) against central "
      "differences of rendered images");
  addSceneOptions(cmd, options->scene, *args);
  cmd->add_option("--material", args->material, "Material (JSON)")->required();
  cmd->add_option("--tolerance", options->tolerance,
                  "Largest difference allowed, as a fraction of each column's largest value")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  commands.push_back({cmd, [options, args] {
                        filled(options->scene, *args);
                        const GradientCheckSummary summary = succeeded(checkGradients(*options));
                        std::fputs(summary.report.c_str(), stdout);
                        std::fflush(stdout);
                        LogMessage(summary.agrees ? Severity::kInfo : Severity::kError,
                                   summary.message);
                        return summary.agrees ? 0 : 4;
                      }});
}

void addRenderCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<RenderingOptions>();
  auto args = std::make_shared<SceneArguments>();
  CLI::App* cmd = app.add_subcommand(
      "render", "Simulate one radiograph of a part model (intensity or path length)");
  addSceneOptions(cmd, *options, *args);
  cmd->add_option(
         "--edge-samples", options->edge_samples,
         "Sample again with m x m (more than n, up to 32) the pixels where the n x n image "
         "bends (walls seen edge-on, silhouettes); 0: off")
      ->check(CLI::Range(0, 32));
  cmd->add_option("--material", args->material, "Material (JSON); required for intensity");
  cmd->add_option("--quantity", args->quantity, "intensity or path (path length in mm)")
      ->check(CLI::IsMember({"intensity", "path"}));
  cmd->add_option("--format", args->format,
                  "TIFF sample format: f32, or u16 (intensity x 65535, intensity only)")
      ->check(CLI::IsMember({"u16", "f32"}));
  cmd->add_option("-o,--output", args->output, "Output TIFF")->required();
  cmd->add_option("--png", args->png, "Also write an 8-bit PNG preview");
  commands.push_back({cmd, [options, args] {
                        succeeded(render(filled(*options, *args)));
                        return 0;
                      }});
}

void addConvertCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<ConversionOptions>();
  auto args = std::make_shared<std::pair<std::string, std::string>>("", "auto");
  CLI::App* cmd = app.add_subcommand(
      "convert",
      "Convert a radiograph between TIFF, raw + JSON sidecar, NXtomo and DICONDE (by OUT's "
      "extension; docs/formats.md, \"Radiographs\")");
  cmd->add_option("input", options->input,
                  "Radiograph to read (TIFF, raw + sidecar, NXtomo with #selector, DICONDE)")
      ->required();
  cmd->add_option(
         "output", args->first,
         "File to write: .tif/.tiff, .raw (+ .raw.json), .nxs/.h5/.hdf5/.nx5 or .dcm/.dicom")
      ->required();
  cmd->add_option("--type", args->second,
                  "Samples written: u16 (rounded, clamped to 0..65535), f32 (exact) or auto "
                  "(u16 when every pixel is a whole number in 0..65535, so nothing is lost)")
      ->check(CLI::IsMember({"auto", "u16", "f32"}))
      ->capture_default_str();
  commands.push_back({cmd, [options, args] {
                        options->output = args->first;
                        options->samples = args->second == "u16"   ? SampleFormat::kUInt16
                                           : args->second == "f32" ? SampleFormat::kFloat32
                                                                   : SampleFormat::kAuto;
                        succeeded(convert(*options));
                        return 0;
                      }});
}

void addNormalizeCommand(CLI::App& app, Commands& commands) {
  auto options = std::make_shared<NormalizationOptions>();
  auto files = std::make_shared<std::pair<std::string, std::string>>();  // output, png
  CLI::App* cmd =
      app.add_subcommand("normalize",
                         "Normalize a raw radiograph: dark/flat correction, then a white region "
                         "(thesis eq. 3.9, docs/method.md)");
  cmd->add_option("raw", options->raw,
                  "Raw radiograph (TIFF, raw + sidecar, NXtomo#selector or DICONDE)")
      ->required();
  auto* dark = cmd->add_option("--dark", options->dark, "Dark frame (any radiograph format)");
  auto* flat =
      cmd->add_option("--flat", options->flat, "Flat (open-beam) frame (any radiograph format)");
  dark->needs(flat);
  flat->needs(dark);
  cmd->add_option("--white", options->white,
                  "Open-beam region x y width height: divide by its mean, clamp to 1")
      ->expected(4);
  cmd->add_option("-o,--output", files->first, "Normalized image (32-bit float TIFF)")->required();
  cmd->add_option("--png", files->second, "Also write an 8-bit PNG preview");
  cmd->add_option("--png-bin", options->png_bin,
                  "Bin the preview by 2x2 box averaging to 1/N size (N = 1, 2, 4, ...)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16}));
  commands.push_back({cmd, [options, files] {
                        options->output = files->first;
                        options->png = files->second;
                        succeeded(normalize(*options));
                        return 0;
                      }});
}

}  // namespace xgauge::cli
