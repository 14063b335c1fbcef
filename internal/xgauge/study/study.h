// `xgauge study`: the thesis's statistics generator
// (docs/method.md). For a simulated dataset
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

#include "xgauge/measure/inputs.h"
#include "xgauge/measure/truth.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
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
  bool report = true;   // write report.html (report/html.h) beside study.json
  // --shard i/N: only runs i-1, i-1+N, ... (0-based), for a scheduler's
  // array tasks sharing one output folder; no study.csv, study.json or
  // report.html then: a run without a shard over the same folder gathers
  // the shards' runs (each run's result is kept) and writes them.
  int shard_index = 1, shard_count = 1;
};

struct StudyRun {
  std::string id;                          // e.g. "t00-t03" or "t00-t03+r02"
  std::map<std::string, double> error_mm;  // measured - true, free dimensions
  // The expanded uncertainty U (k = 2) of each free dimension the run could
  // determine (absent: not identifiable), and the measurable combinations it
  // reported (expression -> error, U).
  std::map<std::string, double> expanded_mm;
  std::map<std::string, std::pair<double, double>> combinations;
  // With the material refined in situ (job "refine_material"): the rate
  // scale the run found and its standard uncertainty.
  std::optional<std::pair<double, double>> rate_scale;
  double seconds = 0.0;
  // Why the run is not a measurement (measure/self_check.h, AcceptanceRule);
  // empty when it measured. Such a run has no errors and enters no figure
  // but the count of runs that measured.
  std::vector<std::string> failures;
  bool measured() const { return failures.empty(); }
};

// How honest the uncertainties of a set of runs are: the mean U, the
// coverage (fraction of runs with |error| <= U; about 95 % for an honest U
// with k = 2) and the mean normalised error |e| / U.
struct CoverageFigures {
  int runs = 0;  // runs with a U
  double mean_u = 0.0, coverage = 0.0, mean_normalised = 0.0;
  double mean_abs = 0.0;
};

struct StudySummary {
  std::vector<std::string> dimensions;  // free dimensions, model order
  std::vector<StudyRun> runs;
  std::map<std::string, double> mean_abs_mm, max_abs_mm;
  double mean_abs_mm_all = 0.0, max_abs_mm_all = 0.0;
  // Per free dimension, per measurable combination, and pooled over every
  // dimension of every run that has a U.
  std::map<std::string, CoverageFigures> coverage, combination_coverage;
  CoverageFigures pooled;
  double median_seconds = 0.0;
  int measured_runs = 0;  // of runs.size(); the others failed the acceptance rule
  // The thesis-style table as text.
  std::string table() const;
};

// Runs (or resumes) the study; writes runs/<id>/, study.csv and study.json
// into options.output.
StudySummary runStudy(const StudyOptions& options);

// The pieces every run of a study shares, loaded once: the dataset's part
// model and machine, and the material (fitted to the dataset's transmission
// table unless the settings name a file).
struct StudyInputs {
  // The model every run fits: the settings' "part" where they name one (a
  // model of the same part with the same dimension names, such as one on
  // its STEP file), else the dataset's.
  std::filesystem::path part_file;
  std::shared_ptr<const PartModel> part;
  Machine machine;
  ExponentialSum material{{{1.0, 0.0}}, ""};
  // The detector's scatter the material file carries (a wedge calibration's),
  // for settings without a "scatter" of their own: every run then takes it
  // from the material, as a measurement job does (measure/inputs.h), and
  // its budget moves it together with the curve when the file says how.
  std::optional<MaterialScatter> material_scatter;
  // The SHA-256 of the files every run's job names (the part model, and
  // where runStudy wrote them, the machine and the material), keyed as the
  // jobs name them: a run's verification holds only for the same bytes.
  std::map<std::string, std::string> file_sha256;
};
// The material as the study records it (material.json in its folder, which
// every run's job.json names): the curve and the scatter it carries.
nlohmann::json materialRecord(const StudyInputs& inputs);
StudyInputs prepareStudyInputs(const DatasetTruth& truth, const nlohmann::json& settings,
                               const std::filesystem::path& settings_file);

// The dataset's radiographs, each read and prepared once however many runs
// use it (thread-safe; every shot shares the dataset's dark and flat frames).
class PreparedShots {
 public:
  explicit PreparedShots(const Machine& machine) : machine_(machine) {}
  std::shared_ptr<const PreparedRadiograph> get(const RadiographSpec& spec);
  std::map<std::string, std::string> sha256() const;

 private:
  const Machine& machine_;
  mutable std::mutex mutex_;
  std::optional<Image> dark_, flat_;
  std::optional<OpenBeamField> open_beam_;  // the flat's, fitted once
  std::map<std::string, std::shared_ptr<const PreparedRadiograph>> prepared_;
  std::map<std::string, std::string> sha256_;
};

// A job (as JSON, also written as each run's record) measuring `shots` of
// the dataset: the first free, the others translated (or rotated) from it,
// or with `turned` turned on the dataset's turntable by the difference of
// their nominal angles; it names the machine and material files the study
// wrote as records.
nlohmann::json studyJob(const nlohmann::json& settings, const DatasetTruth& truth,
                        const std::filesystem::path& part_file,
                        const std::vector<std::string>& shots, const std::string& id,
                        const std::filesystem::path& machine_file,
                        const std::filesystem::path& material_file, bool turned = false);
// The inputs of one run: the job parsed and checked against the part model,
// the shared part, machine and material, and its prepared shots.
MeasurementInputs studyRunInputs(const nlohmann::json& job, const StudyInputs& inputs,
                                 const std::filesystem::path& settings_file, PreparedShots& shots);

}  // namespace xgauge
