// The detector file a machine may name (`detector.characterization`,
// relative to the machine file): what `xgauge characterize` measured of the
// panel (docs/formats.md, "Detector file"). Calibrations and measurements
// take the halo and the lag fraction from it where their job states none,
// and undo its column crosstalk on every raw radiograph.
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/scatter.h"

#include <filesystem>
#include <optional>

namespace xgauge {

struct DetectorFile {
  std::filesystem::path file;
  std::optional<ScatterModel> halo;  // "halo.scatter"
  double lag_fraction = std::numeric_limits<double>::quiet_NaN();
  double lag_fraction_uncertainty = std::numeric_limits<double>::quiet_NaN();
  // "crosstalk": c of X = R + c * column mean of R, with its uncertainty
  // (NaN: not characterised).
  double column_crosstalk = std::numeric_limits<double>::quiet_NaN();
  double column_crosstalk_uncertainty = std::numeric_limits<double>::quiet_NaN();
  std::filesystem::path bad_pixels;  // empty when none
};

// Reads a detector file (Error naming the file and key).
DetectorFile loadDetectorFile(const std::filesystem::path& path);
// The bad-pixel map `bad_pixels.json` (written beside the detector file by
// xgauge characterize: {columns, rows, dead, hot, noisy: [[u, v], ...]})
// as a mask, 1 where a pixel is dead, hot or noisy. Error naming the file
// and key when its size is not columns x rows or a pixel lies outside it.
ImageT<uint8_t> loadBadPixelMask(const std::filesystem::path& path, int columns, int rows);
// The detector file the machine file names, if it names one.
std::optional<DetectorFile> detectorFileOf(const std::filesystem::path& machine_file);

}  // namespace xgauge
