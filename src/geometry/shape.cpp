#include "shape.h"

#include "face_moves.h"
#include "faced_shape.h"

#include "xgauge/geometry/polygon.h"
#include "xgauge/geometry/step.h"
#include "xgauge/geometry/stl.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace xgauge {
namespace {

constexpr std::array<const char*, 3> kAxisNames = {"x", "y", "z"};
// More triangles than any part a fit can use (and than 32-bit indices reach
// comfortably); shapes beyond it are refused before anything is built.
constexpr uint64_t kMaxShapeTriangles = uint64_t{1} << 24;
// Curved surfaces are faceted with at most this chord error at nominal size
// unless the file gives "segments" (docs/formats.md).
constexpr double kChordErrorMm = 0.001;

SourceLocation child(SourceLocation where, std::string_view key) {
  where.key_path += "/";
  where.key_path += key;
  return where;
}

int readAxis(const ConfigNode& node) {
  const std::string name = node.string();
  for (int axis = 0; axis < 3; ++axis)
    if (name == kAxisNames[axis]) return axis;
  node.fail(fmt::format("unknown axis '{}' (known: x, y, z)", name));
}

// A list of points, each a list of `dimension` expressions, appended flat.
void readPoints(const ConfigNode& list, size_t dimension, std::vector<ExpressionSource>& out) {
  for (size_t i = 0; i < list.size(); ++i) {
    const ConfigNode point = list[i];
    if (!point.isArray() || point.size() != dimension)
      point.fail(fmt::format("expected a list of {} expressions", dimension));
    for (size_t k = 0; k < dimension; ++k) out.push_back(readExpression(point[k]));
  }
}

// "segments" of a revolution or cylinder: optional, 0 (chosen from the
// nominal radius) when absent.
void readSegments(const ConfigNode& shape, ShapeSpec& spec) {
  const auto segments = shape.find("segments");
  if (!segments) return;
  spec.segments = static_cast<int>(segments->integer(3, 1000000));
  // Two triangles per profile edge and segment; refused before any is made.
  const uint64_t triangles =
      uint64_t{2} * (spec.scalars.size() / 2) * static_cast<uint64_t>(spec.segments);
  if (triangles > kMaxShapeTriangles)
    segments->fail(fmt::format("{} profile points x {} segments make {} triangles; at most {} are "
                               "supported",
                               spec.scalars.size() / 2, spec.segments, triangles,
                               kMaxShapeTriangles));
}

// The tessellation keys of a "step" shape, both optional.
StepTessellation readStepTessellation(const ConfigNode& shape) {
  static_assert(kMaxStepTriangles == kMaxShapeTriangles);
  StepTessellation tessellation;
  if (const auto chord = shape.find("chord_tolerance_mm"))
    tessellation.chord_tolerance_mm =
        chord->number(kMinStepChordToleranceMm, kMaxStepChordToleranceMm);
  if (const auto angle = shape.find("angular_tolerance_deg"))
    tessellation.angular_tolerance_deg =
        angle->number(kMinStepAngularToleranceDeg, kMaxStepAngularToleranceDeg);
  return tessellation;
}

// A list of exactly three expressions (a point or a size).
std::array<ExpressionSource, 3> readTriple(const ConfigNode& node) {
  if (!node.isArray() || node.size() != 3) node.fail("expected a list of 3 expressions");
  return {readExpression(node[0]), readExpression(node[1]), readExpression(node[2])};
}

// An expression made from others, reported where `where` was written.
ExpressionSource derivedExpression(std::string text, const SourceLocation& where) {
  return {std::move(text), where};
}

uint32_t readIndex(const ConfigNode& node, size_t vertex_count) {
  const double value = node.number();
  if (value != std::floor(value)) node.fail(fmt::format("expected a vertex index, got {}", value));
  if (value < 0 || value >= static_cast<double>(vertex_count))
    node.fail(fmt::format("vertex index {} out of range (the mesh has {} vertices)", value,
                          vertex_count));
  return static_cast<uint32_t>(value);
}

// Places the nominal vertices, turns the triangles outward if asked, and
// requires a closed outward mesh.
void checkNominal(const Shape& shape, std::vector<Triangle>& triangles,
                  std::span<const double> nominal_scalars, bool orient_outward,
                  const SourceLocation& where) {
  TriangleMesh mesh;
  mesh.vertices.resize(shape.vertexCount());
  shape.place(nominal_scalars, mesh.vertices);
  mesh.triangles = triangles;
  if (orient_outward && signedVolume(mesh) < 0) {
    flipOrientation(mesh);
    triangles = mesh.triangles;
  }
  try {
    requireClosedMesh(mesh, where);
  } catch (const Error& e) {
    throw Error("at nominal values: " + e.message(), e.where());
  }
}

// A simple polygon in the plane of axes (a, b), swept along axis c from
// `from` to `to`. Vertices: profile point i at `from` is i, at `to` is n + i.
class ExtrudedShape final : public Shape {
 public:
  ExtrudedShape(const ShapeSpec& spec, std::span<const double> nominal)
      : axes_(spec.axes), n_((spec.scalars.size() - 2) / 2) {
    const SourceLocation& profile_where = spec.profile_where;
    std::vector<Vec2> profile(n_);
    for (size_t i = 0; i < n_; ++i) profile[i] = {nominal[2 * i], nominal[2 * i + 1]};
    if (const std::string problem = simplePolygonProblem(profile); !problem.empty())
      throw Error("at nominal values the profile is not a simple polygon: " + problem,
                  profile_where);
    try {
      cap_ = triangulatePolygon(profile);
    } catch (const Error& e) {
      throw Error(e.message(), profile_where);
    }
    cap_sign_ = signedArea(profile) > 0 ? 1.0 : -1.0;
    const double from = nominal[2 * n_], to = nominal[2 * n_ + 1];
    if (from == to)
      throw Error(
          fmt::format("at nominal values the extrusion has zero length (from = to = {})", from),
          child(spec.where, "to"));
    length_sign_ = to > from ? 1.0 : -1.0;

    // The caps share the profile's winding at `to` and the reverse at
    // `from`; the side quads then run against both caps along every edge, so
    // the surface is consistent for either winding and one global flip (in
    // checkNominal) makes it outward.
    vertex_count_ = 2 * n_;
    const auto n = static_cast<uint32_t>(n_);
    for (const Triangle& t : cap_) {
      triangles_.push_back({n + t[0], n + t[1], n + t[2]});
      triangles_.push_back({t[0], t[2], t[1]});
    }
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t j = (i + 1) % n;
      triangles_.push_back({i, j, n + j});
      triangles_.push_back({i, n + j, n + i});
    }
    checkNominal(*this, triangles_, nominal, /*orient_outward=*/true, spec.where);
  }

  void place(std::span<const double> s, std::span<Vec3> out) const override {
    const double from = s[2 * n_], to = s[2 * n_ + 1];
    for (size_t i = 0; i < n_; ++i) {
      Vec3 p;
      p[axes_[0]] = s[2 * i];
      p[axes_[1]] = s[2 * i + 1];
      p[axes_[2]] = from;
      out[i] = p;
      p[axes_[2]] = to;
      out[n_ + i] = p;
    }
  }

  std::string_view fold(std::span<const double> s) const override {
    if ((s[2 * n_ + 1] - s[2 * n_]) * length_sign_ <= 0)
      return "the extrusion's length reached zero or changed sign";
    auto point = [&](uint32_t i) { return Vec2(s[2 * i], s[2 * i + 1]); };
    for (const Triangle& t : cap_)
      if (orient2d(point(t[0]), point(t[1]), point(t[2])) * cap_sign_ <= 0)
        return "a cap triangle turned over: the profile folds over itself, or moved too far from "
               "nominal for the caps' triangulation";
    return {};
  }

 private:
  std::array<int, 3> axes_;
  size_t n_;                   // profile points
  std::vector<Triangle> cap_;  // profile indices, the profile's winding at nominal
  double cap_sign_ = 1.0;      // sign of the profile's area at nominal
  double length_sign_ = 1.0;   // sign of to - from at nominal
};

// A profile in the (radius, axial) half-plane revolved about an axis. A
// profile point on the axis becomes one pole vertex, any other a ring of
// `segments` vertices on the true circle at angles 2 pi k / segments from u
// towards v. Vertex numbering follows the profile.
class RevolvedShape final : public Shape {
 public:
  RevolvedShape(const ShapeSpec& spec, std::span<const double> nominal)
      : axes_(spec.axes), points_(spec.scalars.size() / 2), segments_(spec.segments) {
    if (segments_ == 0) {
      double radius = 0.0;
      for (size_t i = 0; i < points_; ++i) radius = std::max(radius, nominal[2 * i]);
      segments_ = segmentsForChordError(radius, kChordErrorMm);
    }
    const SourceLocation& profile_where = spec.profile_where;
    if (points_ < 3)
      throw Error(
          fmt::format("a revolution profile needs at least 3 points, this one has {}", points_),
          profile_where);
    std::vector<Vec2> profile(points_);
    size_t pole_count = 0;
    for (size_t i = 0; i < points_; ++i) {
      profile[i] = {nominal[2 * i], nominal[2 * i + 1]};
      if (profile[i].x() < 0)
        throw Error(fmt::format("at nominal values the radius is negative ({} mm)", profile[i].x()),
                    child(profile_where, std::to_string(i)));
      is_pole_.push_back(profile[i].x() == 0);
      pole_count += is_pole_.back();
    }
    // On the axis: none (a ring), or two neighbours closing the profile.
    bool closing_pair = false;
    for (size_t i = 0; i < points_; ++i) closing_pair |= is_pole_[i] && is_pole_[(i + 1) % points_];
    if (pole_count != 0 && !(pole_count == 2 && closing_pair))
      throw Error(fmt::format("at nominal values {} profile points lie on the axis; there must be "
                              "none, or two neighbours whose segment closes the profile",
                              pole_count),
                  profile_where);
    if (const std::string problem = simplePolygonProblem(profile); !problem.empty())
      throw Error("at nominal values the profile is not a simple polygon: " + problem,
                  profile_where);

    // Vertex numbering, and the ring angles.
    for (size_t i = 0; i < points_; ++i) {
      first_vertex_.push_back(static_cast<uint32_t>(vertex_count_));
      vertex_count_ += is_pole_[i] ? 1 : static_cast<size_t>(segments_);
    }
    for (int k = 0; k < segments_; ++k) {
      const double angle = 2.0 * std::numbers::pi * k / segments_;
      cos_.push_back(std::cos(angle));
      sin_.push_back(std::sin(angle));
    }

    // Each profile edge i -> j sweeps a band of quads (a fan where one end
    // is a pole); an edge along the axis sweeps nothing. Quad corners
    // A = (i, k), B = (j, k), C = (j, k + 1), D = (i, k + 1).
    auto vertex = [&](size_t point, int k) {
      return first_vertex_[point] + (is_pole_[point] ? 0u : static_cast<uint32_t>(k % segments_));
    };
    for (size_t i = 0; i < points_; ++i) {
      const size_t j = (i + 1) % points_;
      if (is_pole_[i] && is_pole_[j]) continue;
      for (int k = 0; k < segments_; ++k) {
        const uint32_t a = vertex(i, k), b = vertex(j, k), c = vertex(j, k + 1),
                       d = vertex(i, k + 1);
        if (is_pole_[i]) {
          triangles_.push_back({a, b, c});
        } else if (is_pole_[j]) {
          triangles_.push_back({a, b, d});
        } else {
          triangles_.push_back({a, b, c});
          triangles_.push_back({a, c, d});
        }
      }
    }
    checkNominal(*this, triangles_, nominal, /*orient_outward=*/true, spec.where);
  }

  void place(std::span<const double> s, std::span<Vec3> out) const override {
    for (size_t i = 0; i < points_; ++i) {
      const double radius = s[2 * i], axial = s[2 * i + 1];
      Vec3 p;
      p[axes_[2]] = axial;
      if (is_pole_[i]) {
        p[axes_[0]] = p[axes_[1]] = 0.0;
        out[first_vertex_[i]] = p;
        continue;
      }
      for (int k = 0; k < segments_; ++k) {
        p[axes_[0]] = radius * cos_[k];
        p[axes_[1]] = radius * sin_[k];
        out[first_vertex_[i] + k] = p;
      }
    }
  }

  std::string_view fold(std::span<const double> s) const override {
    for (size_t i = 0; i < points_; ++i) {
      if (is_pole_[i] && s[2 * i] != 0)
        return "a profile point on the axis at nominal values left the axis";
      if (!is_pole_[i] && s[2 * i] <= 0)
        return "a profile point reached or crossed the axis (radius <= 0)";
    }
    return {};
  }

 private:
  std::array<int, 3> axes_;  // u, v, axis
  size_t points_;
  int segments_;
  std::vector<bool> is_pole_;
  std::vector<uint32_t> first_vertex_;
  std::vector<double> cos_, sin_;
};

// Vertices given one by one, triangles given; must be outward as written.
class ListedShape final : public Shape {
 public:
  ListedShape(const ShapeSpec& spec, std::span<const double> nominal) {
    vertex_count_ = spec.scalars.size() / 3;
    triangles_ = spec.triangles;
    checkNominal(*this, triangles_, nominal, /*orient_outward=*/false, spec.where);
  }

  void place(std::span<const double> s, std::span<Vec3> out) const override {
    for (size_t i = 0; i < vertex_count_; ++i) out[i] = {s[3 * i], s[3 * i + 1], s[3 * i + 2]};
  }
};

// A mesh read from an STL or STEP file (already checked by readStl, readStep).
class FixedShape final : public Shape {
 public:
  explicit FixedShape(const TriangleMesh& mesh) : vertices_(mesh.vertices) {
    vertex_count_ = vertices_.size();
    triangles_ = mesh.triangles;
  }

  void place(std::span<const double> /*scalars*/, std::span<Vec3> out) const override {
    std::copy(vertices_.begin(), vertices_.end(), out.begin());
  }

 private:
  std::vector<Vec3> vertices_;
};

}  // namespace

ShapeSpec readShapeSpec(const ConfigNode& shape, const std::filesystem::path& directory,
                        const FaceMoveSources* faces, bool& faces_taken) {
  ShapeSpec spec;
  spec.where = shape.where();
  const ConfigNode type_node = shape.at("type");
  const std::string type = type_node.string();
  if (type == "extrusion") {
    spec.type = ShapeType::kExtrusion;
    const ConfigNode plane = shape.at("plane");
    if (plane.size() != 2) plane.fail("expected the profile's two axes, such as [\"x\", \"z\"]");
    const int a = readAxis(plane[0]), b = readAxis(plane[1]);
    if (a == b) plane.fail("the profile's two axes must differ");
    const ConfigNode axis_node = shape.at("axis");
    const int c = readAxis(axis_node);
    if (c == a || c == b)
      axis_node.fail(fmt::format("the extrusion axis must be the one not in the plane, '{}'",
                                 kAxisNames[3 - a - b]));
    spec.axes = {a, b, c};
    readPoints(shape.at("profile"), 2, spec.scalars);
    spec.profile_where = shape.at("profile").where();
    spec.scalars.push_back(readExpression(shape.at("from")));
    spec.scalars.push_back(readExpression(shape.at("to")));
  } else if (type == "revolution") {
    spec.type = ShapeType::kRevolution;
    const int c = readAxis(shape.at("axis"));
    spec.axes = {(c + 1) % 3, (c + 2) % 3, c};
    readPoints(shape.at("profile"), 2, spec.scalars);
    spec.profile_where = shape.at("profile").where();
    readSegments(shape, spec);
  } else if (type == "box") {
    // An extrusion of the (x, y) rectangle along z.
    spec.type = ShapeType::kExtrusion;
    spec.axes = {0, 1, 2};
    spec.profile_where = spec.where;
    const auto lo = readTriple(shape.at("min"));
    const auto hi = readTriple(shape.at("max"));
    for (const auto* corner : {&lo[0], &lo[1], &hi[0], &lo[1], &hi[0], &hi[1], &lo[0], &hi[1]})
      spec.scalars.push_back(*corner);
    spec.scalars.push_back(lo[2]);
    spec.scalars.push_back(hi[2]);
  } else if (type == "cylinder") {
    // A revolution of the rectangle (0 .. d/2) x (from .. to) about its axis.
    spec.type = ShapeType::kRevolution;
    spec.profile_where = spec.where;
    const int c = readAxis(shape.at("axis"));
    spec.axes = {(c + 1) % 3, (c + 2) % 3, c};
    const ExpressionSource diameter = readExpression(shape.at("diameter"));
    const ExpressionSource from = readExpression(shape.at("from"));
    const ExpressionSource to = readExpression(shape.at("to"));
    const ExpressionSource zero = derivedExpression("0", diameter.where);
    const ExpressionSource radius =
        derivedExpression(fmt::format("({}) / 2", diameter.text), diameter.where);
    for (const auto* s : {&zero, &from, &radius, &from, &radius, &to, &zero, &to})
      spec.scalars.push_back(*s);
    readSegments(shape, spec);
  } else if (type == "mesh") {
    spec.type = ShapeType::kMesh;
    readPoints(shape.at("vertices"), 3, spec.scalars);
    const size_t vertex_count = spec.scalars.size() / 3;
    const ConfigNode triangles = shape.at("triangles");
    if (triangles.size() > kMaxShapeTriangles)
      triangles.fail(fmt::format("{} triangles; at most {} are supported", triangles.size(), kMaxShapeTriangles));
    for (size_t i = 0; i < triangles.size(); ++i) {
      const ConfigNode t = triangles[i];
      if (!t.isArray() || t.size() != 3) t.fail("expected a list of 3 vertex indices");
      spec.triangles.push_back({readIndex(t[0], vertex_count), readIndex(t[1], vertex_count),
                                readIndex(t[2], vertex_count)});
    }
  } else if (type == "stl" || type == "step") {
    spec.type = ShapeType::kFixed;
    const std::filesystem::path file = shape.get<std::string>("file");
    const std::filesystem::path path = file.is_absolute() ? file : directory / file;
    spec.file = path;
    if (type == "stl") {
      spec.fixed = readStl(path, &spec.file_sha256);
    } else if (!faces || faces->empty()) {
      StepSolid solid = readStepSolid(path, readStepTessellation(shape));
      spec.fixed = std::move(solid.mesh);
      spec.file_sha256 = std::move(solid.sha256);
    } else {
      // The part's dimensions move this solid's faces.
      if (faces_taken)
        shape.fail("the part's dimensions name faces, and this is its second \"step\" solid: "
                   "faces can be named on one STEP solid per part");
      faces_taken = true;
      const StepTessellation tessellation = readStepTessellation(shape);
      spec.type = ShapeType::kFaced;
      StepSolid solid = readStepSolid(path, tessellation);
      spec.file_sha256 = solid.sha256;
      spec.faced = resolveFaceMoves(std::move(solid), tessellation.chord_tolerance_mm, *faces,
                                    spec.scalars);
    }
  } else {
    type_node.fail(
        fmt::format("unknown shape type '{}' (known: union, difference, intersection, extrusion, "
                    "revolution, box, cylinder, mesh, stl, step)",
                    type));
  }
  return spec;
}

int segmentsForChordError(double radius_mm, double chord_error_mm) {
  if (!(radius_mm > chord_error_mm)) return 8;
  const double n = std::numbers::pi / std::acos(1.0 - chord_error_mm / radius_mm);
  return static_cast<int>(std::clamp(std::ceil(n), 8.0, 1.0e6));
}

std::unique_ptr<const Shape> buildShape(const ShapeSpec& spec,
                                        std::span<const double> nominal_scalars) {
  switch (spec.type) {
    case ShapeType::kExtrusion:
      return std::make_unique<ExtrudedShape>(spec, nominal_scalars);
    case ShapeType::kRevolution:
      return std::make_unique<RevolvedShape>(spec, nominal_scalars);
    case ShapeType::kMesh:
      return std::make_unique<ListedShape>(spec, nominal_scalars);
    case ShapeType::kFixed:
      return std::make_unique<FixedShape>(spec.fixed);
    case ShapeType::kFaced:
      return buildFacedShape(spec.faced, nominal_scalars);
  }
  XG_CHECK(false, "unknown shape type");
  return nullptr;
}

}  // namespace xgauge
