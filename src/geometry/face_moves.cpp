#include "face_moves.h"

#include "smallest_root_sets.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>

namespace xgauge {
namespace {

constexpr const char* kMoveKinds[] = {"offset", "diameter", "position"};

// Closest distance from p to the triangle (a, b, c) (Ericson, Real-Time
// Collision Detection, 5.1.5: the Voronoi regions of the corners and sides).
double distanceToTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.norm();
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denominator = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denominator) + ac * (vc * denominator))).norm();
}

Vec3 readPoint(const ConfigNode& node) {
  if (!node.isArray() || node.size() != 3) node.fail("expected a list of 3 numbers [x, y, z]");
  return {node[0].number(), node[1].number(), node[2].number()};
}

// Resolves selectors and moves; one per part.
class Resolver {
 public:
  Resolver(FacedStep& faced, const FaceMoveSources& sources, std::vector<ExpressionSource>& scalars)
      : faced_(faced), sources_(sources), scalars_(scalars) {
    const StepSolid& solid = faced_.solid;
    face_triangles_.resize(solid.faces.size());
    for (size_t t = 0; t < solid.triangle_face.size(); ++t)
      face_triangles_[solid.triangle_face[t]].push_back(static_cast<uint32_t>(t));
  }

  // Faces that lie on one surface and share a vertex become one group.
  void groupFaces() {
    const StepSolid& solid = faced_.solid;
    const BoundingBox box = boundingBox(solid.mesh);
    faced_.size_mm = box.diagonal();
    const double tolerance = 1e-7 * std::max(1.0, faced_.size_mm);
    std::vector<std::vector<uint32_t>> vertex_faces(solid.mesh.vertices.size());
    for (size_t t = 0; t < solid.mesh.triangles.size(); ++t)
      for (const uint32_t v : solid.mesh.triangles[t]) {
        auto& faces = vertex_faces[v];
        const uint32_t f = solid.triangle_face[t];
        if (std::find(faces.begin(), faces.end(), f) == faces.end()) faces.push_back(f);
      }
    SmallestRootSets sets(solid.faces.size());
    for (const auto& faces : vertex_faces)
      for (size_t i = 0; i < faces.size(); ++i)
        for (size_t j = i + 1; j < faces.size(); ++j)
          if (solid.faces[faces[i]].surface.sameAs(solid.faces[faces[j]].surface, tolerance,
                                                    faced_.size_mm))
            sets.join(faces[i], faces[j]);
    std::map<size_t, uint32_t> group_of_root;
    faced_.face_group.resize(solid.faces.size());
    for (size_t f = 0; f < solid.faces.size(); ++f) {
      const auto [it, added] = group_of_root.try_emplace(
          sets.root(f), static_cast<uint32_t>(faced_.groups.size()));
      if (added) {
        FaceGroup& group = faced_.groups.emplace_back();
        group.surface = solid.faces[f].surface;
        group.outward = solid.faces[f].outward;
      }
      faced_.face_group[f] = it->second;
      faced_.groups[it->second].faces.push_back(static_cast<uint32_t>(f));
    }
    movers_.resize(faced_.groups.size());
  }

  void resolveMove(const FaceMoveSources::Move& move) {
    const FaceMoveSources::Dimension& dimension = sources_.dimensions[move.dimension];
    const std::string who = fmt::format("dimension '{}', {}", dimension.name, move.kind);
    const ConfigNode& node = move.node;
    if (!node.isObject())
      node.fail(fmt::format("{}: expected an object with \"faces\"", who));
    if (dimension.unit != "mm")
      node.fail(fmt::format("{}: a face move needs a length; the dimension is in {}", who,
                            dimension.unit));
    double ratio = 1.0;
    if (const auto r = node.find("ratio")) {
      ratio = r->number();
      if (ratio == 0.0) r->fail(fmt::format("{}: ratio must not be 0", who));
    }
    const std::vector<uint32_t> groups = selectGroups(node.at("faces"), who);
    const uint32_t scalar = scalarOf(move.dimension, node);
    if (move.kind == "offset") {
      offset(node, who, dimension, groups, scalar, ratio);
    } else if (move.kind == "diameter") {
      diameter(node, who, dimension, groups, scalar, ratio);
    } else {
      position(node, who, dimension, groups, scalar, ratio);
    }
    for (const uint32_t g : groups) addMover(g, dimension.name);
  }

  void resolveSurface(const ConfigNode& entry, size_t index) {
    const std::string who = fmt::format("surfaces[{}]", index);
    const std::vector<uint32_t> groups = selectGroups(entry.at("faces"), who);
    const auto plane = entry.find("plane");
    const auto cylinder = entry.find("cylinder");
    if (plane.has_value() == cylinder.has_value())
      entry.fail(fmt::format("{}: give one of \"plane\" and \"cylinder\"", who));
    FaceGroup::Expressed expressed = FaceGroup::Expressed::kCylinder;
    SurfaceKind kind = SurfaceKind::kCylinder;
    const uint32_t first = static_cast<uint32_t>(scalars_.size());
    const auto points = [&](const ConfigNode& list, size_t count) {
      if (!list.isArray() || list.size() != count)
        list.fail(fmt::format("expected a list of {} points [x, y, z]", count));
      for (size_t i = 0; i < count; ++i) expressions(list[i], 3);
    };
    if (plane) {
      kind = SurfaceKind::kPlane;
      if (const auto through = plane->find("through")) {
        expressed = FaceGroup::Expressed::kPlaneThrough;
        points(*through, 3);
      } else {
        expressed = FaceGroup::Expressed::kPlaneNormal;
        expressions(plane->at("point"), 3);
        expressions(plane->at("normal"), 3);
      }
    } else {
      expressions(cylinder->at("point"), 3);
      expressions(cylinder->at("axis"), 3);
      scalars_.push_back(readExpression(cylinder->at("diameter")));
    }
    for (uint32_t s = first; s < scalars_.size(); ++s) {
      faced_.scalar_names.push_back(who);
      faced_.scalar_ranges.emplace_back(std::numeric_limits<double>::quiet_NaN(),
                                        std::numeric_limits<double>::quiet_NaN());
    }
    for (const uint32_t g : groups) {
      FaceGroup& group = faced_.groups[g];
      if (group.surface.kind != kind)
        entry.fail(fmt::format("{}: {} is a {}, not a {}", who, faced_.describeFace(group.faces[0]),
                               surfaceKindName(group.surface.kind), surfaceKindName(kind)));
      if (group.expressed != FaceGroup::Expressed::kNone)
        entry.fail(fmt::format("{}: {} is already given by {}", who,
                               faced_.describeFace(group.faces[0]),
                               fmt::join(movers_[g], ", ")));
      group.expressed = expressed;
      group.first_scalar = first;
      group.where = entry.where();
      addMover(g, who);
    }
  }

  // A face moved both ways is refused: its surface has one definition.
  void requireOneDefinitionPerFace() const {
    for (size_t g = 0; g < faced_.groups.size(); ++g) {
      const FaceGroup& group = faced_.groups[g];
      if (group.expressed != FaceGroup::Expressed::kNone && !group.terms.empty())
        throw Error(fmt::format("{} is given by a \"surfaces\" entry and moved by a dimension "
                                "({}): a face has one definition",
                                faced_.describeFace(group.faces[0]), faced_.movers(g)),
                    group.where);
    }
  }

  void finish() {
    faced_.group_movers = std::move(movers_);
  }

 private:
  void expressions(const ConfigNode& list, size_t count) {
    if (!list.isArray() || list.size() != count)
      list.fail(fmt::format("expected a list of {} expressions", count));
    for (size_t i = 0; i < count; ++i) scalars_.push_back(readExpression(list[i]));
  }

  uint32_t scalarOf(size_t dimension, const ConfigNode& node) {
    const auto found = dimension_scalar_.find(dimension);
    if (found != dimension_scalar_.end()) return found->second;
    const auto index = static_cast<uint32_t>(scalars_.size());
    scalars_.push_back({sources_.dimensions[dimension].name, node.where()});
    faced_.scalar_names.push_back(sources_.dimensions[dimension].name);
    faced_.scalar_ranges.emplace_back(sources_.dimensions[dimension].min,
                                      sources_.dimensions[dimension].max);
    dimension_scalar_.emplace(dimension, index);
    return index;
  }

  void addMover(uint32_t group, const std::string& name) {
    auto& names = movers_[group];
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  }

  // The groups of the faces a list of selectors (or one selector) names.
  std::vector<uint32_t> selectGroups(const ConfigNode& selectors, const std::string& who) {
    std::vector<uint32_t> groups;
    const auto add = [&](const ConfigNode& selector) {
      const uint32_t g = faced_.face_group[selectFace(selector, who)];
      if (std::find(groups.begin(), groups.end(), g) == groups.end()) groups.push_back(g);
    };
    if (selectors.isArray()) {
      if (selectors.size() == 0) selectors.fail(fmt::format("{}: the list of faces is empty", who));
      for (size_t i = 0; i < selectors.size(); ++i) add(selectors[i]);
    } else {
      add(selectors);
    }
    return groups;
  }

  size_t selectFace(const ConfigNode& selector, const std::string& who) {
    const StepSolid& solid = faced_.solid;
    const size_t count = solid.faces.size();
    if (selector.isNumber()) {
      return static_cast<size_t>(selector.integer(1, static_cast<int64_t>(count))) - 1;
    }
    if (selector.isString()) {
      const std::string text = selector.string();
      if (text.starts_with("#")) {
        int entity = 0;
        try {
          size_t used = 0;
          entity = std::stoi(text.substr(1), &used);
          if (used + 1 != text.size()) entity = 0;
        } catch (const std::exception&) {
          entity = 0;
        }
        for (size_t f = 0; f < count; ++f)
          if (entity > 0 && solid.faces[f].entity == entity) return f;
        std::vector<int> known;
        for (const StepFace& face : solid.faces)
          if (face.entity > 0) known.push_back(face.entity);
        selector.fail(fmt::format("{}: {} is no face of the STEP solid ({})", who, text,
                                  known.empty() ? std::string("its faces carry no entity numbers")
                                                : fmt::format("its faces are the entities #{}",
                                                              fmt::join(known, ", #"))));
      }
      std::vector<size_t> named;
      for (size_t f = 0; f < count; ++f)
        if (solid.faces[f].name == text) named.push_back(f);
      if (named.size() == 1) return named[0];
      if (named.empty())
        selector.fail(fmt::format("{}: no face of the STEP solid is named '{}'", who, text));
      selector.fail(fmt::format("{}: {} faces are named '{}' ({} and {}); choose one by \"at\"",
                                who, named.size(), text, solid.describe(named[0]),
                                solid.describe(named[1])));
    }
    if (!selector.isObject())
      selector.fail(fmt::format("{}: a face is chosen by {{\"at\": [x, y, z]}}, \"#entity\", its "
                                "name or its number",
                                who));
    const Vec3 point = readPoint(selector.at("at"));
    std::vector<std::pair<double, size_t>> distance;  // (mm, face)
    for (size_t f = 0; f < count; ++f) {
      double nearest = std::numeric_limits<double>::infinity();
      for (const uint32_t t : face_triangles_[f]) {
        const Triangle& tri = solid.mesh.triangles[t];
        nearest = std::min(nearest, distanceToTriangle(point, solid.mesh.vertices[tri[0]],
                                                       solid.mesh.vertices[tri[1]],
                                                       solid.mesh.vertices[tri[2]]));
      }
      // A curved face's triangles lie within the chord tolerance of it; its
      // surface itself decides where it is analytic.
      const Surface& surface = solid.faces[f].surface;
      if (surface.kind != SurfaceKind::kOther && nearest < 1.0)
        nearest = std::max(std::abs(surface.value(point)), nearest - chordSlack());
      distance.emplace_back(nearest, f);
    }
    std::sort(distance.begin(), distance.end());
    // Faces that continue one surface (coplanar faces a boolean left
    // split, a cylinder's halves) count as one: the group moves whole.
    std::vector<size_t> on;
    for (const auto& [d, f] : distance)
      if (d <= kFaceSelectionMm &&
          std::none_of(on.begin(), on.end(), [&](size_t other) {
            return faced_.face_group[other] == faced_.face_group[f];
          }))
        on.push_back(f);
    const std::string where =
        fmt::format("({}, {}, {})", point.x(), point.y(), point.z());
    if (on.empty())
      selector.fail(fmt::format("{}: no face within {} mm of {}; the nearest is {}, {:.4g} mm away",
                                who, kFaceSelectionMm, where, solid.describe(distance[0].second),
                                distance[0].first));
    if (on.size() > 1)
      selector.fail(fmt::format("{}: {} lies on {} faces within {} mm, {} and {}: move the point "
                                "into the face you mean",
                                who, where, on.size(), kFaceSelectionMm, solid.describe(on[0]),
                                solid.describe(on[1])));
    return on[0];
  }

  // How far a curved face's triangles may lie from it (mm).
  double chordSlack() const { return 2.0 * faced_.chord_tolerance_mm; }

  const FaceGroup& group(uint32_t g) const { return faced_.groups[g]; }
  std::string face(uint32_t g) const { return faced_.describeFace(faced_.groups[g].faces[0]); }

  void requireKinds(const ConfigNode& node, const std::string& who,
                    const std::vector<uint32_t>& groups, std::initializer_list<SurfaceKind> kinds,
                    const char* what) const {
    for (const uint32_t g : groups)
      if (std::find(kinds.begin(), kinds.end(), group(g).surface.kind) == kinds.end())
        node.fail(fmt::format("{}: {} is a {}; {}", who, face(g),
                              faced_.solid.faces[group(g).faces[0]].surface_type, what));
  }

  void offset(const ConfigNode& node, const std::string& who,
              const FaceMoveSources::Dimension& dimension, const std::vector<uint32_t>& groups,
              uint32_t scalar, double ratio) {
    requireKinds(node, who, groups,
                 {SurfaceKind::kPlane, SurfaceKind::kCylinder, SurfaceKind::kCone,
                  SurfaceKind::kSphere, SurfaceKind::kTorus},
                 "offset moves analytic faces along their normal (a freeform face can only be "
                 "moved by \"position\")");
    const auto datum_node = node.find("datum");
    const bool split = node.get<bool>("split", false);
    if (split && !datum_node)
      node.fail(fmt::format("{}: \"split\" moves the faces and the datum by half each: give "
                            "\"datum\"",
                            who));
    double share = ratio;
    if (datum_node) {
      if (ratio != 1.0)
        datum_node->fail(fmt::format("{}: a datum states the dimension's value: ratio must be 1",
                                     who));
      const std::vector<uint32_t> datum = selectGroups(*datum_node, who + " datum");
      const std::vector<uint32_t> both = [&] {
        std::vector<uint32_t> all = groups;
        all.insert(all.end(), datum.begin(), datum.end());
        return all;
      }();
      requireKinds(node, who, both, {SurfaceKind::kPlane},
                   "a distance from a datum is between parallel planes");
      const Surface& reference = group(datum[0]).surface;
      for (const uint32_t g : both) {
        const Surface& s = group(g).surface;
        if (s.axis.cross(reference.axis).norm() > kNominalAgreementMm / faced_.size_mm)
          node.fail(fmt::format("{}: {} is not parallel to the datum {}", who, face(g),
                                face(datum[0])));
      }
      for (const uint32_t g : groups) {
        const double distance = std::abs(reference.axis.dot(group(g).surface.origin -
                                                            reference.origin));
        if (std::abs(distance - dimension.nominal) > kNominalAgreementMm)
          node.fail(fmt::format("{}: {} is {:.6g} mm from the datum {}, not the nominal {} mm",
                                who, face(g), distance, face(datum[0]), dimension.nominal));
      }
      for (const uint32_t g : datum)
        if (std::find(groups.begin(), groups.end(), g) != groups.end())
          datum_node->fail(fmt::format("{}: {} is both moved and the datum", who, face(g)));
      // Each face moves away from the other side, so that their distance is
      // the value: along its outward normal across material (a thickness),
      // against it across a gap (a slot's width).
      const auto away = [&](uint32_t g, const Surface& other) {
        const Surface& s = group(g).surface;
        return s.axis.dot(s.origin - other.origin) >= 0.0 ? 1.0 : -1.0;
      };
      const Surface& moving = group(groups[0]).surface;
      if (split) {
        share = 0.5;
        for (const uint32_t g : datum) addGrowth(g, scalar, 0.5 * away(g, moving));
      }
      for (const uint32_t g : groups) addGrowth(g, scalar, share * away(g, reference));
      return;
    }
    // Without a datum: along the outward normal (material added).
    for (const uint32_t g : groups) addGrowth(g, scalar, share * group(g).outward);
  }

  void diameter(const ConfigNode& node, const std::string& who,
                const FaceMoveSources::Dimension& dimension, const std::vector<uint32_t>& groups,
                uint32_t scalar, double ratio) {
    requireKinds(node, who, groups,
                 {SurfaceKind::kCylinder, SurfaceKind::kCone, SurfaceKind::kSphere},
                 "a diameter is of cylinders, cones or spheres");
    std::optional<Vec3> station;
    if (const auto at = node.find("station")) station = readPoint(*at);
    for (const uint32_t g : groups) {
      const Surface& s = group(g).surface;
      double diameter = 2.0 * s.radius;
      if (s.kind == SurfaceKind::kCone) {
        if (!station)
          node.fail(fmt::format("{}: {} is a cone, whose diameter is stated at a station: give "
                                "\"station\": [x, y, z], a point of the plane across its axis",
                                who, face(g)));
        diameter = s.diameterAt(*station);
      }
      if (ratio == 1.0 && std::abs(diameter - dimension.nominal) > kNominalAgreementMm)
        node.fail(fmt::format("{}: {} has a diameter of {:.6g} mm{}, not the nominal {} mm", who,
                              face(g), diameter, station ? " at the station" : "",
                              dimension.nominal));
      addGrowth(g, scalar, 0.5 * ratio);
    }
  }

  void position(const ConfigNode& node, const std::string& who,
                const FaceMoveSources::Dimension& dimension, const std::vector<uint32_t>& groups,
                uint32_t scalar, double ratio) {
    const ConfigNode direction_node = node.at("direction");
    const Vec3 direction = readPoint(direction_node);
    if (!(direction.norm() > 0))
      direction_node.fail(fmt::format("{}: the direction must not be zero", who));
    const Vec3 unit = direction.normalized();
    if (const auto datum_node = node.find("datum")) {
      if (ratio != 1.0)
        datum_node->fail(fmt::format("{}: a datum states the dimension's value: ratio must be 1",
                                     who));
      const std::vector<uint32_t> datum = selectGroups(*datum_node, who + " datum");
      // Where along the direction a surface lies: a plane across it, or the
      // axis or centre of a curved surface.
      const auto station = [&](uint32_t g) {
        const Surface& s = group(g).surface;
        if (s.kind == SurfaceKind::kOther)
          node.fail(fmt::format("{}: {} is freeform: it has no axis or plane to measure a "
                                "position from",
                                who, face(g)));
        if (s.kind == SurfaceKind::kPlane && std::abs(std::abs(s.axis.dot(unit)) - 1.0) > 1e-9)
          node.fail(fmt::format("{}: the plane {} does not lie across the direction", who,
                                face(g)));
        return s.origin.dot(unit);
      };
      const double separation = std::abs(station(groups[0]) - station(datum[0]));
      if (std::abs(separation - dimension.nominal) > kNominalAgreementMm)
        node.fail(fmt::format("{}: {} lies {:.6g} mm from the datum {} along the direction, not "
                              "the nominal {} mm",
                              who, face(groups[0]), separation, face(datum[0]),
                              dimension.nominal));
    }
    for (const uint32_t g : groups)
      faced_.groups[g].terms.push_back({scalar, ratio * unit, 0.0});
  }

  void addGrowth(uint32_t g, uint32_t scalar, double growth) {
    faced_.groups[g].terms.push_back({scalar, Vec3::Zero(), growth});
  }

  FacedStep& faced_;
  const FaceMoveSources& sources_;
  std::vector<ExpressionSource>& scalars_;
  std::vector<std::vector<uint32_t>> face_triangles_;
  std::map<size_t, uint32_t> dimension_scalar_;
  std::vector<std::vector<std::string>> movers_;
};

}  // namespace

void readFaceMoves(const ConfigNode& entry, FaceMoveSources& sources) {
  for (const char* kind : kMoveKinds) {
    const auto node = entry.find(kind);
    if (!node) continue;
    const auto add = [&](const ConfigNode& move) {
      sources.moves.push_back({sources.dimensions.size() - 1, kind, move});
    };
    if (node->isArray()) {
      if (node->size() == 0) node->fail("an empty list of moves");
      for (size_t i = 0; i < node->size(); ++i) add((*node)[i]);
    } else {
      add(*node);
    }
  }
}

Surface FaceGroup::at(std::span<const double> s, std::span<const double> nominal) const {
  const auto point = [&](uint32_t i) { return Vec3(s[i], s[i + 1], s[i + 2]); };
  Surface moved = surface;
  switch (expressed) {
    case Expressed::kNone: {
      Vec3 translation = Vec3::Zero();
      double growth = 0.0;
      for (const Term& term : terms) {
        const double delta = s[term.scalar] - nominal[term.scalar];
        translation += delta * term.translation;
        growth += delta * term.growth;
      }
      return surface.moved(translation, growth);
    }
    case Expressed::kPlaneThrough: {
      const Vec3 a = point(first_scalar), b = point(first_scalar + 3), c = point(first_scalar + 6);
      moved.origin = a;
      moved.axis = (b - a).cross(c - a).normalized();
      return moved;
    }
    case Expressed::kPlaneNormal:
      moved.origin = point(first_scalar);
      moved.axis = point(first_scalar + 3).normalized();
      return moved;
    case Expressed::kCylinder:
      moved.origin = point(first_scalar);
      moved.axis = point(first_scalar + 3).normalized();
      moved.radius = 0.5 * s[first_scalar + 6];
      return moved;
  }
  return moved;
}

std::string FacedStep::describeFace(size_t face) const { return solid.describe(face); }

std::string FacedStep::movers(size_t group) const {
  if (group >= group_movers.size() || group_movers[group].empty()) return "nothing";
  return fmt::format("{}", fmt::join(group_movers[group], ", "));
}

std::shared_ptr<const FacedStep> resolveFaceMoves(StepSolid solid, double chord_tolerance_mm,
                                                  const FaceMoveSources& sources,
                                                  std::vector<ExpressionSource>& scalars) {
  auto faced = std::make_shared<FacedStep>();
  faced->solid = std::move(solid);
  faced->chord_tolerance_mm = chord_tolerance_mm;
  Resolver resolver(*faced, sources, scalars);
  resolver.groupFaces();
  for (const FaceMoveSources::Move& move : sources.moves) resolver.resolveMove(move);
  if (sources.surfaces) {
    const ConfigNode& list = *sources.surfaces;
    if (!list.isArray()) list.fail("expected a list of {\"faces\", \"plane\" or \"cylinder\"}");
    for (size_t i = 0; i < list.size(); ++i) resolver.resolveSurface(list[i], i);
  }
  resolver.finish();
  resolver.requireOneDefinitionPerFace();
  return faced;
}

}  // namespace xgauge
