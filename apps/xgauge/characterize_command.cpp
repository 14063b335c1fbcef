#include "characterize_command.h"

#include "xgauge/characterize/characterize.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace xgauge::cli {

void addCharacterizeCommand(CLI::App& app, CharacterizeArguments& args) {
  CLI::App* cmd = app.add_subcommand(
      "characterize",
      "Characterise the detector from dark and flat series and shots of an opaque edge, a lag "
      "pair and a covered quadrant: halo (shape, weight, width, border), lag, crosstalk, bad "
      "pixels");
  cmd->add_option("job", args.job, "Characterisation job (JSON, docs/formats.md)")->required();
  cmd->add_option("-o,--output", args.output, "Output folder: detector.json, bad_pixels.json")
      ->required();
}

void runCharacterize(const CharacterizeArguments& args) {
  checkOutputFolder(args.output);
  const CharacterizeJob job = CharacterizeJob::load(args.job);
  Characterization result;
  {
    ProgressBar progress("characterize", characterizeSteps(job));
    result = characterize(job, [&] { progress.advance(); });
  }
  std::fputs(characterizationReport(result).c_str(), stdout);
  OutputTransaction outputs;
  const std::filesystem::path folder(args.output);
  createOutputFolder(folder);
  writeFileAtomically(folder / "bad_pixels.json", badPixelsJson(result.bad_pixels).dump() + "\n");
  writeFileAtomically(folder / "detector.json",
                      detectorJson(result, "bad_pixels.json").dump(2) + "\n");
  outputs.commit();
  spdlog::info("wrote {}/detector.json and bad_pixels.json", args.output);
}

}  // namespace xgauge::cli
