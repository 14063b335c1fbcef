#include "normalize_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/radiograph.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"

#include <spdlog/spdlog.h>

#include <optional>

namespace xgauge::cli {

void addNormalizeCommand(CLI::App& app, NormalizeArguments& args) {
  CLI::App* cmd =
      app.add_subcommand("normalize",
                         "Normalize a raw radiograph: dark/flat correction, then a white region "
                         "(thesis eq. 3.9, docs/method.md)");
  cmd->add_option("raw", args.raw,
                  "Raw radiograph (TIFF, raw + sidecar, NXtomo#selector or DICONDE)")
      ->required();
  auto* dark = cmd->add_option("--dark", args.dark, "Dark frame (any radiograph format)");
  auto* flat =
      cmd->add_option("--flat", args.flat, "Flat (open-beam) frame (any radiograph format)");
  dark->needs(flat);
  flat->needs(dark);
  cmd->add_option("--white", args.white, "Open-beam region x y width height: divide by its mean, clamp to 1")
      ->expected(4);
  cmd->add_option("-o,--output", args.output, "Normalized image (32-bit float TIFF)")->required();
  cmd->add_option("--png", args.png, "Also write an 8-bit PNG preview");
  cmd->add_option("--png-bin", args.png_bin, "Bin the preview by 2x2 box averaging to 1/N size (N = 1, 2, 4, ...)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16}));
}

void runNormalize(const NormalizeArguments& args) {
  checkOutputFile(args.output);
  if (!args.png.empty()) checkOutputFile(args.png);
  OutputTransaction outputs;
  if (args.dark.empty() && args.white.empty())
    fail("give --dark and --flat, or --white, or both: otherwise there is nothing to normalize by");
  std::optional<Image> dark, flat;
  if (!args.dark.empty())
    dark = readRadiograph(args.dark).image, flat = readRadiograph(args.flat).image;
  std::optional<PixelRect> white;
  if (!args.white.empty()) white = PixelRect{args.white[0], args.white[1], args.white[2], args.white[3]};
  RadiographFrames frames;
  frames.dark = dark ? &*dark : nullptr;
  frames.flat = flat ? &*flat : nullptr;
  NormalizedRadiograph normalized = normalizeRadiograph(readRadiograph(args.raw).image, frames,
                                                        white, ClampPolicy::kNone, args.raw);
  if (dark)
    spdlog::info("flat-field corrected; {} bad pixels repaired from their neighbours",
                 normalized.repaired_pixels);
  if (white) {
    // The spread of the open beam, before the clamp hides its upper half.
    const Image region = normalized.image.crop(*white);
    spdlog::info("white region: mean {:.6g}; normalized min / 0.1 / 50 / 99.9 % / max: "
                 "{:.4f} / {:.4f} / {:.4f} / {:.4f} / {:.4f} (before clamping)",
                 normalized.white_mean, percentileOf(region, 0.0), percentileOf(region, 0.1),
                 percentileOf(region, 50.0), percentileOf(region, 99.9),
                 percentileOf(region, 100.0));
    clampToOne(normalized.image);
  }
  const Image& image = normalized.image;
  writeTiff(args.output, image, TiffFormat::kFloat32);
  spdlog::info("wrote {}", args.output);
  if (!args.png.empty()) {
    Image preview = image;
    for (int bin = args.png_bin; bin > 1; bin /= 2) preview = downsample2x(preview);
    writePreviewPng(args.png, preview);
    spdlog::info("wrote {}", args.png);
  }
  outputs.commit();
}

}  // namespace xgauge::cli
