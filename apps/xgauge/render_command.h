// `xgauge render`: one simulated radiograph of a part model; `xgauge
// check-gradients`: its derivatives against central differences.
#pragma once

#include <CLI/CLI.hpp>

#include <map>
#include <string>
#include <vector>

namespace xgauge::cli {

struct RenderArguments {
  std::string part;                    // part model (.json) or mesh (.stl)
  std::string machine;                 // machine JSON
  std::string material;                // material JSON (needed for intensity)
  std::string pose;                    // pose JSON
  std::vector<double> rotation_deg;    // or inline: rx ry rz
  std::vector<double> translation_mm;  // tx ty tz
  std::vector<std::string> set;        // name=value dimension overrides
  std::string quantity = "intensity";  // intensity | path
  std::string format = "f32";          // u16 | f32
  int samples = 1;
  int edge_samples = 0;  // render only: refine pixels where the image bends (RenderOptions)
  std::vector<int> region;  // x y width height
  std::string output;       // TIFF
  std::string png;          // optional preview
};

void addRenderCommand(CLI::App& app, RenderArguments& args);
void runRender(const RenderArguments& args);

// The same part, pose, machine, material and sampling as `render`, no output
// file; the exit status is 0 when every parameter's derivative image agrees
// with central differences within `tolerance`, else 4.
struct GradientArguments {
  RenderArguments scene;
  double tolerance = 1e-4;
};
void addGradientCommand(CLI::App& app, GradientArguments& args);
int runGradientCheck(const GradientArguments& args);

}  // namespace xgauge::cli
