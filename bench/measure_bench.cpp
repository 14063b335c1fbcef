// Measurement speed and accuracy (issues: measurement; analytic derivatives).
// Run from the repository root: build/bench/measure_bench [dataset folder]
// [--thesis | --renders]
//
// On replica prism_a at 4096^2 (simulated into data/prism_a first if
// missing), on this machine's cores, in one run:
// - three 2-radiograph measurements (pairs t00-t03, t01-t04, t02-t05) with
//   the default schedule (the joint fit on the render's derivatives, then
//   least squares on refined renders), the same three with `bobyqa` (the
//   previous default: derivative-free BOBYQA joint stages) and with
//   `gauss-newton` (every stage on the render's derivatives): each one's
//   wall time with and without the uncertainty budget, its renders (and how
//   many with derivatives) and its errors (mean and max |error| over the 8
//   dimensions); the medians and their ratios to the default's;
// - the time of one evaluation of the residuals of both radiographs at the
//   final stage's level, without and with the derivatives of the 16
//   parameters, with point samples and with the edges refined;
// - what a measurement costs a lab besides itself, on the first default
//   pair: reading and preparing its radiographs from the files (as a
//   command's first run does; the measurements above reuse them) and
//   writing its outputs (simulated and difference images, report page);
// - with --thesis, the thesis's schedule on t00-t03 too; with --renders,
//   only the default on t00-t03 and the evaluation times.
#include "xgauge/core/config.h"
#include "xgauge/core/log.h"
#include "xgauge/core/memory.h"
#include "xgauge/core/progress.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/schedule.h"
#include "xgauge/report/measurement.h"
#include "xgauge/study/study.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>

namespace fs = std::filesystem;
using namespace xgauge;

namespace {

struct Run {
  double seconds;      // the whole measurement
  double fit_seconds;  // without the uncertainty budget and self-checks
  int renders;
  int with_derivatives;
  double mean_abs_mm;
  double max_abs_mm;
};

// The bench's jobs name the study's record files but never read them: every
// input is loaded once, in memory.
Run measureShots(const nlohmann::json& settings, const DatasetTruth& truth,
                 const StudyInputs& inputs, PreparedShots& prepared,
                 const std::vector<std::string>& shots, const fs::path& settings_file,
                 std::vector<double>* solution = nullptr,
                 std::optional<MeasurementInputs>* kept = nullptr, const fs::path& outputs = {}) {
  const std::string id = shots[0] + "-" + shots[1];
  const nlohmann::json job = studyJob(settings, truth, truth.part_file, shots, id, "machine.json", "material.json");
  MeasurementInputs run_inputs = studyRunInputs(job, inputs, settings_file, prepared);
  const auto start = std::chrono::steady_clock::now();
  ForwardModel model(run_inputs);
  // As `xgauge measure` runs it: the full-size losses come with the outputs.
  MeasureOptions options;
  options.full_size_losses = false;
  MeasurementResult result = measure(model, model.start(), options);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!outputs.empty()) {
    const auto written = std::chrono::steady_clock::now();
    std::vector<Image> simulated = simulateRadiographs(model, result.theta);
    takeFullSizeLosses(model, simulated, result);
    writeMeasurementOutputs(model, result, outputs, true, nullptr, std::move(simulated));
    std::printf("writing its outputs (%s): %.2f s\n", outputs.c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - written).count());
  }
  Run run{seconds, 0.0, 0, 0, 0.0, 0.0};
  for (const StageReport& stage : result.stages) {
    run.fit_seconds += stage.seconds;
    run.renders += stage.evaluations;
    run.with_derivatives += stage.with_derivatives;
  }
  double sum = 0.0, worst = 0.0;
  for (const auto& d : result.dimensions) {
    const double e = std::abs(d.value - truth.dimensions.at(d.name));
    sum += e, worst = std::max(worst, e);
  }
  run.mean_abs_mm = sum / static_cast<double>(result.dimensions.size());
  run.max_abs_mm = worst;
  if (solution) *solution = result.theta;
  if (kept) kept->emplace(std::move(run_inputs));
  return run;
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

void print(const char* schedule, const std::vector<std::string>& pair, const Run& r) {
  std::printf(
      "%-12s %s-%s: %5.1f s (fit %5.1f s, budget %5.1f s), %5d renders (%3d with derivatives), "
      "mean |error| %.4f mm, max %.4f mm\n",
      schedule, pair[0].c_str(), pair[1].c_str(), r.seconds, r.fit_seconds,
      r.seconds - r.fit_seconds, r.renders, r.with_derivatives, r.mean_abs_mm, r.max_abs_mm);
}

// Median seconds of `repeat` calls of `f`.
template <typename F>
double timed(int repeat, F&& f) {
  std::vector<double> times;
  for (int i = 0; i < repeat; ++i) {
    const auto start = std::chrono::steady_clock::now();
    f();
    times.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return median(times);
}

}  // namespace

int main(int argc, char** argv) {
  keepLargeBlocksInHeap();  // as the command line does (core/memory.h)
  try {
    setupLogging(Verbosity::kQuiet);
    setProgressEnabled(false);
    // [dataset folder] [--thesis | --renders]: anything else, or a flag in
    // the folder's place, is refused (`--help` once became a folder of
    // 437 MB of simulated radiographs).
    const std::string usage =
        "usage: measure_bench [dataset folder, default data/prism_a] [--thesis | --renders]";
    const bool help =
        argc > 1 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h");
    if (help || argc > 3 || (argc > 1 && std::string(argv[1]).starts_with("-")) ||
        (argc > 2 && std::string(argv[2]) != "--thesis" && std::string(argv[2]) != "--renders")) {
      std::fprintf(help ? stdout : stderr, "%s\n", usage.c_str());
      return help ? 0 : 2;
    }
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

    const bool renders_only = argc > 2 && std::string(argv[2]) == "--renders";
    std::vector<std::vector<std::string>> pairs{{"t00", "t03"}, {"t01", "t04"}, {"t02", "t05"}};
    if (renders_only) pairs.resize(1);
    std::map<std::string, std::vector<Run>> runs;
    std::vector<double> solution;
    std::optional<MeasurementInputs> first_inputs;
    std::vector<std::string> schedules{"default", "bobyqa", "gauss-newton"};
    if (renders_only) schedules.resize(1);
    {
      // Reading and preparing the first pair's radiographs, as a first run
      // does (the runs below share `prepared`, which this fills).
      settings["schedule"] = schedules.front();
      const nlohmann::json job =
          studyJob(settings, truth, truth.part_file, pairs.front(), "load", "machine.json",
                   "material.json");
      const auto start = std::chrono::steady_clock::now();
      studyRunInputs(job, inputs, settings_file, prepared);
      std::printf("reading and preparing %s and %s: %.2f s\n", pairs.front()[0].c_str(),
                  pairs.front()[1].c_str(),
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    const fs::path outputs = fs::temp_directory_path() / "xgauge_measure_bench_outputs";
    for (const std::string& schedule : schedules) {
      settings["schedule"] = schedule;
      for (const auto& pair : pairs) {
        const bool keep = runs[schedule].empty() && schedule == "default";
        runs[schedule].push_back(measureShots(
            settings, truth, inputs, prepared, pair, settings_file, keep ? &solution : nullptr,
            keep ? &first_inputs : nullptr, keep ? outputs : fs::path()));
        print(schedule.c_str(), pair, runs[schedule].back());
      }
    }
    std::error_code ignored;
    fs::remove_all(outputs, ignored);
    if (argc > 2 && std::string(argv[2]) == "--thesis") {
      settings["schedule"] = "thesis";
      print("thesis", pairs[0],
            measureShots(settings, truth, inputs, prepared, pairs[0], settings_file));
    }

    auto medianOf = [&](const std::string& schedule, auto field) {
      std::vector<double> values;
      for (const Run& r : runs[schedule]) values.push_back(field(r));
      return median(values);
    };
    const double base = medianOf("default", [](const Run& r) { return r.seconds; });
    const double base_fit = medianOf("default", [](const Run& r) { return r.fit_seconds; });
    std::printf("\nmedians per 2-radiograph measurement (ratio: its time over the default's):\n");
    for (const std::string& schedule : schedules) {
      const double seconds = medianOf(schedule, [](const Run& r) { return r.seconds; });
      const double fit = medianOf(schedule, [](const Run& r) { return r.fit_seconds; });
      std::printf(
          "%-12s %5.1f s (ratio %.2f), fit alone %5.1f s (ratio %.2f), %5.0f renders (%.0f with "
          "derivatives), mean |error| %.4f mm\n",
          schedule.c_str(), seconds, seconds / base, fit, fit / base_fit,
          medianOf(schedule, [](const Run& r) { return r.renders; }),
          medianOf(schedule, [](const Run& r) { return r.with_derivatives; }),
          medianOf(schedule, [](const Run& r) { return r.mean_abs_mm; }));
    }

    // One evaluation of both radiographs' residuals at the final stage's
    // level, without and with the derivatives of every joint parameter.
    ForwardModel model(*first_inputs);
    const Schedule& schedule = scheduleFor(ScheduleKind::kDefault);
    const LeastSquaresStage& ls = schedule.least_squares;
    const int level = leastSquaresLevel(model, schedule);
    const std::vector<int> both{0, 1};
    const std::vector<int> joint = model.jointIndices();
    std::vector<double> r, j;
    for (int edges : {0, ls.edge_samples}) {
      model.setEdgeSamples(edges);
      const double plain = timed(5, [&] { model.residuals(solution, level, ls.samples, both, r); });
      const double with = timed(
          5, [&] { model.residualsAndJacobian(solution, joint, level, ls.samples, both, r, j); });
      std::printf(
          "residuals of both radiographs at %d px, %d x %d samples%s: %.3f s; with the "
          "derivatives of %zu parameters: %.3f s (%.1f x)\n",
          model.radiograph(0).levels[static_cast<size_t>(level)].width(), ls.samples, ls.samples,
          edges > 0 ? fmt::format(", edges {} x {}", edges, edges).c_str() : "", plain,
          joint.size(), with, with / plain);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "measure_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
