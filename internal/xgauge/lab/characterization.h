// The replica lab's characterisation session: the shots a lab takes once
// per set-up to qualify its flat panel (docs/method.md, "Detector
// characterisation"), on the same detector as a dataset's shots, for
// `xgauge characterize`:
//
//   darks/dark_NNN.tif, flats/flat_NNN.tif   single frames, beam off and open
//   edge.tif         an opaque plate over the panel's left 40 %, its edge
//                    slanted by 3 degrees: behind it the halo alone
//   crosstalk.tif    an opaque plate over the top-left quadrant
//   lag_bright.tif   an open frame after a rest,
//   lag_dark_after_bright.tif  then a beam-off frame right after it
//   characterize.json          the job that reads them
//
// The plates are ideal (transmission 0); each frame goes through the same
// physics as the dataset's shots (scatter, column darkening, ghosting,
// noise, gain, dark).
#pragma once

#include "xgauge/lab/detector.h"
#include "xgauge/xray/machine.h"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace xgauge {

struct CharacterizationPlan {
  int frames = 8;  // darks and flats each
};

// What the shots' physics needs of the acquisition besides the detector.
struct CharacterizationPhysics {
  bool scatter = false;
  double scatter_weight = 0.0, scatter_sigma_px = 0.0;
  double column_darkening = 0.0;
  bool quantize_16bit = true;
};

// Writes the session into `folder` (created; existing files replaced) and
// returns its truth entry (the folder, the job, the halo, lag and column
// darkening the frames were made with). `machine_file` is written into the
// job as an absolute path.
nlohmann::json simulateCharacterization(const CharacterizationPlan& plan, const Machine& machine,
                                        const std::filesystem::path& machine_file,
                                        const DetectorPattern& pattern,
                                        const DetectorNoiseModel& noise,
                                        const CharacterizationPhysics& physics, uint64_t seed,
                                        const std::filesystem::path& folder);

}  // namespace xgauge
