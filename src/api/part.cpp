// The front door's part tools (xgauge/part.h) over the geometry module and
// the part pages of the report module. `xgauge part faces` and `xgauge part
// check` are these calls and a print.
#include "xgauge/part.h"

#include "guard.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/geometry/step.h"
#include "xgauge/report/part_page.h"
#include "xgauge/report/part_views.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {
namespace {

constexpr int kFacesPicturePx = 480;
constexpr int kCheckPicturePx = 360;
// A vertex that moves less than this (mm) did not move.
constexpr double kStillMm = 1e-9;
// A face whose vertices leave its nominal surface by more than this (mm) is
// moved by the dimension; one whose vertices only slide along it, stretched.
constexpr double kOffSurfaceMm = 1e-7;

std::string faceLine(const StepFace& face) {
  const Surface& s = face.surface;
  std::string geometry;
  const auto vec = [](const Vec3& v) { return fmt::format("({:.3f}, {:.3f}, {:.3f})", v.x(), v.y(), v.z()); };
  switch (s.kind) {
    case SurfaceKind::kPlane:
      geometry = "normal " + vec(face.outward * s.axis);
      break;
    case SurfaceKind::kCylinder:
    case SurfaceKind::kCone:
    case SurfaceKind::kTorus:
      geometry = fmt::format("axis {} through {}, radius {:.4f}", vec(s.axis), vec(s.origin), s.radius);
      break;
    case SurfaceKind::kSphere:
      geometry = fmt::format("centre {}, radius {:.4f}", vec(s.origin), s.radius);
      break;
    case SurfaceKind::kOther:
      break;
  }
  return fmt::format("{:>4} {:>8} {:<14} {:<20} {:>10.3f}  {}  {}\n", face.index,
                     face.entity > 0 ? entityName(face) : "-",
                     face.name.empty() ? "-" : face.name, face.surface_type, face.area_mm2,
                     vec(face.centroid_mm), geometry);
}

PartFacesSummary listFacesOrThrow(const PartFacesOptions& options) {
  checkOutputFolder(options.output_folder);
  const StepSolid solid =
      readStepSolid(options.step_file, {options.chord_tolerance_mm, options.angular_tolerance_deg});
  std::vector<int> region(solid.triangle_face.begin(), solid.triangle_face.end());
  const BoundingBox box = boundingBox(solid.mesh);
  std::vector<PartPicture> pictures;
  for (const ViewDirection& view : standardViews())
    pictures.push_back(drawPart(
        solid.mesh.vertices, solid.mesh.triangles, region,
        [&](int face) { return faceColour(solid.faces[static_cast<size_t>(face)]); }, view, box,
        kFacesPicturePx));

  nlohmann::json json = {{"file", options.step_file.string()},
                         {"chord_tolerance_mm", options.chord_tolerance_mm},
                         {"angular_tolerance_deg", options.angular_tolerance_deg},
                         {"faces", nlohmann::json::array()}};
  PartFacesSummary summary;
  summary.table = fmt::format("{:>4} {:>8} {:<14} {:<20} {:>10}  {}\n", "face", "entity", "name",
                              "type", "area mm2", "centroid mm, normal or axis");
  for (const StepFace& face : solid.faces) {
    json["faces"].push_back(faceJson(face));
    summary.table += faceLine(face);
  }
  const std::string title = "Faces of " + options.step_file.filename().string();
  OutputTransaction outputs;
  createOutputFolder(options.output_folder);
  writeFileAtomically(options.output_folder / "faces.json", json.dump(2) + "\n");
  writeFileAtomically(options.output_folder / "faces.html", facesPage(title, solid, pictures));
  outputs.commit();
  summary.termination = RunTermination::kDone;
  summary.faces = solid.faces.size();
  summary.message = fmt::format("{} faces; wrote {}/faces.json and faces.html", solid.faces.size(),
                                options.output_folder.string());
  return summary;
}

// The largest step up to `step` (halving) at which the part can be built on
// this side of nominal; nullopt when none of 10 halvings can.
std::optional<double> sideStep(const PartModel& part, size_t index, double step, double sign,
                               std::vector<Vec3>& vertices) {
  std::vector<double> values = part.nominalValues();
  for (int k = 0; k < 10; ++k, step /= 2) {
    values[index] = part.dimensions()[index].nominal + sign * step;
    if (part.invalidity(values)) continue;
    if (!part.tryEvaluate(values, vertices)) return step;
  }
  return std::nullopt;
}

// What moving dimension `index` does to the STEP solid's faces: the faces
// whose vertices leave their nominal surface (moved) and those whose
// vertices only slide along it (stretched).
void classifyFaces(const PartModel& part, const std::vector<Vec3>& nominal,
                   const std::vector<std::vector<Vec3>>& displaced, std::vector<char>& moved_face,
                   std::vector<char>& stretched_face) {
  const PartModel::StepFaces step = part.stepFaces();
  const StepSolid& solid = *step.solid;
  moved_face.assign(solid.faces.size(), 0);
  stretched_face.assign(solid.faces.size(), 0);
  const auto& triangles = part.triangles();
  for (size_t t = 0; t < solid.triangle_face.size(); ++t) {
    const size_t face = solid.triangle_face[t];
    const Surface& surface = solid.faces[face].surface;
    for (const uint32_t v : triangles[step.first_triangle + t])
      for (const std::vector<Vec3>& moved : displaced) {
        const Vec3 shift = moved[v] - nominal[v];
        if (shift.norm() <= kStillMm) continue;
        const bool off = surface.kind == SurfaceKind::kOther
                             ? true
                             : std::abs(surface.value(moved[v]) - surface.value(nominal[v])) >
                                   kOffSurfaceMm;
        (off ? moved_face : stretched_face)[face] = 1;
      }
  }
  for (size_t f = 0; f < solid.faces.size(); ++f)
    if (moved_face[f]) stretched_face[f] = 0;
}

PartCheckSummary checkPartOrThrow(const PartCheckOptions& options) {
  if (!(options.step_mm > 0.0 && options.step_mm <= 10.0))
    fail("the step must lie in (0, 10] mm or deg, not {}", options.step_mm);
  checkOutputFolder(options.output_folder);
  const PartModel part = PartModel::load(options.part_file);
  if (part.dimensions().empty())
    throw Error("the part has no dimensions to check (a fixed mesh)",
                SourceLocation::inFile(options.part_file.string()));
  const std::vector<double> nominal_values = part.nominalValues();
  std::vector<Vec3> nominal;
  part.evaluate(nominal_values, nominal);
  const PartModel::StepFaces step_faces = part.stepFaces();
  BoundingBox frame = boundingBox(part.mesh(nominal_values));
  frame.min_mm -= Vec3::Constant(options.step_mm), frame.max_mm += Vec3::Constant(options.step_mm);

  std::vector<DimensionCheckSection> sections;
  nlohmann::json json = {{"part", options.part_file.string()},
                         {"step", options.step_mm},
                         {"dimensions", nlohmann::json::array()}};
  PartCheckSummary summary;
  summary.table = fmt::format("{:<24} {:>10} {:>11} {:>11}  {}\n", "dimension", "nominal",
                              "buildable", "to", "moves");
  for (size_t i = 0; i < part.dimensions().size(); ++i) {
    const Dimension& d = part.dimensions()[i];
    DimensionCheckSection section;
    section.name = d.name, section.unit = d.unit, section.nominal = d.nominal;
    // Each side's vertices, at the largest step up to the asked one.
    std::vector<std::vector<Vec3>> displaced;
    std::vector<double> steps;
    for (const double sign : {-1.0, 1.0}) {
      std::vector<Vec3> vertices;
      if (const auto s = sideStep(part, i, options.step_mm, sign, vertices)) {
        displaced.push_back(std::move(vertices));
        steps.push_back(sign * *s);
      }
    }
    section.step = steps.empty() ? 0.0 : std::abs(steps.back());
    bool moves = false;
    for (const auto& vertices : displaced)
      for (size_t v = 0; v < nominal.size(); ++v)
        moves = moves || (vertices[v] - nominal[v]).norm() > kStillMm;
    if (!moves)
      throw Error(fmt::format("dimension '{}' moves nothing: {} {} either side of nominal moves "
                              "no vertex of the part (name the faces it moves: "
                              "docs/your-part.md)",
                              d.name, options.step_mm, d.unit),
                  SourceLocation::at(options.part_file.string(), fmt::format("/dimensions/{}", i)));
    const PartModel::DimensionRange range = part.buildableRange(static_cast<int>(i));
    section.buildable_low = range.low, section.buildable_high = range.high;
    section.low_reason = range.low_reason, section.high_reason = range.high_reason;

    // Regions: 0 still, 1 moved, 2 stretched (by face for a STEP solid, by
    // triangle otherwise).
    std::vector<int> region(part.triangles().size(), 0);
    nlohmann::json moved_json = nlohmann::json::array(), stretched_json = nlohmann::json::array();
    if (step_faces.solid) {
      std::vector<char> moved_face, stretched_face;
      classifyFaces(part, nominal, displaced, moved_face, stretched_face);
      const StepSolid& solid = *step_faces.solid;
      for (size_t f = 0; f < solid.faces.size(); ++f) {
        if (moved_face[f]) section.moved.push_back(solid.describe(f)), moved_json.push_back(f + 1);
        if (stretched_face[f])
          section.stretched.push_back(solid.describe(f)), stretched_json.push_back(f + 1);
      }
      for (size_t t = 0; t < solid.triangle_face.size(); ++t) {
        const size_t f = solid.triangle_face[t];
        region[step_faces.first_triangle + t] = moved_face[f] ? 1 : stretched_face[f] ? 2 : 0;
      }
    } else {
      for (size_t t = 0; t < region.size(); ++t)
        for (const uint32_t v : part.triangles()[t])
          for (const auto& vertices : displaced)
            if ((vertices[v] - nominal[v]).norm() > kStillMm) region[t] = 1;
    }
    if (!part.csg()) {
      const auto colour = [](int r) {
        return r == 1 ? Rgb{215, 48, 39} : r == 2 ? Rgb{253, 174, 97} : Rgb{205, 205, 205};
      };
      const std::vector<int> outline_regions = [&] {
        std::vector<int> faces(part.triangles().size(), 0);
        if (step_faces.solid)
          for (size_t t = 0; t < step_faces.solid->triangle_face.size(); ++t)
            faces[step_faces.first_triangle + t] =
                static_cast<int>(step_faces.solid->triangle_face[t]);
        return faces;
      }();
      for (const ViewDirection& view : standardViews()) {
        const auto black = [](int) { return Rgb{0, 0, 0}; };
        PartPicture picture = drawPart(nominal, part.triangles(), region, colour, view, frame,
                                       kCheckPicturePx);
        const PartPicture unchanged =
            drawPart(nominal, part.triangles(), outline_regions, black, view, frame, kCheckPicturePx);
        for (size_t k = 0; k < displaced.size(); ++k) {
          const PartPicture other =
              drawPart(displaced[k], part.triangles(), outline_regions, black, view, frame,
                       kCheckPicturePx);
          overlayOutline(picture, other, &unchanged,
                         steps[k] < 0 ? Rgb{33, 102, 172} : Rgb{178, 24, 43});
        }
        section.pictures.push_back(std::move(picture));
      }
    }
    summary.table += fmt::format("{:<24} {:>10.4f} {:>11.4f} {:>11.4f}  {} face{}{}\n", d.name,
                                 d.nominal, range.low, range.high, section.moved.size(),
                                 section.moved.size() == 1 ? "" : "s",
                                 step_faces.solid ? "" : " (no STEP faces)");
    json["dimensions"].push_back({{"name", d.name},
                                  {"unit", d.unit},
                                  {"nominal", d.nominal},
                                  {"steps", steps},
                                  {"buildable", {range.low, range.high}},
                                  {"buildable_ends", {range.low_reason, range.high_reason}},
                                  {"moved_faces", moved_json},
                                  {"stretched_faces", stretched_json}});
    sections.push_back(std::move(section));
  }
  OutputTransaction outputs;
  createOutputFolder(options.output_folder);
  writeFileAtomically(options.output_folder / "check.json", json.dump(2) + "\n");
  writeFileAtomically(options.output_folder / "check.html",
                      checkPage("Dimensions of " + options.part_file.filename().string(), sections));
  outputs.commit();
  summary.termination = RunTermination::kDone;
  summary.dimensions = sections.size();
  summary.message = fmt::format("{} dimensions checked; wrote {}/check.json and check.html",
                                sections.size(), options.output_folder.string());
  return summary;
}

}  // namespace

PartFacesSummary listFaces(const PartFacesOptions& options) {
  return api::guarded<PartFacesSummary>([&] { return listFacesOrThrow(options); });
}

PartCheckSummary checkPart(const PartCheckOptions& options) {
  return api::guarded<PartCheckSummary>([&] { return checkPartOrThrow(options); });
}

}  // namespace xgauge
