#include "convert_command.h"

#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/image/radiograph_file.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

namespace xgauge::cli {

void addConvertCommand(CLI::App& app, ConvertArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "convert",
      "Convert a radiograph between TIFF, raw + JSON sidecar, NXtomo and DICONDE (by OUT's "
      "extension; docs/formats.md, \"Radiographs\")");
  cmd->add_option("input", args.input,
                  "Radiograph to read (TIFF, raw + sidecar, NXtomo with #selector, DICONDE)")
      ->required();
  cmd->add_option(
         "output", args.output,
         "File to write: .tif/.tiff, .raw (+ .raw.json), .nxs/.h5/.hdf5/.nx5 or .dcm/.dicom")
      ->required();
  cmd->add_option("--type", args.type,
                  "Samples written: u16 (rounded, clamped to 0..65535), f32 (exact) or auto "
                  "(u16 when every pixel is a whole number in 0..65535, so nothing is lost)")
      ->check(CLI::IsMember({"auto", "u16", "f32"}))
      ->capture_default_str();
}

void runConvert(const ConvertArguments& args) {
  writableFormatOf(args.output);  // an unknown extension fails before the read
  checkOutputFile(args.output);
  const RadiographFile in = readRadiograph(args.input);
  TiffFormat samples = args.type == "u16" ? TiffFormat::kUInt16 : TiffFormat::kFloat32;
  if (args.type == "auto") {
    const auto pixels = in.image.pixels();
    const bool whole = std::all_of(pixels.begin(), pixels.end(), [](float v) {
      return v >= 0.0f && v <= 65535.0f && std::nearbyint(v) == v;
    });
    samples = whole ? TiffFormat::kUInt16 : TiffFormat::kFloat32;
  }
  writeRadiograph(args.output, in.image, samples);
  spdlog::info("{} ({}, {}x{}{}) -> {} ({}, {})", args.input, toString(in.format), in.image.width(),
               in.image.height(),
               in.frames > 1 ? fmt::format(", mean of {} frames", in.frames) : std::string(),
               args.output, toString(writableFormatOf(args.output)),
               samples == TiffFormat::kUInt16 ? "16-bit unsigned" : "32-bit float");
}

}  // namespace xgauge::cli
