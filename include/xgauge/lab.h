// xgauge's virtual lab from code: datasets of raw radiographs with their
// ground truth simulated from a recipe, a material fitted to a dataset's
// true transmission, and measurement studies over a dataset's shots. In the
// style of xgauge/xgauge.h: an options struct, one call, a summary whose
// termination and message say how it ended. Needs only the C++ standard
// library; nothing here throws for bad input. docs/formats.md describes the
// recipes, settings and outputs.
#pragma once

#include "xgauge/runtime.h"

#include <cstddef>
#include <filesystem>
#include <string>

namespace xgauge {

// A dataset (raw radiographs, dark, flat, truth.json) or, for a lot recipe,
// one folder per part, from a recipe.
struct SimulationOptions {
  std::filesystem::path recipe;         // e.g. datasets/prism_a.json
  std::filesystem::path output_folder;  // created if missing
};

struct SimulationSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;                 // kFailure: why
  bool lot = false;                    // a lot recipe: parts, each in its own folder
  int shots = 0;                       // a dataset's
  int parts = 0, parts_simulated = 0;  // a lot's: all, and made by this call
  double seconds = 0.0;
};

SimulationSummary simulate(const SimulationOptions& options);

// An exponential-sum material fitted to a virtual lab's transmission table.
struct MaterialFitOptions {
  std::filesystem::path truth_file;  // truth.json of a simulated dataset
  // The fewest exponentials; more are added, up to 8, until the largest
  // residual over the paths the shots show is at most 1e-4.
  int terms = 3;
  std::filesystem::path output_file;  // the material (JSON)
};

struct MaterialFitSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;      // kFailure: why
  std::string description;  // the material, in words
};

MaterialFitSummary fitMaterial(const MaterialFitOptions& options);

// Every combination of a simulated dataset's shots measured, the errors
// tabulated (study.csv, study.json, report.html).
struct MeasurementStudyOptions {
  std::filesystem::path dataset;        // folder with truth.json
  std::filesystem::path settings;       // a job without radiographs (JSON)
  std::string combinations = "pairs";   // pairs, pairs+rotated or turned-pairs
  int limit = 0;                        // only the first N runs; 0: all
  std::filesystem::path output_folder;  // resumes a study already there
  bool images = false;  // each run's simulated and difference images and report.html
  bool report = true;   // report.html, the study's report
  // Empty, or "i/N": only every N-th run from the i-th (array tasks sharing
  // one output folder; a call without a shard then gathers them).
  std::string shard;
};

struct MeasurementStudySummary {
  RunTermination termination = RunTermination::kFailure;
  // kFailure: why; otherwise what was written, in words.
  std::string message;
  std::size_t runs = 0;
  std::string table;  // the errors' table (empty for a shard)
};

MeasurementStudySummary study(const MeasurementStudyOptions& options);

}  // namespace xgauge
