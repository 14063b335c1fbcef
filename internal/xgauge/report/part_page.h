// The pages `xgauge part faces` and `xgauge part check` write: one
// self-contained HTML file each (pictures embedded as data: URIs, styles
// inlined, no script, nothing fetched), read beside docs/your-part.md.
#pragma once

#include "xgauge/geometry/step.h"
#include "xgauge/report/part_views.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace xgauge {

// A face's colour in the pictures: a hue per surface type, lighter or
// darker by face so that neighbours of one type stay apart.
Rgb faceColour(const StepFace& face);

// "#42", the face's STEP entity; empty when unknown.
std::string entityName(const StepFace& face);

// faces.json's object for one face: number, entity, name, type, area,
// centroid, outward normal (planes) or axis, origin and radii.
nlohmann::json faceJson(const StepFace& face);

// faces.html: the solid from the pictures' directions with every face's
// number on it, the colours' legend and the faces' table.
std::string facesPage(const std::string& title, const StepSolid& solid,
                      const std::vector<PartPicture>& pictures);

// One dimension's section of check.html.
struct DimensionCheckSection {
  std::string name, unit;
  double nominal = 0.0, step = 0.0;
  double buildable_low = 0.0, buildable_high = 0.0;
  std::string low_reason, high_reason;
  std::vector<std::string> moved, stretched;  // faces, described
  std::vector<PartPicture> pictures;          // may be empty (a CSG part)
};

// check.html: for each dimension, its range, the faces it moves and
// stretches, and its pictures (moved faces red, stretched faces orange, the
// part at -step outlined in blue and at +step in red).
std::string checkPage(const std::string& title, const std::vector<DimensionCheckSection>& sections);

}  // namespace xgauge
