// Wedge calibration speed and accuracy (issue: calibration in under a
// minute). Run from the repository root:
//   build/bench/calibrate_bench [dataset folder] [--verbose]
//
// The replica of a lab's 3072^2 wedge shot (datasets/wedge_3072.json,
// simulated into data/wedge_3072 first if missing, about two minutes): the
// wedge block at magnification 3.83 filling about 72 % of the width of a
// panel of 0.139 mm pixels, a scatter halo and a previous frame's lag.
// Runs its job, examples/calibrate_wedge_3072.json (the wedge fitted as a
// known part, the scatter estimated), on the dataset's files, on this
// machine's cores, and prints:
// - the total wall time and each step's;
// - the pose found against the lab's, the scatter found against the lab's;
// - the curve's largest deviation from the lab's true curve (truth.json's
//   transmission table) over the calibrated range, 0 .. the longest path,
//   as `xgauge calibrate wedge --truth` reports it, against the curve's
//   stated standard uncertainty.
// --verbose: the calibration's log, with timestamps.
//
// Last, the same figures of this calibration before its speed-up (kBefore:
// main at 72676af on the 2-core development machine, whose known-part fit
// searched the pose at 192 px and refined it at 384 and 768 px, ran
// BOBYQA joint stages at 768 and 1536 px and least squares on forward
// differences at 1536 px after the pose search, after the free curve and
// after each of its always-run tilt retries, and read its tables from the
// full 3072^2 image), and the ratio. docs/method.md, "The wedge fitted as a
// known part", says what the calibration does now.
#include "xgauge/calibrate/wedge.h"
#include "xgauge/core/log.h"
#include "xgauge/core/memory.h"
#include "xgauge/core/progress.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/recipe.h"
#include "xgauge/measure/truth.h"

#include <fmt/format.h>

#include <sys/resource.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;
using namespace xgauge;

namespace {

// This bench on main at 72676af, before the calibration's speed-up, on the
// 2-core development machine (shared: its CPU seconds are the steadier
// figure): the total, the steps and the curve.
struct BeforeStep {
  const char* step;
  double seconds;
};
struct Before {
  double seconds, cpu_seconds;
  double deviation, at_mm, uncertainty;
  std::array<BeforeStep, 10> steps;
};
constexpr Before kBefore{698.0,
                         1123.7,
                         0.00109,
                         0.15,
                         0.00205,
                         {{{"normalize the radiograph", 0.8},
                           {"estimate the scatter around the box of the edges", 0.8},
                           {"the poses with the initial material", 78.2},
                           {"the poses with a free curve", 131.3},
                           {"the tilts searched again", 297.1},
                           {"the scatter around the posed wedge", 1.2},
                           {"round 1", 170.5},
                           {"round 2", 14.0},
                           {"the final table and curve", 0.3},
                           {"the curve's uncertainty", 3.9}}}};

// This process's CPU seconds so far (user and system, every thread).
double cpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

}  // namespace

int main(int argc, char** argv) {
  keepLargeBlocksInHeap();  // as the command line does (core/memory.h)
  try {
    const std::string usage =
        "usage: calibrate_bench [dataset folder, default data/wedge_3072] [--verbose]";
    fs::path dataset = "data/wedge_3072";
    bool verbose = false, folder_given = false;
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--help" || arg == "-h") {
        std::printf("%s\n", usage.c_str());
        return 0;
      }
      if (arg == "--verbose") {
        verbose = true;
      } else if (!arg.starts_with("-") && !folder_given) {
        dataset = arg, folder_given = true;
      } else {
        std::fprintf(stderr, "%s\n", usage.c_str());
        return 2;
      }
    }
    setupLogging(verbose ? Verbosity::kVerbose : Verbosity::kQuiet);
    if (verbose) spdlog::set_pattern("[%T.%e] %^[%l]%$ %v");
    setProgressEnabled(false);
    if (!fs::exists(dataset / "truth.json")) {
      std::printf("simulating %s (about two minutes)...\n", dataset.c_str());
      simulateDataset(Recipe::load("datasets/wedge_3072.json"), dataset);
    }
    const DatasetTruth truth = DatasetTruth::load(dataset / "truth.json");
    WedgeCalibrationJob job = WedgeCalibrationJob::load("examples/calibrate_wedge_3072.json");
    // The job names data/wedge_3072: the dataset's own files instead.
    RadiographSpec& spec = job.radiograph;
    for (fs::path* file : {&spec.image, &spec.dark, &spec.flat, &spec.previous})
      *file = dataset / file->filename();

    const double cpu_start = cpuSeconds();
    const auto start = std::chrono::steady_clock::now();
    const WedgeCalibration result = calibrateFromWedge(job);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double cpu = cpuSeconds() - cpu_start;

    std::printf(
        "wedge calibration of %s (%dx%d): %.1f s (%.1f CPU seconds: %.2f cores busy on "
        "average)\n",
        spec.image.c_str(), job.machine.columns, job.machine.rows, seconds, cpu, cpu / seconds);
    for (const StepSeconds& step : result.step_seconds)
      std::printf("  %7.1f s  %s\n", step.seconds, step.step.c_str());
    if (result.part) {
      const Pose& pose = result.part->measurement.radiographs.front().pose;
      const Pose& lab = truth.shot("calibration").pose;
      const Vec3 a = pose.eulerDeg(), b = lab.eulerDeg();
      std::printf(
          "pose: rotation (%.3f, %.3f, %.3f) deg, origin (%.3f, %.3f, %.3f) mm; the lab's (%.3f, "
          "%.3f, %.3f) deg, (%.3f, %.3f, %.3f) mm; %zu rounds\n",
          a.x(), a.y(), a.z(), pose.translation_mm.x(), pose.translation_mm.y(),
          pose.translation_mm.z(), b.x(), b.y(), b.z(), lab.translation_mm.x(),
          lab.translation_mm.y(), lab.translation_mm.z(), result.part->rounds.size());
    }
    if (result.halo)
      std::printf("scatter: weight %.4f +- %.2g, sigma %.1f +- %.2g mm\n", result.scatter.weight,
                  result.scatter.weight_uncertainty, result.scatter.sigma_mm,
                  result.scatter.sigma_uncertainty_mm);
    std::string curve = "I(x) =";
    for (size_t k = 0; k < result.material.terms().size(); ++k)
      curve += fmt::format("{} {:.5f} exp(-{:.5f} x)", k ? " +" : "",
                           result.material.terms()[k].weight, result.material.terms()[k].mu_per_mm);
    std::printf("%s\n", curve.c_str());
    const TrueCurve lab{truth.path_mm, truth.transmission};
    const CurveDeviation deviation = curveDeviation(
        [&](double x) { return result.material.transmission(x); }, lab, result.x_max_mm);
    const double u = result.material.transmissionUncertainty();
    std::printf(
        "against the true curve: largest deviation %.5f at %.2f mm over 0 .. %.2f mm; the "
        "curve's standard uncertainty %.5f (table %.5f)\n",
        deviation.max_abs, deviation.at_mm, result.x_max_mm, u, result.table_uncertainty);
    for (const CurveInfluence& i : result.influences)
      std::printf("  %.5f from the %s\n", i.change, i.name.c_str());
    std::printf(
        "\nbefore (main at 72676af, this machine): %.1f s (%.1f CPU seconds), the curve %.5f off "
        "at %.2f mm, its standard uncertainty %.5f\n",
        kBefore.seconds, kBefore.cpu_seconds, kBefore.deviation, kBefore.at_mm,
        kBefore.uncertainty);
    for (const BeforeStep& step : kBefore.steps)
      std::printf("  %7.1f s  %s\n", step.seconds, step.step);
    std::printf("now %.1f times faster (%.1f times fewer CPU seconds)\n", kBefore.seconds / seconds,
                kBefore.cpu_seconds / cpu);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
