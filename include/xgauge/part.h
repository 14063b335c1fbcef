// A part model before any radiograph: the faces of a STEP solid, numbered
// and drawn, so that a person can name dimensions on them without a CAD
// program (`xgauge part faces`), and a part model's dimensions checked: which
// faces each one moves, over which range the part can be built
// (`xgauge part check`). In the style of xgauge/xgauge.h: an options
// struct, one call, a summary whose termination and message say how it
// ended. Needs only the C++ standard library; nothing here throws for bad
// input. docs/your-part.md walks through both; docs/formats.md describes
// the files written.
#pragma once

#include "xgauge/runtime.h"

#include <cstddef>
#include <filesystem>
#include <string>

namespace xgauge {

// Every face of a STEP solid: faces.json and faces.html (the part from
// three directions, each face numbered and coloured by its surface's type).
struct PartFacesOptions {
  std::filesystem::path step_file;
  std::filesystem::path output_folder;  // created if missing
  // How finely curved faces are tessellated (the "step" shape's keys).
  double chord_tolerance_mm = 0.001;
  double angular_tolerance_deg = 20.0;
};

struct PartFacesSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;  // kFailure: why; otherwise what was written
  std::size_t faces = 0;
  // One line per face: number, STEP entity, name, surface type, area,
  // centroid, normal or axis, radius.
  std::string table;
};

PartFacesSummary listFaces(const PartFacesOptions& options);

// Each dimension of a part model moved by +-step from nominal: the faces it
// moves and stretches, the range over which the part can be built with the
// others at nominal, and a picture of it (check.json, check.html). A
// dimension that moves nothing is refused (kFailure, nothing written).
struct PartCheckOptions {
  std::filesystem::path part_file;
  std::filesystem::path output_folder;  // created if missing
  double step_mm = 0.5;                 // or deg, for angles; within (0, 10]
};

struct PartCheckSummary {
  RunTermination termination = RunTermination::kFailure;
  std::string message;
  std::size_t dimensions = 0;
  // One line per dimension: nominal, the buildable range, what it moves.
  std::string table;
};

PartCheckSummary checkPart(const PartCheckOptions& options);

}  // namespace xgauge
