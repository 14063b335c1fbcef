// `xgauge part faces` and `xgauge part check`: xgauge/part.h's calls and a
// print.
#include "commands.h"
#include "xgauge/part.h"
#include "xgauge/runtime.h"

#include <cstdio>
#include <memory>
#include <string>

namespace xgauge::cli {

void addPartCommand(CLI::App& app, Commands& commands) {
  CLI::App* part = app.add_subcommand(
      "part", "A part model before any radiograph: a STEP solid's faces, a model's dimensions");
  part->require_subcommand(1);

  auto faces = std::make_shared<PartFacesOptions>();
  auto faces_paths = std::make_shared<std::pair<std::string, std::string>>();
  CLI::App* faces_cmd = part->add_subcommand(
      "faces", "List and draw every face of a STEP solid, numbered (faces.json, faces.html)");
  faces_cmd->add_option("step", faces_paths->first, "STEP file (.step, .stp)")->required();
  faces_cmd->add_option("-o,--output", faces_paths->second, "Output folder (created if missing)")
      ->required();
  faces_cmd->add_option("--chord-tolerance-mm", faces->chord_tolerance_mm,
                        "Tessellation: largest chord error of curved edges (mm)")
      ->capture_default_str();
  faces_cmd->add_option("--angular-tolerance-deg", faces->angular_tolerance_deg,
                        "Tessellation: largest angle between neighbouring normals (deg)")
      ->capture_default_str();
  commands.push_back({faces_cmd, [faces, faces_paths] {
                        faces->step_file = faces_paths->first;
                        faces->output_folder = faces_paths->second;
                        const PartFacesSummary summary = succeeded(listFaces(*faces));
                        std::fputs(summary.table.c_str(), stdout);
                        LogMessage(Severity::kInfo, summary.message);
                        return 0;
                      }});

  auto check = std::make_shared<PartCheckOptions>();
  auto check_paths = std::make_shared<std::pair<std::string, std::string>>();
  CLI::App* check_cmd = part->add_subcommand(
      "check",
      "Move each dimension of a part model either side of nominal: the faces it moves, where "
      "the part can be built (check.json, check.html)");
  check_cmd->add_option("part", check_paths->first, "Part model (JSON)")->required();
  check_cmd->add_option("-o,--output", check_paths->second, "Output folder (created if missing)")
      ->required();
  check_cmd->add_option("--step", check->step_mm, "Step either side of nominal (mm or deg)")
      ->capture_default_str();
  commands.push_back({check_cmd, [check, check_paths] {
                        check->part_file = check_paths->first;
                        check->output_folder = check_paths->second;
                        const PartCheckSummary summary = succeeded(checkPart(*check));
                        std::fputs(summary.table.c_str(), stdout);
                        LogMessage(Severity::kInfo, summary.message);
                        return 0;
                      }});
}

}  // namespace xgauge::cli
