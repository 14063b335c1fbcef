// How long a view plan takes (issue: where to put the part). Run from the
// repository root: build/bench/plan_bench
//
// Prism A on the replica cabinet at 1024^2 (examples/machine_1024.json, the
// monochromatic aluminium of examples/aluminium_60kev.json, the replica's
// halo): 3 fixture rotations x 7 stage positions = 21 candidate views, 210
// pairs, every pair screened and the 5 best and the face-on pair 30 mm
// apart budgeted. Prints the wall time of each part (simulating the views
// with their shares of the linearisation, screening, the budgets), the
// sets per second of the screening, the whole plan's time and peak memory,
// on this machine's cores.
#include "xgauge/core/log.h"
#include "xgauge/core/progress.h"
#include "xgauge/plan/plan.h"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>

#include <sys/resource.h>

namespace fs = std::filesystem;

int main() {
  xgauge::setProgressEnabled(false);
  xgauge::setupLogging(xgauge::Verbosity::kQuiet);
  const fs::path dir = fs::temp_directory_path() / "xgauge_plan_bench";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path root = fs::current_path();
  std::ofstream(dir / "plan.json") << fmt::format(R"({{
  "job": {{
    "part": "{0}/parts/prism_jaw.json", "machine": "{0}/examples/machine_1024.json",
    "material": "{0}/examples/aluminium_60kev.json",
    "scatter": {{"weight": 0.139, "sigma_mm": 50.0}},
    "tolerances": {{"width": {{"lower": -0.05, "upper": 0.05}}, "thickness": {{"lower": -0.05, "upper": 0.05}},
                   "groove_depth": {{"lower": -0.1, "upper": 0.1}}, "slot_depth": {{"lower": -0.1, "upper": 0.1}}}},
    "pose_bounds": {{"rotation_deg": [[-5, 5], [-90, 90], [-5, 5]], "centre_mm": [[-60, 60], [-30, 30], [690, 750]]}}
  }},
  "exposure": {{"open_beam_noise": 0.005}},
  "views": {{"centre_mm": [-30, 0, 720], "rotations_deg": [[0, 0, 0], [0, 40, 0], [0, 80, 0]],
            "stage": {{"axis": [1, 0, 0], "positions_mm": [0, 5, 10, 15, 20, 25, 30]}}}},
  "radiographs": 2,
  "compare": [["v00", "v06"]]
}})",
                                                  root.string());
  const xgauge::PlanJob job = xgauge::PlanJob::load(dir / "plan.json");
  const xgauge::PlanResult result = xgauge::planViews(job);
  fs::remove_all(dir);
  std::printf("plan_bench: Prism A at 1024^2, %zu candidate views, %lld sets of 2 screened\n",
              job.views.size(), static_cast<long long>(result.screened));
  std::printf("  simulating the views and their shares  %7.2f s (%.2f s per view)\n",
              result.views_seconds, result.views_seconds / static_cast<double>(job.views.size()));
  std::printf("  screening every set                    %7.3f s (%.0f sets per second)\n",
              result.screening_seconds,
              static_cast<double>(result.screened) / std::max(1e-9, result.screening_seconds));
  std::printf("  budgets of %zu sets                     %7.2f s\n",
              static_cast<size_t>(job.budgeted) + job.compare.size(), result.budget_seconds);
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf("  the whole plan                         %7.2f s, peak memory %.0f MB\n",
              result.seconds, static_cast<double>(usage.ru_maxrss) / 1024.0);
  std::printf("  best set %s + %s: criterion %.4f; the face-on pair: %.4f\n",
              job.views[static_cast<size_t>(result.ranked[0].views[0])].name.c_str(),
              job.views[static_cast<size_t>(result.ranked[0].views[1])].name.c_str(),
              result.ranked[0].score, result.compared[0].score);
  return 0;
}
