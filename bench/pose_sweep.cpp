// How reliably the pose of a rotated shot is found (issue 45): for each of
// Parts 1, 5 and 6 (prism jaw, bracket, stepped shaft), `count` cases of a
// reference shot, a shot translated 10 mm and one turned 0 to 90 degrees
// about an axis tilted 4 to 14 degrees from the vertical, simulated by the
// lab on a 256^2 detector and measured from the drawing's round values
// (tests/pose_cases.h). Prints each case and the totals: cases, found
// (rotation within 0.5 deg, dimensions within 0.1 mm, the acceptance rule
// passed), the rate, the time per measurement and how often the joint fit
// needed a pose candidate beyond the first or a retry.
//
// Run from the repository root:
//   build/bench/pose_sweep [cases per part, default 20] [work folder]
//       [--candidates N] [--part prism|bracket|shaft]
// --candidates 1 measures as before the pose candidates (the search's best
// alone); --part sweeps one part.
#include "../tests/pose_cases.h"

#include "xgauge/core/log.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

using namespace xgauge;
using namespace xgauge::pose_cases;

int main(int argc, char** argv) {
  try {
    setupLogging(Verbosity::kQuiet);
    std::vector<std::string> positional;
    std::optional<int> candidates;
    std::string only_part;
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--candidates" && i + 1 < argc)
        candidates = std::stoi(argv[++i]);
      else if (arg == "--part" && i + 1 < argc)
        only_part = argv[++i];
      else if (arg.starts_with("-"))
        throw std::runtime_error("unknown option " + arg);
      else
        positional.push_back(arg);
    }
    const int count = !positional.empty() ? std::stoi(positional[0]) : 20;
    const fs::path work =
        positional.size() > 1 ? fs::path(positional[1]) : fs::temp_directory_path() / "pose_sweep";
    int cases = 0, found = 0, out_of_bounds = 0, beyond_first = 0, retried = 0;
    std::vector<double> seconds;
    for (int part = 0; part < static_cast<int>(parts().size()); ++part)
      for (int i = 0; i < count; ++i) {
        const std::string& name = parts()[static_cast<size_t>(part)].name;
        if (!only_part.empty() && name != only_part) continue;
        const PoseCase c = sweepCase(part, i, count);
        const PoseOutcome o = runCase(c, ".", work / fmt::format("{}_{:02d}", name, i), candidates);
        std::printf("%s %s\n", o.found() ? "found  " : (o.in_bounds ? "MISSED " : "bounds "),
                    o.summary.c_str());
        std::fflush(stdout);
        if (!o.in_bounds) {
          ++out_of_bounds;
          continue;
        }
        ++cases;
        found += o.found();
        beyond_first += o.candidates_tried > 1;
        retried += o.attempts > 1;
        seconds.push_back(o.seconds);
      }
    std::sort(seconds.begin(), seconds.end());
    double total = 0.0;
    for (double s : seconds) total += s;
    std::printf(
        "\n%d cases (%d more with a true rotation outside the bounds, left out): %d found, rate "
        "%.1f %%; per measurement %.1f s mean, %.1f s median; a candidate beyond the first in %d, "
        "a retry from other starts in %d\n",
        cases, out_of_bounds, found, 100.0 * found / std::max(1, cases),
        total / static_cast<double>(std::max<size_t>(1, seconds.size())),
        seconds.empty() ? 0.0 : seconds[seconds.size() / 2], beyond_first, retried);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pose_sweep: %s\n", e.what());
    return 1;
  }
  return 0;
}
