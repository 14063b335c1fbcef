// STEP solids through OpenCASCADE (OCCT), the maintained tool for reading
// STEP: read, check closed and valid, tessellate, then the STL reader's
// welding and checks (closedMeshFromSoup). See xgauge/geometry/step.h.
#include "xgauge/geometry/step.h"

#include "xgauge/core/digest.h"
#include "xgauge/core/file.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepCheck.hxx>
#include <BRepCheck_Analyzer.hxx>
#include <BRepCheck_ListOfStatus.hxx>
#include <BRepCheck_Result.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IMeshTools_Parameters.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <Poly_Triangulation.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <StepData_StepModel.hxx>
#include <StepRepr_RepresentationItem.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <gp_Cone.hxx>
#include <gp_Cylinder.hxx>
#include <gp_Pln.hxx>
#include <gp_Sphere.hxx>
#include <gp_Torus.hxx>

#include <array>
#include <cctype>
#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {
namespace {

// A STEP file holds text: 256 MiB is far beyond any part a fit can use.
constexpr uint64_t kMaxStepBytes = uint64_t{256} << 20;

std::mutex& occtMutex() {
  static std::mutex mutex;
  return mutex;
}

// OCCT's default messenger prints to standard output (xgauge writes results
// there); remove that printer once for the process.
void silenceOcct() {
  static std::once_flag once;
  std::call_once(once, [] {
    Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  });
}

[[noreturn]] void failIn(const std::string& file, const std::string& message) {
  throw Error(message, SourceLocation::inFile(file));
}

// The faces in OCCT's order (1-based), and how to name one in an error.
class FaceNames {
 public:
  FaceNames(const STEPControl_Reader& reader, const TopoDS_Shape& shape) : reader_(reader) {
    TopExp::MapShapes(shape, TopAbs_FACE, faces_);
  }
  int count() const { return faces_.Extent(); }
  const TopoDS_Face& face(int index) const { return TopoDS::Face(faces_(index)); }

  // The STEP entity (#42) the face was read from, 0 when the transfer did
  // not record it; and its name, empty when the file gives none.
  int entity(const TopoDS_Shape& face) const {
    const Handle(Standard_Transient) item = entityOf(face);
    const auto model = modelOf();
    return item.IsNull() || model.IsNull() ? 0 : model->IdentLabel(item);
  }
  std::string label(const TopoDS_Shape& face) const {
    const auto item = Handle(StepRepr_RepresentationItem)::DownCast(entityOf(face));
    if (item.IsNull() || item->Name().IsNull()) return {};
    return item->Name()->ToCString();
  }

  // "face 3 of 6 (#42 'top')": the entity and its name where the transfer
  // recorded them.
  std::string name(const TopoDS_Shape& face) const {
    const int index = faces_.FindIndex(face);
    std::string text = fmt::format("face {} of {}", index, faces_.Extent());
    std::string details;
    if (const int id = entity(face); id > 0) details = fmt::format("#{}", id);
    if (const std::string given = label(face); !given.empty())
      details += fmt::format("{}'{}'", details.empty() ? "" : " ", given);
    return details.empty() ? text : fmt::format("{} ({})", text, details);
  }

 private:
  // Mode 1: the last transfer's roots and their sub-shapes (faces).
  Handle(Standard_Transient) entityOf(const TopoDS_Shape& face) const {
    const Handle(XSControl_WorkSession) session = reader_.WS();
    if (session.IsNull() || session->TransferReader().IsNull()) return {};
    return session->TransferReader()->EntityFromShapeResult(face, 1);
  }
  Handle(StepData_StepModel) modelOf() const {
    const Handle(XSControl_WorkSession) session = reader_.WS();
    if (session.IsNull()) return {};
    return Handle(StepData_StepModel)::DownCast(session->Model());
  }

  const STEPControl_Reader& reader_;
  TopTools_IndexedMapOfShape faces_;
};

// Every edge of every face must bound exactly two face sides: a closed,
// manifold surface. A seam (a closed face meeting itself) counts twice in
// its face; degenerate edges (a cone's apex) bound nothing.
void requireClosedSurface(const FaceNames& names, const std::string& file) {
  TopTools_IndexedMapOfShape edges;
  std::vector<int> uses;
  for (int f = 1; f <= names.count(); ++f)
    for (TopExp_Explorer e(names.face(f), TopAbs_EDGE); e.More(); e.Next()) {
      if (BRep_Tool::Degenerated(TopoDS::Edge(e.Current()))) continue;
      const int index = edges.Add(e.Current());
      if (static_cast<size_t>(index) > uses.size()) uses.resize(static_cast<size_t>(index), 0);
      ++uses[static_cast<size_t>(index) - 1];
    }
  for (int f = 1; f <= names.count(); ++f)
    for (TopExp_Explorer e(names.face(f), TopAbs_EDGE); e.More(); e.Next()) {
      if (BRep_Tool::Degenerated(TopoDS::Edge(e.Current()))) continue;
      const int count = uses[static_cast<size_t>(edges.FindIndex(e.Current())) - 1];
      if (count == 1)
        failIn(file, fmt::format("{} is bounded by a free edge (one no other face shares): not a "
                                 "closed solid",
                                 names.name(names.face(f))));
      if (count > 2)
        failIn(file, fmt::format("{} has an edge shared by {} faces: not a closed solid (not "
                                 "manifold)",
                                 names.name(names.face(f)), count));
    }
}

std::optional<BRepCheck_Status> firstProblem(const BRepCheck_ListOfStatus& list) {
  for (const BRepCheck_Status status : list)
    if (status != BRepCheck_NoError) return status;
  return std::nullopt;
}

std::string statusName(BRepCheck_Status status) {
  std::ostringstream text;
  BRepCheck::Print(status, text);
  std::string name = text.str();
  while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
  return name;
}

// The first problem OCCT's checker finds on this face, its wires or edges.
std::optional<BRepCheck_Status> faceProblem(const BRepCheck_Analyzer& analyzer,
                                            const TopoDS_Face& face) {
  if (const Handle(BRepCheck_Result) result = analyzer.Result(face); !result.IsNull())
    if (const auto problem = firstProblem(result->Status())) return problem;
  for (const TopAbs_ShapeEnum kind : {TopAbs_WIRE, TopAbs_EDGE})
    for (TopExp_Explorer e(face, kind); e.More(); e.Next()) {
      const Handle(BRepCheck_Result) result = analyzer.Result(e.Current());
      if (result.IsNull()) continue;
      if (const auto problem = firstProblem(result->Status())) return problem;
      if (result->IsStatusOnShape(face))
        if (const auto problem = firstProblem(result->StatusOnShape(face))) return problem;
    }
  return std::nullopt;
}

void requireValid(const TopoDS_Shape& shape, const FaceNames& names, const std::string& file) {
  const BRepCheck_Analyzer analyzer(shape);
  if (analyzer.IsValid()) return;
  for (int f = 1; f <= names.count(); ++f)
    if (const auto problem = faceProblem(analyzer, names.face(f)))
      failIn(file, fmt::format("{} fails OpenCASCADE's B-rep check ({}): not a valid solid",
                               names.name(names.face(f)), statusName(*problem)));
  std::string why = "the shape fails OpenCASCADE's B-rep check";
  if (const Handle(BRepCheck_Result) result = analyzer.Result(shape); !result.IsNull())
    if (const auto problem = firstProblem(result->Status()))
      why += fmt::format(" ({})", statusName(*problem));
  failIn(file, why + ": not a valid solid");
}

// The face's carrying surface in the part frame (its location applied).
Surface surfaceOf(const TopoDS_Face& face, std::string& type_name) {
  const BRepAdaptor_Surface adaptor(face, Standard_True);
  const auto point = [](const gp_Pnt& p) { return Vec3(p.X(), p.Y(), p.Z()); };
  const auto direction = [](const gp_Dir& d) { return Vec3(d.X(), d.Y(), d.Z()); };
  Surface surface;
  switch (adaptor.GetType()) {
    case GeomAbs_Plane: {
      const gp_Pln plane = adaptor.Plane();
      surface.kind = SurfaceKind::kPlane;
      surface.origin = point(plane.Location());
      surface.axis = direction(plane.Axis().Direction());
      break;
    }
    case GeomAbs_Cylinder: {
      const gp_Cylinder cylinder = adaptor.Cylinder();
      surface.kind = SurfaceKind::kCylinder;
      surface.origin = point(cylinder.Location());
      surface.axis = direction(cylinder.Axis().Direction());
      surface.radius = cylinder.Radius();
      break;
    }
    case GeomAbs_Cone: {
      const gp_Cone cone = adaptor.Cone();
      surface.kind = SurfaceKind::kCone;
      surface.origin = point(cone.Location());
      surface.axis = direction(cone.Axis().Direction());
      surface.radius = cone.RefRadius();
      surface.setSemiAngle(cone.SemiAngle());
      break;
    }
    case GeomAbs_Sphere: {
      const gp_Sphere sphere = adaptor.Sphere();
      surface.kind = SurfaceKind::kSphere;
      surface.origin = point(sphere.Location());
      surface.radius = sphere.Radius();
      break;
    }
    case GeomAbs_Torus: {
      const gp_Torus torus = adaptor.Torus();
      surface.kind = SurfaceKind::kTorus;
      surface.origin = point(torus.Location());
      surface.axis = direction(torus.Axis().Direction());
      surface.radius = torus.MajorRadius();
      surface.minor_radius = torus.MinorRadius();
      break;
    }
    case GeomAbs_BezierSurface:
      type_name = "Bezier";
      return surface;
    case GeomAbs_BSplineSurface:
      type_name = "B-spline";
      return surface;
    case GeomAbs_SurfaceOfRevolution:
      type_name = "surface of revolution";
      return surface;
    case GeomAbs_SurfaceOfExtrusion:
      type_name = "surface of extrusion";
      return surface;
    case GeomAbs_OffsetSurface:
      type_name = "offset surface";
      return surface;
    default:
      type_name = "other";
      return surface;
  }
  type_name = std::string(surfaceKindName(surface.kind));
  return surface;
}

// Meshes the shape (BRepMesh_IncrementalMesh, absolute deflection).
void meshShape(const TopoDS_Shape& shape, const StepTessellation& tessellation,
          const std::string& file) {
  IMeshTools_Parameters parameters;
  parameters.Deflection = parameters.DeflectionInterior = tessellation.chord_tolerance_mm;
  parameters.Angle = parameters.AngleInterior =
      tessellation.angular_tolerance_deg * std::numbers::pi / 180.0;
  parameters.Relative = false;
  parameters.InParallel = false;  // the same triangles on every run
  const BRepMesh_IncrementalMesh mesher(shape, parameters);
  if (!mesher.IsDone()) failIn(file, "OpenCASCADE's mesher failed on the shape");
}

// The triangles of every face, outward, in the part frame (mm), face by face
// in OCCT's face order; `faces` receives each face's description and
// `triangle_face` each triangle's face (0-based).
TriangleSoup tessellate(const FaceNames& names, const StepTessellation& tessellation,
                        const std::string& file, std::vector<StepFace>& faces,
                        std::vector<uint32_t>& triangle_face) {
  TriangleSoup soup;
  for (int f = 1; f <= names.count(); ++f) {
    const TopoDS_Face& face = names.face(f);
    StepFace& described = faces.emplace_back();
    described.index = f;
    described.entity = names.entity(face);
    described.name = names.label(face);
    described.surface = surfaceOf(face, described.surface_type);

    TopLoc_Location location;
    const Handle(Poly_Triangulation) triangulation = BRep_Tool::Triangulation(face, location);
    if (triangulation.IsNull() || triangulation->NbTriangles() == 0)
      failIn(file, fmt::format("{} could not be tessellated (OpenCASCADE's mesher made no "
                               "triangles)",
                               names.name(face)));
    if (soup.size() + static_cast<size_t>(triangulation->NbTriangles()) > kMaxStepTriangles)
      failIn(file, fmt::format("tessellating at a chord tolerance of {} mm makes more than {} "
                               "triangles; choose a larger chord_tolerance_mm",
                               tessellation.chord_tolerance_mm, kMaxStepTriangles));
    const gp_Trsf& transform = location.Transformation();
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int t = 1; t <= triangulation->NbTriangles(); ++t) {
      int corner[3];
      triangulation->Triangle(t).Get(corner[0], corner[1], corner[2]);
      if (reversed) std::swap(corner[1], corner[2]);
      std::array<Vec3, 3> triangle;
      for (int c = 0; c < 3; ++c) {
        const gp_Pnt p = triangulation->Node(corner[c]).Transformed(transform);
        triangle[static_cast<size_t>(c)] = Vec3(p.X(), p.Y(), p.Z());
      }
      // A degenerate edge (a sphere's pole, a cone's apex) is one point that
      // the mesher places several nodes on: triangles between two of them
      // cover nothing and are left out here, without the welding's warning.
      if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[2] == triangle[0])
        continue;
      soup.push_back(triangle);
      triangle_face.push_back(static_cast<uint32_t>(f - 1));
    }
  }
  return soup;
}

// Area, centroid, mean outward normal and, for analytic surfaces, which way
// the outward normal points relative to Surface::gradient, from the face's
// triangles.
// A cone or torus as OCCT gives it may carry a face on a part that its
// implicit function (Surface::value) does not describe: a cone's far nappe,
// where the radius R + h tan(a) is negative, or the inner (lemon) part of a
// torus whose tube crosses the axis. Such a surface is restated so that the
// function is 0 on the face: the cone's radius and angle negated, the
// torus's centre circle taken on the far side (a negative radius). Which one
// the face lies on is decided over all its vertices: a vertex on the axis
// fits both.
void chooseSheets(const TriangleMesh& mesh, std::span<const uint32_t> triangle_face,
                  std::vector<StepFace>& faces) {
  std::vector<double> as_read(faces.size(), 0.0), restated(faces.size(), 0.0);
  const auto flipped = [](Surface s) {
    s.radius = -s.radius;
    if (s.kind == SurfaceKind::kCone) s.setSemiAngle(-s.semi_angle);
    return s;
  };
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const size_t f = triangle_face[t];
    const Surface& s = faces[f].surface;
    if (s.kind != SurfaceKind::kCone && s.kind != SurfaceKind::kTorus) continue;
    const Surface other = flipped(s);
    for (const uint32_t v : mesh.triangles[t]) {
      as_read[f] += std::abs(s.value(mesh.vertices[v]));
      restated[f] += std::abs(other.value(mesh.vertices[v]));
    }
  }
  for (size_t f = 0; f < faces.size(); ++f)
    if (restated[f] < as_read[f]) faces[f].surface = flipped(faces[f].surface);
}

void describeTriangles(const TriangleMesh& mesh, std::span<const uint32_t> triangle_face,
                       std::vector<StepFace>& faces) {
  chooseSheets(mesh, triangle_face, faces);
  std::vector<Vec3> weighted_centroid(faces.size(), Vec3::Zero());
  std::vector<Vec3> area_normal(faces.size(), Vec3::Zero());
  std::vector<double> along_gradient(faces.size(), 0.0);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3& b = mesh.vertices[tri[1]];
    const Vec3& c = mesh.vertices[tri[2]];
    const Vec3 twice_area = (b - a).cross(c - a);
    const Vec3 centre = (a + b + c) / 3.0;
    const size_t f = triangle_face[t];
    StepFace& face = faces[f];
    face.area_mm2 += 0.5 * twice_area.norm();
    weighted_centroid[f] += 0.5 * twice_area.norm() * centre;
    area_normal[f] += 0.5 * twice_area;
    if (face.surface.kind != SurfaceKind::kOther)
      along_gradient[f] += 0.5 * twice_area.dot(face.surface.gradient(centre));
  }
  for (size_t f = 0; f < faces.size(); ++f) {
    StepFace& face = faces[f];
    if (face.area_mm2 > 0) face.centroid_mm = weighted_centroid[f] / face.area_mm2;
    const double n = area_normal[f].norm();
    face.normal = n > 0 ? Vec3(area_normal[f] / n) : Vec3::Zero();
    face.outward = along_gradient[f] < 0 ? -1 : 1;
  }
}

TopoDS_Shape readShape(STEPControl_Reader& reader, const std::filesystem::path& path,
                       const std::string& file, std::string& sha256) {
  const std::string bytes = readFileContents(path, kMaxStepBytes, "a STEP file");
  sha256 = sha256Hex(bytes);
  std::string_view text(bytes);
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // a UTF-8 byte order mark
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos || !text.substr(first).starts_with("ISO-10303-21;"))
    failIn(file, "not a STEP file: it does not start with 'ISO-10303-21;' (ISO 10303-21)");
  std::istringstream stream(bytes);
  if (reader.ReadStream(file.c_str(), stream) != IFSelect_RetDone)
    failIn(file, "OpenCASCADE cannot read this STEP file (syntax or structure error)");
  if (reader.TransferRoots() == 0)
    failIn(file, "the STEP file holds no shape OpenCASCADE can read");
  TopoDS_Shape shape = reader.OneShape();
  if (shape.IsNull()) failIn(file, "the STEP file holds no shape OpenCASCADE can read");
  return shape;
}

void requireTolerances(const StepTessellation& t, const std::string& file) {
  if (!(t.chord_tolerance_mm >= kMinStepChordToleranceMm &&
        t.chord_tolerance_mm <= kMaxStepChordToleranceMm))
    failIn(file, fmt::format("chord_tolerance_mm {} out of range [{}, {}]", t.chord_tolerance_mm,
                             kMinStepChordToleranceMm, kMaxStepChordToleranceMm));
  if (!(t.angular_tolerance_deg >= kMinStepAngularToleranceDeg &&
        t.angular_tolerance_deg <= kMaxStepAngularToleranceDeg))
    failIn(file,
           fmt::format("angular_tolerance_deg {} out of range [{}, {}]", t.angular_tolerance_deg,
                       kMinStepAngularToleranceDeg, kMaxStepAngularToleranceDeg));
}

}  // namespace

std::string StepSolid::describe(size_t face) const {
  const StepFace& f = faces[face];
  std::string details;
  if (f.entity > 0) details = fmt::format("#{}", f.entity);
  if (!f.name.empty()) details += fmt::format("{}'{}'", details.empty() ? "" : " ", f.name);
  details += fmt::format("{}{}", details.empty() ? "" : ", ", f.surface_type);
  return fmt::format("face {} of {} ({})", f.index, faces.size(), details);
}

StepSolid readStepSolid(const std::filesystem::path& path, const StepTessellation& tessellation) {
  const std::string file = path.string();
  requireTolerances(tessellation, file);
  StepSolid solid;
  solid.chord_tolerance_mm = tessellation.chord_tolerance_mm;
  TriangleSoup soup;
  std::vector<uint32_t> soup_face;
  {
    const std::lock_guard lock(occtMutex());
    silenceOcct();
    try {
      STEPControl_Reader reader;
      const TopoDS_Shape shape = readShape(reader, path, file, solid.sha256);
      const FaceNames names(reader, shape);
      if (names.count() == 0)
        failIn(file, "the shape has no faces: not a solid (a STEP file of curves or points?)");
      requireClosedSurface(names, file);
      requireValid(shape, names, file);
      meshShape(shape, tessellation, file);
      soup = tessellate(names, tessellation, file, solid.faces, soup_face);
    } catch (const Standard_Failure& failure) {
      failIn(file, fmt::format("OpenCASCADE failed: {} ({})", failure.GetMessageString(),
                               failure.DynamicType()->Name()));
    }
  }
  std::vector<uint32_t> kept;
  solid.mesh = closedMeshFromSoup(soup, file, &kept);
  solid.triangle_face.reserve(kept.size());
  for (const uint32_t t : kept) solid.triangle_face.push_back(soup_face[t]);
  describeTriangles(solid.mesh, solid.triangle_face, solid.faces);
  return solid;
}

TriangleMesh readStep(const std::filesystem::path& path, const StepTessellation& tessellation) {
  return readStepSolid(path, tessellation).mesh;
}

}  // namespace xgauge
