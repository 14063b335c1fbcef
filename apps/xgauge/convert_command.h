// `xgauge convert IN OUT`: a radiograph from any format xgauge reads to any
// it writes (image/radiograph_file.h), chosen by OUT's extension.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace xgauge::cli {

struct ConvertArguments {
  std::string input;          // may carry an NXtomo selector: scan.nxs#dark
  std::string output;         // .tif/.tiff, .raw (+ .raw.json), .nxs/.h5/.hdf5/.nx5, .dcm/.dicom
  std::string type = "auto";  // auto, u16 or f32
};

void addConvertCommand(CLI::App& app, ConvertArguments& args);
void runConvert(const ConvertArguments& args);

}  // namespace xgauge::cli
