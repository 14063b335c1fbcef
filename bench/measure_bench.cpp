// Measurement speed and accuracy (issue: measurement). Run from the
// repository root: build/bench/measure_bench [dataset folder]
//
// On replica prism_a at 4096^2 (simulated into data/prism_a first if
// missing), on this machine's cores: the wall time of three 2-radiograph
// measurements with the default schedule (pairs t00-t03, t01-t04, t02-t05),
// their median, and in the same run the thesis's schedule on t00-t03; both
// times, their ratio, and both errors (mean and max |error| over the 8
// dimensions).
#include "xgauge/core/config.h"
#include "xgauge/core/log.h"
#include "xgauge/core/progress.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/study/study.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

namespace fs = std::filesystem;
using namespace xgauge;

namespace {

struct Run {
  double seconds;
  double mean_abs_mm;
  double max_abs_mm;
};

// The bench's jobs name the study's record files but never read them: every
// input is loaded once, in memory.
Run measureShots(const nlohmann::json& settings, const DatasetTruth& truth, const StudyInputs& inputs,
                 PreparedShots& prepared, const std::vector<std::string>& shots,
                 const fs::path& settings_file) {
  const std::string id = shots[0] + "-" + shots[1];
  const nlohmann::json job = studyJob(settings, truth, shots, id, "machine.json", "material.json");
  const MeasurementInputs run_inputs = studyRunInputs(job, inputs, settings_file, prepared);
  const auto start = std::chrono::steady_clock::now();
  ForwardModel model(run_inputs);
  const MeasurementResult result = measure(model, model.start());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double sum = 0.0, worst = 0.0;
  for (const auto& d : result.dimensions) {
    const double e = std::abs(d.value - truth.dimensions.at(d.name));
    sum += e, worst = std::max(worst, e);
  }
  return {seconds, sum / static_cast<double>(result.dimensions.size()), worst};
}

}  // namespace

int main(int argc, char** argv) {
  try {
    setupLogging(Verbosity::kQuiet);
    setProgressEnabled(false);
    const fs::path dataset = argc > 1 ? fs::path(argv[1]) : fs::path("data/prism_a");
    if (!fs::exists(dataset / "truth.json")) {
      std::printf("simulating %s (about 35 s)...\n", dataset.c_str());
      simulateDataset(Recipe::load("datasets/prism_a.json"), dataset);
    }
    const DatasetTruth truth = DatasetTruth::load(dataset / "truth.json");
    const fs::path settings_file = "examples/study_prism_a.json";
    nlohmann::json settings = ConfigNode::loadFile(settings_file).json();
    const StudyInputs inputs = prepareStudyInputs(truth, settings, settings_file);
    PreparedShots prepared(inputs.machine);

    std::vector<Run> runs;
    for (const auto& pair : std::vector<std::vector<std::string>>{{"t00", "t03"}, {"t01", "t04"}, {"t02", "t05"}}) {
      runs.push_back(measureShots(settings, truth, inputs, prepared, pair, settings_file));
      std::printf("default schedule, %s-%s: %.1f s, mean |error| %.4f mm, max %.4f mm\n", pair[0].c_str(),
                  pair[1].c_str(), runs.back().seconds, runs.back().mean_abs_mm, runs.back().max_abs_mm);
    }
    std::vector<double> times;
    for (const auto& r : runs) times.push_back(r.seconds);
    std::sort(times.begin(), times.end());
    const double median = times[times.size() / 2];

    settings["schedule"] = "thesis";
    const Run thesis = measureShots(settings, truth, inputs, prepared, {"t00", "t03"}, settings_file);
    std::printf("thesis schedule,  t00-t03: %.1f s, mean |error| %.4f mm, max %.4f mm\n", thesis.seconds,
                thesis.mean_abs_mm, thesis.max_abs_mm);
    std::printf("\nmedian time per 2-radiograph measurement (default): %.1f s (target <= 30 s; thesis GPU: 136 s)\n",
                median);
    std::printf("thesis schedule / default schedule on t00-t03: %.1f s / %.1f s = %.2f\n", thesis.seconds,
                runs[0].seconds, thesis.seconds / runs[0].seconds);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "measure_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
