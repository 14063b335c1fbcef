// A production lot in the virtual lab: N parts of one part model whose
// dimensions come from a process (nominal, per-dimension sigma, an optional
// drift from part k on with a slope per part, an optional step), each taken
// with the recipe's acquisition, its pose jittered as a loader would place
// it, written as one folder per part with a manifest (core/manifest.h).
//
// A lot recipe is a dataset recipe (lab/recipe.h) with a "lot" section:
//   name            the lot's name (default: the output folder's name)
//   parts           N, 1 .. 100000
//   start_time      the first part's acquisition time, UTC ISO 8601
//                   (default 2026-01-01T06:00:00Z); part k at start + (k - 1) interval
//   interval_s      seconds between parts (default 60)
//   process         {dimension: {"sigma": s, "drift": {"from_part": k, "per_part": d},
//                    "step": {"from_part": k, "by": b}}}: part k's true value is the
//                   recipe's true value (its nominal here) + N(0, s)
//                   + d (k - from + 1) for k >= drift.from_part + b for k >= step.from_part.
//                   Dimensions not named stay at the recipe's value.
//   pose_jitter     {"rotation_deg": r, "translation_mm": t}: each part is placed
//                   turned by N(0, r) about a random axis through its bounding-box
//                   centre and moved by N(0, t) along each axis, the same for all its
//                   shots (the stage then moves it as the recipe says). Default 0.
//
// Output folder: parts/p0001/ ... parts/pNNNN/ with the shots' raw TIFFs,
// dark.tif, flat.tif and manifest.json (written last): the folder of part
// folders `xgauge inspect` reads; truth/pNNNN.json, each part's dataset
// truth (lab/dataset.h); truth.json, the lot's truth (every part's
// dimensions, seed, time and jitter), written last. A part folder whose
// manifest is complete is kept, so an interrupted lot resumes.
#pragma once

#include "xgauge/lab/recipe.h"

#include <filesystem>
#include <optional>
#include <string>

namespace xgauge {

struct LotReport {
  int parts = 0, simulated = 0;  // all, and made by this call (the others were there)
  double seconds = 0.0;
};

// Whether the recipe has a "lot" section.
bool isLotRecipe(const Recipe& recipe);

// Simulates the lot into `folder` (created if missing), part after part:
// each part's folder appears complete, manifest last, so `xgauge inspect
// --watch` can take it while the next is being made. The same recipe gives
// bit-identical files.
LotReport simulateLot(const Recipe& recipe, const std::filesystem::path& folder);

}  // namespace xgauge
