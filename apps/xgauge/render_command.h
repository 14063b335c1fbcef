// `xgauge render`: one simulated radiograph of a part model.
#pragma once

#include <CLI/CLI.hpp>

#include <map>
#include <string>
#include <vector>

namespace xgauge::cli {

struct RenderArguments {
  std::string part;                 // part model (.json) or mesh (.stl)
  std::string machine;              // machine JSON
  std::string material;             // material JSON (needed for intensity)
  std::string pose;                 // pose JSON
  std::vector<double> rotation_deg;     // or inline: rx ry rz
  std::vector<double> translation_mm;   // tx ty tz
  std::vector<std::string> set;     // name=value dimension overrides
  std::string quantity = "intensity";  // intensity | path
  std::string format = "f32";       // u16 | f32
  int samples = 1;
  std::vector<int> region;          // x y width height
  std::string output;               // TIFF
  std::string png;                  // optional preview
};

void addRenderCommand(CLI::App& app, RenderArguments& args);
void runRender(const RenderArguments& args);

}  // namespace xgauge::cli
