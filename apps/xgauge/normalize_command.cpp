#include "normalize_command.h"

#include "xgauge/core/error.h"
#include "xgauge/image/bad_pixels.h"
#include "xgauge/image/normalize.h"
#include "xgauge/image/preview.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"

#include <spdlog/spdlog.h>

namespace xgauge::cli {

void addNormalizeCommand(CLI::App& app, NormalizeArguments& args) {
  CLI::App* cmd =
      app.add_subcommand("normalize",
                         "Normalize a raw radiograph: dark/flat correction, then a white region "
                         "(thesis eq. 3.9, docs/method.md)");
  cmd->add_option("raw", args.raw, "Raw radiograph (TIFF)")->required();
  auto* dark = cmd->add_option("--dark", args.dark, "Dark frame (TIFF)");
  auto* flat = cmd->add_option("--flat", args.flat, "Flat (open-beam) frame (TIFF)");
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
  Image image = readTiff(args.raw);
  if (args.dark.empty() && args.white.empty())
    fail("give --dark and --flat, or --white, or both: otherwise there is nothing to normalize by");
  if (!args.dark.empty()) {
    const Image dark = readTiff(args.dark), flat = readTiff(args.flat);
    int64_t repaired = 0;
    try {
      image = flatFieldCorrectRepairing(image, dark, flat, &repaired);
    } catch (const Error& e) {
      fail("{} with {} and {}: {}", args.raw, args.dark, args.flat, e.message());
    }
    spdlog::info("flat-field corrected; {} bad pixels repaired from their neighbours", repaired);
  }
  if (!args.white.empty()) {
    const PixelRect white{args.white[0], args.white[1], args.white[2], args.white[3]};
    if (!image.rect().contains(white) || white.empty())
      fail("--white {} is not a non-empty region inside the {}x{} image", toString(white),
           image.width(), image.height());
    // The spread of the open beam, before the clamp hides its upper half.
    const double mean = meanOf(image, white);
    const Image region = image.crop(white);
    spdlog::info("white region: mean {:.6g}; normalized min / 0.1 / 50 / 99.9 % / max: "
                 "{:.4f} / {:.4f} / {:.4f} / {:.4f} / {:.4f} (before clamping)",
                 mean, percentileOf(region, 0.0) / mean, percentileOf(region, 0.1) / mean,
                 percentileOf(region, 50.0) / mean, percentileOf(region, 99.9) / mean,
                 percentileOf(region, 100.0) / mean);
    image = normalizeByWhiteRegion(image, white);
  }
  writeTiff(args.output, image, TiffFormat::kFloat32);
  spdlog::info("wrote {}", args.output);
  if (!args.png.empty()) {
    Image preview = image;
    for (int bin = args.png_bin; bin > 1; bin /= 2) preview = downsample2x(preview);
    writePreviewPng(args.png, preview);
    spdlog::info("wrote {}", args.png);
  }
}

}  // namespace xgauge::cli
