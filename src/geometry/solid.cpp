#include "solid.h"

#include "face_moves.h"

#include "xgauge/geometry/polygon.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {
namespace {

// Reads the tree depth first, appending pieces, placements and the postfix
// program to `spec`.
class TreeReader {
 public:
  TreeReader(const std::filesystem::path& directory, const FaceMoveSources* faces, SolidSpec& spec)
      : directory_(directory), faces_(faces), spec_(spec) {}

  // Whether a "step" shape took the face moves.
  bool facesTaken() const { return faces_taken_; }

  void read(const ConfigNode& node, const std::vector<uint32_t>& outer) {
    const std::vector<uint32_t> chain = placementChain(node, outer);
    const std::string type = node.at("type").string();
    if (type == "union" || type == "difference" || type == "intersection") {
      const ConfigNode solids = node.at("solids");
      if (!solids.isArray() || solids.size() == 0)
        solids.fail(fmt::format("{} {} needs a list of one or more solids",
                                type == "intersection" ? "an" : "a", type));
      for (size_t i = 0; i < solids.size(); ++i) read(solids[i], chain);
      const Csg::Op op = type == "union"        ? Csg::Op::kUnion
                         : type == "difference" ? Csg::Op::kDifference
                                                : Csg::Op::kIntersection;
      spec_.program.push_back({op, static_cast<uint32_t>(solids.size())});
      return;
    }
    ShapeSpec shape = readShapeSpec(node, directory_, faces_, faces_taken_);
    const auto holes = type == "extrusion" ? node.find("holes") : std::nullopt;
    if (!holes) {
      addPiece(node, std::move(shape), chain);
      return;
    }
    // Holes through an extrusion: the outer prism minus prisms of the holes,
    // made longer than the outer one by a twentieth of its length at each end
    // so that no cap of a hole coincides with an outer cap.
    if (!holes->isArray() || holes->size() == 0)
      holes->fail("expected a list of hole profiles, each a list of [a, b] points");
    std::vector<ShapeSpec> hole_shapes;
    const ExpressionSource& from = shape.scalars[shape.scalars.size() - 2];
    const ExpressionSource& to = shape.scalars.back();
    for (size_t h = 0; h < holes->size(); ++h) {
      const ConfigNode profile = (*holes)[h];
      if (!profile.isArray() || profile.size() < 3)
        profile.fail("expected a hole profile: a list of at least 3 [a, b] points");
      ShapeSpec hole = shape;
      hole.where = profile.where();
      hole.profile_where = profile.where();
      hole.scalars.clear();
      for (size_t i = 0; i < profile.size(); ++i) {
        const ConfigNode point = profile[i];
        if (!point.isArray() || point.size() != 2) point.fail("expected a list of 2 expressions");
        hole.scalars.push_back(readExpression(point[0]));
        hole.scalars.push_back(readExpression(point[1]));
      }
      hole.scalars.push_back(
          {fmt::format("({0}) - (({1}) - ({0})) / 20", from.text, to.text), from.where});
      hole.scalars.push_back(
          {fmt::format("({1}) + (({1}) - ({0})) / 20", from.text, to.text), to.where});
      hole_shapes.push_back(std::move(hole));
    }
    addPiece(node, std::move(shape), chain);
    for (ShapeSpec& hole : hole_shapes) addPiece(node, std::move(hole), chain);
    spec_.program.push_back({Csg::Op::kDifference, static_cast<uint32_t>(hole_shapes.size() + 1)});
  }

 private:
  // The node's own placement (if it has "rotate" or "translate") before the
  // enclosing ones.
  std::vector<uint32_t> placementChain(const ConfigNode& node, const std::vector<uint32_t>& outer) {
    const auto rotate = node.find("rotate");
    const auto translate = node.find("translate");
    if (!rotate && !translate) return outer;
    SolidSpec::Placement placement{spec_.scalars.size()};
    for (const auto& part : {rotate, translate}) {
      if (!part) {
        for (int k = 0; k < 3; ++k) spec_.scalars.push_back({"0", node.where()});
        continue;
      }
      if (!part->isArray() || part->size() != 3) part->fail("expected a list of 3 expressions");
      for (size_t k = 0; k < 3; ++k) spec_.scalars.push_back(readExpression((*part)[k]));
    }
    std::vector<uint32_t> chain{static_cast<uint32_t>(spec_.placements.size())};
    spec_.placements.push_back(placement);
    chain.insert(chain.end(), outer.begin(), outer.end());
    return chain;
  }

  void addPiece(const ConfigNode& node, ShapeSpec shape, const std::vector<uint32_t>& chain) {
    if (spec_.pieces.size() == Csg::kMaxPieces)
      node.fail(fmt::format("a part has at most {} solids (holes of an extrusion count as solids)",
                            Csg::kMaxPieces));
    SolidSpec::Piece piece;
    piece.first_scalar = spec_.scalars.size();
    spec_.scalars.insert(spec_.scalars.end(), shape.scalars.begin(), shape.scalars.end());
    piece.shape = std::move(shape);
    piece.placements = chain;
    spec_.program.push_back({Csg::Op::kPiece, static_cast<uint32_t>(spec_.pieces.size())});
    spec_.pieces.push_back(std::move(piece));
  }

  const std::filesystem::path& directory_;
  const FaceMoveSources* faces_;
  bool faces_taken_ = false;
  SolidSpec& spec_;
};

// Why a closed surface with these vertex positions is not a solid: negative
// or (almost) zero signed volume; nullopt when it is one. Linear in the
// triangle count, so cheap beside any render.
// `own`: the vertices of this surface; `triangles` index `vertices`.
std::optional<std::string> turnedInsideOut(std::span<const Vec3> vertices,
                                           std::span<const Vec3> own,
                                           std::span<const Triangle> triangles) {
  if (own.empty()) return std::nullopt;
  Vec3 lo = own.front(), hi = lo;
  for (const Vec3& v : own) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  const double diagonal = (hi - lo).norm();
  const double volume = signedVolume(vertices, triangles);
  if (volume > kZeroAreaTolerance * diagonal * diagonal * diagonal) return std::nullopt;
  return volume < 0
             ? fmt::format("the surface turns inside out (signed volume {:.6g} mm^3)", volume)
             : fmt::format("the surface encloses no volume ({:.6g} mm^3)", volume);
}

}  // namespace

SolidSpec readSolidSpec(const ConfigNode& shape, const std::filesystem::path& directory,
                        const FaceMoveSources* faces) {
  SolidSpec spec;
  spec.where = shape.where();
  const std::string type = shape.at("type").string();
  const bool moved = faces && !faces->empty();
  if (type == "stl" || (type == "step" && !moved)) spec.fixed_root = type;
  TreeReader reader(directory, faces, spec);
  reader.read(shape, {});
  if (moved && !reader.facesTaken())
    throw Error("the dimensions name faces (\"offset\", \"diameter\", \"position\" or "
                "\"surfaces\"), which only a \"step\" solid has; the shape has none",
                faces->where);
  return spec;
}

Solid::Solid(const SolidSpec& spec, std::span<const double> nominal_scalars) {
  std::vector<uint32_t> ends;
  for (const SolidSpec::Piece& p : spec.pieces) {
    Piece piece;
    piece.first_scalar = p.first_scalar;
    piece.scalar_count = p.shape.scalars.size();
    piece.shape = buildShape(p.shape, nominal_scalars.subspan(p.first_scalar, piece.scalar_count));
    piece.first_vertex = static_cast<uint32_t>(vertex_count_);
    piece.first_triangle = static_cast<uint32_t>(triangles_.size());
    for (const Triangle& t : piece.shape->triangles())
      triangles_.push_back(
          {t[0] + piece.first_vertex, t[1] + piece.first_vertex, t[2] + piece.first_vertex});
    piece.triangle_end = static_cast<uint32_t>(triangles_.size());
    vertex_count_ += piece.shape->vertexCount();
    XG_CHECK(vertex_count_ < (uint64_t{1} << 32), "too many vertices");
    piece.placements = p.placements;
    piece.where = p.shape.where;
    if (p.shape.faced) {
      faced_ = p.shape.faced;
      faced_first_triangle_ = piece.first_triangle;
    }
    ends.push_back(piece.triangle_end);
    pieces_.push_back(std::move(piece));
  }
  for (const SolidSpec::Placement& placement : spec.placements)
    placement_scalars_.push_back(placement.first_scalar);
  if (pieces_.size() > 1) csg_ = std::make_shared<const Csg>(std::move(ends), spec.program);
}

void Solid::place(std::span<const double> scalars, std::span<Vec3> out) const {
  for (const Piece& piece : pieces_) {
    const std::span<Vec3> vertices = out.subspan(piece.first_vertex, piece.shape->vertexCount());
    piece.shape->place(scalars.subspan(piece.first_scalar, piece.scalar_count), vertices);
    for (uint32_t p : piece.placements) {
      const double* s = scalars.data() + placement_scalars_[p];
      const Pose pose = Pose::fromEulerDeg({s[0], s[1], s[2]}, {s[3], s[4], s[5]});
      for (Vec3& v : vertices) v = pose.apply(v);
    }
  }
}

std::optional<std::string> Solid::placementProblem(const Piece& piece,
                                                  std::span<const double> scalars,
                                                  std::span<const Vec3> vertices) const {
  const std::span<const Vec3> own =
      vertices.subspan(piece.first_vertex, piece.shape->vertexCount());
  const std::span<const double> own_scalars =
      scalars.subspan(piece.first_scalar, piece.scalar_count);
  if (piece.placements.empty()) return piece.shape->placementProblem(own_scalars, own);
  // The piece's vertices back in its own frame: undo its placements,
  // outermost first.
  thread_local std::vector<Vec3> unplaced;
  unplaced.assign(own.begin(), own.end());
  for (auto p = piece.placements.rbegin(); p != piece.placements.rend(); ++p) {
    const double* s = scalars.data() + placement_scalars_[*p];
    const Pose pose = Pose::fromEulerDeg({s[0], s[1], s[2]}, {s[3], s[4], s[5]});
    for (Vec3& v : unplaced) v = pose.rotation.transpose() * (v - pose.translation_mm);
  }
  return piece.shape->placementProblem(own_scalars, unplaced);
}

std::optional<Solid::Problem> Solid::problem(std::span<const double> scalars,
                                             std::span<const Vec3> vertices) const {
  for (const Piece& piece : pieces_) {
    std::optional<std::string> why;
    if (const std::string_view fold =
            piece.shape->fold(scalars.subspan(piece.first_scalar, piece.scalar_count));
        !fold.empty())
      why = std::string(fold);
    if (!why) why = placementProblem(piece, scalars, vertices);
    // The connectivity is fixed and was checked at load; what values can
    // break is the orientation: a surface turned inside out, or flattened.
    if (!why)
      why = turnedInsideOut(
          vertices, vertices.subspan(piece.first_vertex, piece.shape->vertexCount()),
          std::span<const Triangle>(triangles_)
              .subspan(piece.first_triangle, piece.triangle_end - piece.first_triangle));
    if (!why) continue;
    if (pieces_.size() > 1) *why = fmt::format("solid {}: {}", piece.where.key_path, *why);
    return Problem{std::move(*why), piece.where};
  }
  return std::nullopt;
}

}  // namespace xgauge
