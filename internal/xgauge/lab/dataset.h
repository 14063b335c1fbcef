// Simulating a dataset: every shot of a recipe as a raw 16-bit radiograph,
// with dark and flat frames and the ground truth, as a real X-ray session
// would record it (and more faithfully than the model xgauge fits: a real
// spectrum, area sampling, focal spot, scintillator scatter, noise and
// detector artefacts).
//
// Files written into the output folder, each atomically:
//   <shot>.tif   raw detector image, 16-bit ADU
//   dark.tif     dark frame, averaged over detector.flat_frames, 32-bit float ADU
//   flat.tif     open-beam frame, averaged likewise, 32-bit float ADU
//   truth.json   written last: recipe, seed, machine, beam, material, part and its
//                true dimensions, every shot's exact pose (Euler and 4x4), the
//                translation distances, the polychromatic transmission table
//                T(path), a white region for normalization, and the dead pixels
#pragma once

#include "xgauge/lab/recipe.h"

#include <filesystem>

namespace xgauge {

struct DatasetReport {
  int shots = 0;
  double seconds = 0.0;            // total wall time
  double seconds_per_shot = 0.0;   // mean wall time of one shot (render to file)
  PixelRect white_region;
};

// Simulates `recipe` into `folder` (created if missing). Shows a progress bar.
// The same recipe and seed give bit-identical files at any thread count.
DatasetReport simulateDataset(const Recipe& recipe, const std::filesystem::path& folder);

}  // namespace xgauge
