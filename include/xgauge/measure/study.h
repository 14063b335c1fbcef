// `xgauge study`: the thesis's statistics generator. For a simulated dataset
// (truth.json), measure every combination of shots asked for and tabulate the
// errors against the truth: mean and max |error| per dimension and overall.
//
// Settings JSON: a measurement job (measure/job.h) without part, machine and
// radiographs, which come from the dataset; "material" may be "fit" (default):
// three exponentials fitted to the dataset's transmission table.
// Combinations:
//   pairs            every pair (a, b) of translated shots: a free, b translated
//                    from a by the exact distance between them
//   pairs+rotated    every pair plus one rotated shot (all but the first, ~0 deg)
// Runs are independent and run in parallel; a run whose result.json exists is
// not run again, so an interrupted study resumes where it stopped.
#pragma once

#include "xgauge/measure/truth.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace xgauge {

struct StudyOptions {
  std::filesystem::path dataset;   // folder with truth.json
  std::filesystem::path settings;  // study settings (JSON)
  std::string combinations = "pairs";
  int limit = 0;  // 0 = all runs; else the first `limit`
  std::filesystem::path output;
  bool images = false;  // also write simulated and difference images per run
};

struct StudyRun {
  std::string id;                          // e.g. "t00-t03" or "t00-t03+r02"
  std::map<std::string, double> error_mm;  // measured - true, free dimensions
  double seconds = 0.0;
};

struct StudySummary {
  std::vector<std::string> dimensions;  // free dimensions, model order
  std::vector<StudyRun> runs;
  std::map<std::string, double> mean_abs_mm, max_abs_mm;
  double mean_abs_mm_all = 0.0, max_abs_mm_all = 0.0;
  double median_seconds = 0.0;
  // The thesis-style table as text.
  std::string table() const;
};

// Runs (or resumes) the study; writes runs/<id>/, study.csv and study.json
// into options.output.
StudySummary runStudy(const StudyOptions& options);

// The pieces a study builds its jobs from, for other drivers (benchmarks):
// the dataset's machine and the material (fitted unless the settings name
// one), written into `folder`.
struct StudyInputs {
  std::filesystem::path machine, material;
};
StudyInputs prepareStudyInputs(const DatasetTruth& truth, const nlohmann::json& settings,
                               const std::filesystem::path& settings_file,
                               const std::filesystem::path& folder);
// A job measuring `shots` of the dataset: the first free, the others
// translated (or rotated) from it.
nlohmann::json studyJob(const nlohmann::json& settings, const DatasetTruth& truth,
                        const std::vector<std::string>& shots, const StudyInputs& inputs,
                        const std::string& id);

}  // namespace xgauge
