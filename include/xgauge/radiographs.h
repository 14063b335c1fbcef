// xgauge's radiographs from code: converted between file formats,
// normalized, rendered from a part model (with its exact derivatives
// checked), in the style of xgauge/xgauge.h: an options struct, one call, a
// summary whose termination and message say how it ended. Needs only the
// C++ standard library; nothing here throws for bad input. The calls write
// what they did to the library's log (xgauge/runtime.h). docs/formats.md
// describes the formats and files.
#pragma once

#include "xgauge/runtime.h"

#include <filesystem>
#include <string>
#include <vector>

namespace xgauge {

// The samples a radiograph is written with.
enum class SampleFormat {
  kAuto,     // kUInt16 when every pixel is a whole number in 0..65535, else kFloat32
  kUInt16,   // rounded, clamped to 0..65535
  kFloat32,  // exact
};

// A radiograph from any format xgauge reads to any it writes, chosen by the
// output's extension: .tif/.tiff, .raw (+ .raw.json), .nxs/.h5/.hdf5/.nx5,
// .dcm/.dicom.
struct ConversionOptions {
  std::string input;  // may carry an NXtomo selector: scan.nxs#dark
  std::filesystem::path output;
  SampleFormat samples = SampleFormat::kAuto;
};

struct ConversionSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why
  int width = 0, height = 0;
  int frames = 0;                              // averaged into the image read
  SampleFormat samples = SampleFormat::kAuto;  // as written
};

ConversionSummary convert(const ConversionOptions& options);

// A raw radiograph to normalized intensity (1 = open beam): dark and flat
// correction, then division by a white region's mean, clamped to 1 (thesis
// eq. 3.9, docs/method.md).
struct NormalizationOptions {
  std::string raw;
  std::string dark, flat;        // both or neither
  std::vector<int> white;        // empty, or the open-beam region x y width height
  std::filesystem::path output;  // 32-bit float TIFF
  std::filesystem::path png;     // optional 8-bit preview
  int png_bin = 1;               // the preview binned to 1/png_bin (a power of two)
};

struct NormalizationSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;      // kFailure: why
  int repaired_pixels = 0;  // bad pixels repaired from their neighbours (with dark and flat)
};

NormalizationSummary normalize(const NormalizationOptions& options);

// One simulated radiograph of a part model.
enum class RenderedQuantity {
  kIntensity,   // transmitted intensity (needs the material)
  kPathLength,  // path length through the part, mm
};

struct RenderingOptions {
  std::filesystem::path part;      // part model (.json) or mesh (.stl)
  std::filesystem::path machine;   // machine geometry (JSON)
  std::filesystem::path material;  // material (JSON); needed for intensity
  // The pose: a file, or rotation rx ry rz (deg) and translation tx ty tz (mm).
  std::filesystem::path pose;
  std::vector<double> rotation_deg, translation_mm;
  // Dimension values as "name=value" (mm), the part's own where absent.
  std::vector<std::string> dimensions;
  RenderedQuantity quantity = RenderedQuantity::kIntensity;
  // kFloat32, or kUInt16 (intensity x 65535, intensity only).
  SampleFormat format = SampleFormat::kFloat32;
  int samples = 1;               // n x n samples per pixel
  int edge_samples = 0;          // m x m again where the n x n image bends; 0: off
  std::vector<int> region;       // empty, or only x y width height (pixels)
  std::filesystem::path output;  // TIFF
  std::filesystem::path png;     // optional 8-bit preview
};

struct RenderingSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why
  int width = 0, height = 0;
  double milliseconds = 0.0;  // the render alone
};

RenderingSummary render(const RenderingOptions& options);

// The radiograph's derivatives with respect to the dimensions and the pose
// against central differences of rendered images (the scene as render's:
// part, dimensions, pose, machine, material, samples, region).
struct GradientCheckOptions {
  RenderingOptions scene;
  double tolerance = 1e-4;  // as a fraction of each column's largest value
};

struct GradientCheckSummary {
  RunTermination termination = RunTermination::kFailure;
  // kFailure: why; otherwise whether the derivatives agree, in words.
  std::string message;
  bool agrees = false;  // every derivative within the tolerance
  double worst = 0.0;
  std::string report;  // the table `xgauge check-gradients` prints
};

GradientCheckSummary checkGradients(const GradientCheckOptions& options);

}  // namespace xgauge
