// What a measurement writes for people and scripts: result.json (the
// machine-readable truth), the final simulated radiographs and the
// difference images. docs/formats.md documents every key.
#pragma once

#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"

#include <filesystem>

namespace xgauge {

// Writes result.json (with the SHA-256 of every input as it was read), the
// final simulated radiographs and the difference images (float TIFF and
// diverging-colour PNG) into `folder`, each file atomically, from the model
// that measured.
void writeMeasurementOutputs(ForwardModel& model, const MeasurementResult& result,
                             const std::filesystem::path& folder);

// The contents of result.json (docs/formats.md): dimensions with their U,
// tolerances and verdicts, the uncertainty budget, the self-checks' warnings
// and residual regions, poses, stages and the inputs' SHA-256.
nlohmann::json measurementJson(const ForwardModel& model, const MeasurementResult& result);

}  // namespace xgauge
