// The front door's detector characterisation (xgauge/xgauge.h) over the
// characterize module. `xgauge characterize` is this call and a print.
#include "guard.h"
#include "xgauge/characterize/characterize.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/xgauge.h"

namespace xgauge {

namespace {

CharacterizationSummary characterizeOrThrow(const CharacterizationOptions& options) {
  checkOutputFolder(options.output_folder);
  const CharacterizeJob job = CharacterizeJob::load(options.job_file);
  Characterization result;
  {
    ProgressBar progress("characterize", characterizeSteps(job));
    result = characterize(job, [&] { progress.advance(); });
  }
  CharacterizationSummary summary;
  summary.report = characterizationReport(result);
  OutputTransaction outputs;
  const std::filesystem::path& folder = options.output_folder;
  createOutputFolder(folder);
  writeFileAtomically(folder / "bad_pixels.json", badPixelsJson(result.bad_pixels).dump() + "\n");
  writeFileAtomically(folder / "detector.json",
                      detectorJson(result, "bad_pixels.json").dump(2) + "\n");
  outputs.commit();
  summary.termination = RunTermination::kDone;
  summary.message = "wrote " + folder.string() + "/detector.json and bad_pixels.json";
  return summary;
}

}  // namespace

CharacterizationSummary characterize(const CharacterizationOptions& options) {
  return api::guarded<CharacterizationSummary>([&] { return characterizeOrThrow(options); });
}

}  // namespace xgauge
