// Rendering CSG parts (geometry/csg.h, src/xray/csg_paths.h): closed forms,
// an independent along-the-ray boolean of convex pieces, watertightness of
// the reference parts 5 and 6, smoothness in a hole's diameter, and
// determinism. The file side (solids, placements, errors) is tested in
// src/geometry/solid_test.cpp.
#include "xgauge/xray/renderer.h"

#include "test_machines.h"

#include "xgauge/core/config.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_sum.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <numbers>
#include <random>

namespace xgauge {
namespace {

using testing::kParts;
using testing::posed;
using testing::randomPose;
using testing::squareMachine;
constexpr double kPi = std::numbers::pi;

PartModel partFromText(const std::string& text) {
  return PartModel::fromConfig(ConfigNode::parse(text, "csg_test.json"), "csg_test.json");
}

// Places `centre` (part frame) at `at` after rotating by Euler angles (deg).
Pose poseAbout(const Vec3& angles_deg, const Vec3& centre, const Vec3& at) {
  Pose pose = Pose::fromEulerDeg(angles_deg, Vec3::Zero());
  pose.translation_mm = at - pose.rotation * centre;
  return pose;
}

// The ray from the source to the centre of pixel (u, v), in the part frame:
// o + s dir, s in [0, 1] from the source to the detector; |dir| = |P - S|.
struct PartRay {
  Vec3 o, dir;
};
PartRay partRay(const Machine& m, const Pose& pose, int u, int v) {
  const Mat3 back = pose.rotation.transpose();
  const Vec3 o = back * (m.sourceWorld() - pose.translation_mm);
  const Vec3 p = back * (m.detectorPoint(u + 0.5, v + 0.5) - pose.translation_mm);
  return {o, p - o};
}

// ---------------------------------------------------------------------------
// An independent CSG along a ray: every piece of the parts below is a convex
// polyhedron (a box, or a prism over the inscribed regular N-gon of a
// cylinder, vertices on the true circle). Each piece's interval on the ray
// comes from clipping against its face planes (Cyrus-Beck); the booleans are
// evaluated on the elementary segments between all interval ends.

struct HalfSpace {
  Vec3 normal;  // the inside is normal . X <= offset
  double offset;
};
using Convex = std::vector<HalfSpace>;

Convex placed(Convex body, const Pose& pose) {
  for (HalfSpace& h : body) {
    h.normal = pose.rotation * h.normal;
    h.offset += h.normal.dot(pose.translation_mm);
  }
  return body;
}

Convex box(const Vec3& lo, const Vec3& hi) {
  Convex body;
  for (int axis = 0; axis < 3; ++axis) {
    body.push_back({Vec3::Unit(axis), hi[axis]});
    body.push_back({-Vec3::Unit(axis), -lo[axis]});
  }
  return body;
}

// A cylinder's faceted model as the reader builds it (docs/formats.md,
// part_model.h): axis `a` with (u, v, a) right-handed (x -> (y, z),
// y -> (z, x), z -> (x, y)), N vertices per ring on the circle of `radius`
// at angles 2 pi k / N from u towards v; so face k's outward normal points
// at angle 2 pi (k + 1/2) / N, at distance r cos(pi / N) from the axis.
Convex prism(int a, double radius, double from, double to, int segments) {
  const int u = (a + 1) % 3, v = (a + 2) % 3;
  Convex body;
  for (int k = 0; k < segments; ++k) {
    const double angle = 2 * kPi * (k + 0.5) / segments;
    Vec3 normal = Vec3::Zero();
    normal[u] = std::cos(angle);
    normal[v] = std::sin(angle);
    body.push_back({normal, radius * std::cos(kPi / segments)});
  }
  body.push_back({Vec3::Unit(a), to});
  body.push_back({-Vec3::Unit(a), -from});
  return body;
}

// A prism along z over a convex polygon in (x, y), either winding.
Convex prismOver(const std::vector<Vec2>& polygon, double from, double to) {
  double area = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& p = polygon[i];
    const Vec2& q = polygon[(i + 1) % polygon.size()];
    area += p.x() * q.y() - q.x() * p.y();
  }
  Convex body = {{Vec3::UnitZ(), to}, {-Vec3::UnitZ(), -from}};
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& p = polygon[i];
    const Vec2& q = polygon[(i + 1) % polygon.size()];
    // Outward: to the right of the edge for a counter-clockwise polygon.
    Vec3 normal(q.y() - p.y(), p.x() - q.x(), 0.0);
    if (area < 0) normal = -normal;
    body.push_back({normal, normal.x() * p.x() + normal.y() * p.y()});
  }
  return body;
}

struct Interval {
  double lo = 0.0, hi = 0.0;  // in s; empty when hi <= lo
};

Interval clip(const Convex& body, const PartRay& ray) {
  Interval in{0.0, 1.0};
  for (const HalfSpace& h : body) {
    const double nd = h.normal.dot(ray.dir), no = h.normal.dot(ray.o);
    if (nd == 0.0) {
      if (no > h.offset) return {};
      continue;
    }
    const double s = (h.offset - no) / nd;
    if (nd > 0) in.hi = std::min(in.hi, s);
    else in.lo = std::max(in.lo, s);
  }
  return in.hi > in.lo ? in : Interval{};
}

// Path length (mm) through the set whose membership, given which pieces
// contain a point (bit i: piece i), is `contains`.
double csgPath(const std::vector<Convex>& pieces, const std::function<bool(uint64_t)>& contains,
               const PartRay& ray) {
  std::vector<Interval> in;
  std::vector<double> ends;
  for (const Convex& piece : pieces) {
    in.push_back(clip(piece, ray));
    if (in.back().hi > in.back().lo) ends.insert(ends.end(), {in.back().lo, in.back().hi});
  }
  std::sort(ends.begin(), ends.end());
  double length = 0.0;
  for (size_t i = 0; i + 1 < ends.size(); ++i) {
    if (!(ends[i + 1] > ends[i])) continue;
    const double mid = 0.5 * (ends[i] + ends[i + 1]);
    uint64_t mask = 0;
    for (size_t p = 0; p < in.size(); ++p)
      if (in[p].lo < mid && mid < in[p].hi) mask |= uint64_t{1} << p;
    if (contains(mask)) length += ends[i + 1] - ends[i];
  }
  return length * ray.dir.norm();
}

// Segments of a cylinder piece: its triangle count is 4 N (two fans and a
// band).
int cylinderSegments(const Csg& csg, size_t piece) {
  const auto ends = csg.pieceTriangleEnds();
  const uint32_t count = ends[piece] - (piece == 0 ? 0 : ends[piece - 1]);
  EXPECT_EQ(count % 4, 0u);
  return static_cast<int>(count / 4);
}

// Renders `model` at `poses` random poses about `centre` and compares every
// pixel with the independent CSG; returns the number of pixels the part
// covers and the largest difference.
struct Agreement {
  double worst = 0.0;
  long hits = 0;
};
Agreement compareWithConvexCsg(const PartModel& model, const std::vector<double>& values,
                               const std::vector<Convex>& pieces,
                               const std::function<bool(uint64_t)>& contains, const Vec3& centre,
                               int poses, uint64_t seed) {
  const Machine m = squareMachine(200, 0.5);
  const TriangleMesh mesh = model.mesh(values);
  std::mt19937_64 rng(seed);
  std::vector<Vec3> world;
  ImageT<double> path;
  Agreement result;
  for (int trial = 0; trial < poses; ++trial) {
    const Pose pose = randomPose(rng, centre, 450.0, 8.0);
    renderPathLength(m, posed(mesh, pose, world), {}, path);
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u) {
        const double expected = csgPath(pieces, contains, partRay(m, pose, u, v));
        const double difference = std::abs(path(u, v) - expected);
        if (difference > result.worst) {
          result.worst = difference;
          if (difference > 1e-9)
            ADD_FAILURE() << "pose " << trial << " pixel " << u << ", " << v << ": rendered "
                          << path(u, v) << " mm, expected " << expected << " mm";
        }
        result.hits += expected > 0;
      }
  }
  return result;
}

double nominal(const PartModel& model, const char* name) {
  return model.nominalValues()[static_cast<size_t>(model.dimensionIndex(name))];
}

// ---------------------------------------------------------------------------
// 1. A plate with a round hole, seen along the hole's axis and tilted.

constexpr const char* kPlateWithHole = R"({"description": "plate with a round hole",
  "dimensions": [
    {"name": "T", "nominal": 5, "min": 1, "max": 10, "unit": "mm"},
    {"name": "d", "nominal": 10, "min": 2, "max": 20, "unit": "mm"}],
  "shape": {"type": "difference", "solids": [
    {"type": "box", "min": [-15, -15, 0], "max": [15, 15, "T"]},
    {"type": "cylinder", "axis": "z", "diameter": "d", "from": -1, "to": "T + 1"}]}})";

// Distance in the (x, y) plane from the origin to the segment a-b.
double distanceToSegment(const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double t = ab.squaredNorm() == 0 ? 0.0 : std::clamp(-a.dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab).norm();
}

// Checks every pixel of a render of the plate (thickness T, half-width 15)
// with a hole of radius r faceted by N segments (inscribed), hole axis = part
// z through the origin. In the part frame the ray meets the faces z = 0 and
// z = T at A and B; between them its (x, y) runs along the segment AB. So:
// - AB at least r from the axis (the faceted hole lies inside the circle of
//   radius r) and within the plate: the ray crosses the whole slab, path =
//   T |dir| / |dir_z| (= T |P - S| / D when the plate faces the detector);
// - AB within r cos(pi / N) of the axis (inside the inscribed circle of the
//   polygon, the circle is convex): the ray stays in the hole, path = 0
//   exactly;
// - A and B beyond the same side of the plate: path = 0 exactly;
// - otherwise (the hole's wall or the plate's rim): 0 <= path <= the slab.
// The first two cases use the true circle: every ray that keeps more than the
// chord error r (1 - cos(pi / N)) away from the true hole's wall gets the
// true cylinder's path exactly (the faceted wall lies between the circles of
// radius r cos(pi / N) and r), which is the check against the quadric with a
// tolerance derived from the chord error.
struct PlateCounts {
  int slab = 0, hole = 0, outside = 0, between = 0;
};
PlateCounts checkPlate(const Machine& m, const Pose& pose, const ImageT<double>& path, double T,
                       double r, int segments, bool facing) {
  constexpr double kMargin = 1e-6;  // mm, far above rounding
  const double r_in = r * std::cos(kPi / segments);
  const double d = m.source_detector_distance_mm;
  PlateCounts counts;
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.columns; ++u) {
      const PartRay ray = partRay(m, pose, u, v);
      const Vec3 a3 = ray.o + (0.0 - ray.o.z()) / ray.dir.z() * ray.dir;
      const Vec3 b3 = ray.o + (T - ray.o.z()) / ray.dir.z() * ray.dir;
      const Vec2 a = a3.head<2>(), b = b3.head<2>();
      const double slab = T * ray.dir.norm() / std::abs(ray.dir.z());
      const double got = path(u, v);
      const bool in_plate = std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff()) < 15 - kMargin;
      bool beyond = false;
      for (int k = 0; k < 2; ++k)
        beyond |= (a[k] > 15 + kMargin && b[k] > 15 + kMargin) ||
                  (a[k] < -15 - kMargin && b[k] < -15 - kMargin);
      if (in_plate && distanceToSegment(a, b) > r + kMargin) {
        if (facing) {
          // Facing the detector: the closed form in pixel terms.
          const Vec3 p = m.detectorPoint(u + 0.5, v + 0.5);
          EXPECT_NEAR(slab, T * (p - m.sourceWorld()).norm() / d, 1e-12);
        }
        if (std::abs(got - slab) > 1e-9) {
          ADD_FAILURE() << "pixel " << u << ", " << v << ": " << got << " mm, the slab is " << slab;
          return counts;
        }
        ++counts.slab;
      } else if (std::max(a.norm(), b.norm()) < r_in - kMargin || beyond) {
        if (got != 0.0) {
          ADD_FAILURE() << "pixel " << u << ", " << v << ": " << got << " mm, expected 0";
          return counts;
        }
        ++(beyond ? counts.outside : counts.hole);
      } else {
        if (!(got >= 0.0 && got <= slab + 1e-9)) {
          ADD_FAILURE() << "pixel " << u << ", " << v << ": " << got << " mm, slab " << slab;
          return counts;
        }
        ++counts.between;
      }
    }
  return counts;
}

TEST(CsgRender, PlateWithRoundHoleHasClosedFormPaths) {
  const PartModel plate = partFromText(kPlateWithHole);
  ASSERT_NE(plate.csg(), nullptr);
  // Box: 8 vertices; cylinder: two poles and two rings.
  const int segments = static_cast<int>((plate.vertexCount() - 8 - 2) / 2);
  ASSERT_EQ(segments, cylinderSegments(*plate.csg(), 1));
  ASSERT_LE(5.0 * (1 - std::cos(kPi / segments)), 0.001);  // chord error

  const Machine m = squareMachine(256, 0.4);
  std::vector<Vec3> world;
  ImageT<double> path;
  for (const std::vector<double>& values :
       {plate.nominalValues(), std::vector<double>{3.25, 13.5}}) {
    const double T = values[0], r = values[1] / 2;
    const TriangleMesh mesh = plate.mesh(values);
    // Facing the detector, the hole's axis off the principal point.
    const Pose facing = Pose::fromEulerDeg(Vec3::Zero(), Vec3(3.0, -2.0, 400.0));
    renderPathLength(m, posed(mesh, facing, world), {}, path);
    PlateCounts counts = checkPlate(m, facing, path, T, r, segments, true);
    EXPECT_GT(counts.slab, 5000);
    EXPECT_GT(counts.hole, 500);
    EXPECT_GT(counts.outside, 20000);
    EXPECT_LT(counts.between, counts.slab / 2);
    std::printf("facing, T %g, d %g: %d slab, %d hole, %d outside, %d between\n", T, 2 * r,
                counts.slab, counts.hole, counts.outside, counts.between);
    // Tilted about both in-plane axes (and turned), about the plate's centre.
    const Pose tilted = poseAbout(Vec3(20, -12, 7), Vec3(0, 0, T / 2), Vec3(3.0, -2.0, 400.0));
    renderPathLength(m, posed(mesh, tilted, world), {}, path);
    counts = checkPlate(m, tilted, path, T, r, segments, false);
    EXPECT_GT(counts.slab, 5000);
    EXPECT_GT(counts.hole, 200);
    EXPECT_GT(counts.outside, 20000);
    EXPECT_LT(counts.between, counts.slab);
    std::printf("tilted, T %g, d %g: %d slab, %d hole, %d outside, %d between\n", T, 2 * r,
                counts.slab, counts.hole, counts.outside, counts.between);
  }
}

// ---------------------------------------------------------------------------
// 2. Cylinders with cross holes against the independent convex CSG.
//
// Why 1e-9 mm: the renderer and the test intersect the same faceted solids
// (the prisms over the inscribed N-gons, whose vertices are on the true
// circles), so they differ only by rounding: ~1e-16 relative in the depths
// along a ray of ~1000 mm, 1e-13 mm, times a few crossings. The true
// cylinders are another matter: the facets lie within the chord error
// r (1 - cos(pi / N)) <= 0.001 mm of them, but a ray's chord through a
// cylinder changes by up to ~2 sqrt(2 r e) (0.2 mm for r = 10 mm) when it
// grazes the surface, so a per-pixel comparison with the quadrics would need a
// tolerance that depends on the ray's angle and distance to the axis; the
// faceted solid is what the fit models, so that is what is checked exactly.

TEST(CsgRender, CylinderWithCrossHoleMatchesIndependentCsg) {
  // A revolved cylinder along y, minus a cylinder along x turned 20 degrees
  // about z (a skew cross hole), with explicit segment counts.
  const PartModel part = partFromText(R"({"description": "cylinder with a cross hole",
    "dimensions": [
      {"name": "D", "nominal": 20, "min": 10, "max": 30, "unit": "mm"},
      {"name": "dh", "nominal": 8, "min": 2, "max": 12, "unit": "mm"}],
    "shape": {"type": "difference", "solids": [
      {"type": "revolution", "axis": "y", "segments": 40,
       "profile": [[0, 0], ["D / 2", 0], ["D / 2", 40], [0, 40]]},
      {"type": "cylinder", "axis": "x", "diameter": "dh", "from": -15, "to": 15, "segments": 24,
       "rotate": [0, 0, 20], "translate": [0, 20, 0]}]}})");
  const auto difference = [](uint64_t m) { return m == 1; };
  const Pose hole_pose = Pose::fromEulerDeg(Vec3(0, 0, 20), Vec3(0, 20, 0));
  for (const std::vector<double>& values : {part.nominalValues(), std::vector<double>{17.0, 6.5}}) {
    const std::vector<Convex> pieces = {prism(1, values[0] / 2, 0, 40, 40),
                                        placed(prism(0, values[1] / 2, -15, 15, 24), hole_pose)};
    const Agreement a = compareWithConvexCsg(part, values, pieces, difference, Vec3(0, 20, 0), 10,
                                             values[0] == 20 ? 11 : 12);
    EXPECT_LT(a.worst, 1e-9);
    EXPECT_GT(a.hits, 10 * 3000L);
  }
}

TEST(CsgRender, SteppedShaftMatchesIndependentCsg) {
  // Part 6: the stepped profile is the union of two coaxial prisms of the
  // same segment count (the revolution's, set by the larger radius), the
  // cross hole a prism along x.
  const PartModel shaft = PartModel::load(kParts + "stepped_shaft.json");
  const Csg& csg = *shaft.csg();
  ASSERT_EQ(csg.pieces(), 2u);
  ASSERT_EQ(csg.pieceTriangleEnds()[0] % 8, 0u);  // 2 fans and 3 bands
  const int n_shaft = static_cast<int>(csg.pieceTriangleEnds()[0] / 8);
  const int n_hole = cylinderSegments(csg, 1);
  const double d1 = nominal(shaft, "large_diameter"), d2 = nominal(shaft, "small_diameter");
  const double l1 = nominal(shaft, "large_length"), l2 = nominal(shaft, "small_length");
  const double dh = nominal(shaft, "cross_hole_diameter"), yh = nominal(shaft, "cross_hole_position");
  const std::vector<Convex> pieces = {
      prism(1, d1 / 2, 0, l1, n_shaft), prism(1, d2 / 2, l1, l1 + l2, n_shaft),
      placed(prism(0, dh / 2, -d1, d1, n_hole), Pose::fromEulerDeg(Vec3::Zero(), Vec3(0, yh, 0)))};
  const auto shape = [](uint64_t m) { return (m & 3) != 0 && (m & 4) == 0; };
  const Agreement a = compareWithConvexCsg(shaft, shaft.nominalValues(), pieces, shape,
                                           Vec3(0, 27.5, 0), 20, 13);
  EXPECT_LT(a.worst, 1e-9);
  EXPECT_GT(a.hits, 20 * 3000L);
}

TEST(CsgRender, BracketMatchesIndependentCsg) {
  // Part 5: (base | upright) - three hole prisms. The plates share faces
  // (x = 0, y = 0, y = W, z = 0): crossings of equal depth from two pieces.
  const PartModel bracket = PartModel::load(kParts + "bracket.json");
  const Csg& csg = *bracket.csg();
  ASSERT_EQ(csg.pieces(), 5u);
  const double L = nominal(bracket, "base_length"), H = nominal(bracket, "height");
  const double W = nominal(bracket, "width"), T = nominal(bracket, "thickness");
  const double d = nominal(bracket, "hole_diameter"), c = nominal(bracket, "hole_position");
  const double s = nominal(bracket, "hole_spacing");
  const double du = nominal(bracket, "upright_hole_diameter");
  const double hu = nominal(bracket, "upright_hole_height");
  auto at = [](double x, double y, double z) { return Pose::fromEulerDeg(Vec3::Zero(), Vec3(x, y, z)); };
  const std::vector<Convex> pieces = {
      box({0, 0, 0}, {L, W, T}), box({0, 0, 0}, {T, W, H}),
      placed(prism(2, d / 2, -1, T + 1, cylinderSegments(csg, 2)), at(c, W / 2, 0)),
      placed(prism(2, d / 2, -1, T + 1, cylinderSegments(csg, 3)), at(c + s, W / 2, 0)),
      placed(prism(0, du / 2, -1, T + 1, cylinderSegments(csg, 4)), at(0, W / 2, hu))};
  const auto shape = [](uint64_t m) { return (m & 3) != 0 && (m >> 2) == 0; };
  const Agreement a = compareWithConvexCsg(bracket, bracket.nominalValues(), pieces, shape,
                                           Vec3(L / 2, W / 2, H / 2), 20, 14);
  EXPECT_LT(a.worst, 1e-9);
  EXPECT_GT(a.hits, 20 * 3000L);
}

// More than 16 pieces: Csg evaluates the program for each mask instead of
// looking it up in its table. A plate with 20 square holes (an extrusion
// with "holes"), in union with a bar through it: 22 pieces.
TEST(CsgRender, TwentyTwoPiecesMatchIndependentCsg) {
  std::string holes;
  std::vector<Convex> pieces = {box({0, 0, 0}, {50, 40, 4})};
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 4; ++j) {
      const double x = 3 + 10 * i, y = 3 + 9 * j;
      holes += fmt::format("{}[[{}, {}], [{}, {}], [{}, {}], [{}, {}]]", holes.empty() ? "" : ", ",
                           x, y, x + 4, y, x + 4, y + 4, x, y + 4);
      pieces.push_back(box({x, y, -0.2}, {x + 4, y + 4, 4.2}));  // 1/20 of 4 beyond each cap
    }
  pieces.push_back(box({20, 10, -3}, {27, 30, 8}));
  const PartModel part = partFromText(R"({"description": "plate with 20 holes and a bar",
    "dimensions": [],
    "shape": {"type": "union", "solids": [
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [[0, 0], [50, 0], [50, 40], [0, 40]], "from": 0, "to": 4,
       "holes": [)" + holes + R"(]},
      {"type": "box", "min": [20, 10, -3], "max": [27, 30, 8]}]}})");
  ASSERT_NE(part.csg(), nullptr);
  ASSERT_EQ(part.csg()->pieces(), 22u);
  const auto shape = [](uint64_t m) {
    return ((m & 1) != 0 && (m & 0x1ffffe) == 0) || (m & (uint64_t{1} << 21)) != 0;
  };
  const Agreement a =
      compareWithConvexCsg(part, {}, pieces, shape, Vec3(25, 20, 2), 10, 15);
  EXPECT_LT(a.worst, 1e-9);
  EXPECT_GT(a.hits, 10 * 3000L);
}

// ---------------------------------------------------------------------------
// 3. Watertightness of the reference parts.

// Bounding box diagonal of the pieces that are the part on their own (the
// part lies in their union for these trees).
double solidDiagonal(const TriangleMesh& mesh) {
  Vec3 lo = Vec3::Constant(HUGE_VAL), hi = -lo;
  uint32_t begin = 0;
  const auto ends = mesh.csg->pieceTriangleEnds();
  for (size_t p = 0; p < ends.size(); ++p) {
    if (mesh.csg->alone(p))
      for (uint32_t t = begin; t < ends[p]; ++t)
        for (uint32_t i : mesh.triangles[t])
          lo = lo.cwiseMin(mesh.vertices[i]), hi = hi.cwiseMax(mesh.vertices[i]);
    begin = ends[p];
  }
  return (hi - lo).norm();
}

// `poses` renders; every tenth pose is axis-aligned with the part's `centre`
// on a grid of sample centres (ties between the pieces' shared edges and
// faces), the others random. Every pixel: entries == exits on every sample,
// and 0 <= path <= the solid's diagonal.
void checkWatertight(const PartModel& model, const Vec3& centre, int poses, uint64_t seed) {
  const Machine m = squareMachine(256, 0.5);
  const TriangleMesh mesh = model.mesh(model.nominalValues());
  const double limit = solidDiagonal(mesh) + 1e-9;
  std::mt19937_64 rng(seed);
  std::vector<Vec3> world;
  long covered = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int trial = 0; trial < poses; ++trial) {
    Pose pose;
    if (trial % 10 == 0) {
      std::uniform_int_distribution<int> quarter(0, 3), shift(-40, 40);
      pose = Pose::fromEulerDeg(Vec3(90.0 * quarter(rng), 90.0 * quarter(rng), 90.0 * quarter(rng)),
                                Vec3::Zero());
      pose.translation_mm =
          -pose.rotation * centre + Vec3(0.25 * shift(rng), 0.25 * shift(rng), 500.0);
    } else {
      pose = randomPose(rng, centre, 500.0, 15.0);
    }
    const RenderDiagnostics d = renderDiagnostics(m, posed(mesh, pose, world), {});
    // Plain loops; gtest's assertions only on a failure.
    const auto unbalanced = d.unbalanced.pixels(), entries = d.entries.pixels(),
               exits = d.exits.pixels();
    const auto lo = d.min_path_mm.pixels(), hi = d.max_path_mm.pixels();
    for (size_t i = 0; i < unbalanced.size(); ++i) {
      if (unbalanced[i] != 0 || entries[i] != exits[i] || !(lo[i] >= -1e-9) || !(hi[i] <= limit)) {
        FAIL() << "pose " << trial << " pixel " << i % 256 << ", " << i / 256 << ": unbalanced "
               << unbalanced[i] << ", entries " << entries[i] << ", exits " << exits[i]
               << ", path " << lo[i] << " to " << hi[i] << " mm (limit " << limit << ")";
      }
      covered += entries[i] > 0;
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%d poses, %.1f ms per pose, %.0f%% of the pixels covered on average\n", poses,
              1e3 * seconds / poses, 100.0 * covered / (256.0 * 256.0 * poses));
  EXPECT_GT(covered, 256L * 256 * poses / 10);
}

TEST(CsgRender, WatertightBracket10000Poses) {
  const PartModel bracket = PartModel::load(kParts + "bracket.json");
  // Box corners 0.125 mm off the grid of 0.25 mm: at magnification 2 and
  // 0.5 mm pixels, corners in the plane z = 500 project on pixel centres.
  checkWatertight(bracket, Vec3(20.125, 12.125, 15.125), 10000, 21);
}

TEST(CsgRender, WatertightSteppedShaft10000Poses) {
  const PartModel shaft = PartModel::load(kParts + "stepped_shaft.json");
  checkWatertight(shaft, Vec3(0.125, 27.625, 0.125), 10000, 22);
}

// ---------------------------------------------------------------------------
// 4. Smoothness: area-sampled intensity moves strictly with a hole's size.

void checkIntensityIncreases(const PartModel& bracket, const char* dimension) {
  const auto material = ExponentialSum({{0.6, 0.03}, {0.3, 0.08}, {0.1, 0.3}});
  const auto table = TransmissionTable::forMaterial(material, 100.0);
  const Machine m = squareMachine(256, 0.4);
  // Oblique: every hole's wall is seen at an angle, so the paths near it
  // change continuously with the diameter.
  const Pose pose = poseAbout(Vec3(25, -35, 15), Vec3(20, 12.5, 15), Vec3(1.5, -2.0, 450.0));
  RenderOptions options;
  options.samples_per_axis = 4;
  const double centre = nominal(bracket, dimension);
  std::vector<Vec3> world;
  Image image;
  double previous = -HUGE_VAL;
  for (int step = -50; step <= 50; ++step) {
    const double value = centre + 0.001 * step;
    const TriangleMesh mesh = bracket.mesh(bracket.values({{dimension, value}}));
    renderIntensity(m, posed(mesh, pose, world), table, options, image);
    double sum = 0.0;
    for (float p : image.pixels()) sum += static_cast<double>(p);
    // A larger hole, less material, more light: strictly increasing.
    ASSERT_GT(sum, previous) << dimension << " = " << value;
    previous = sum;
  }
}

TEST(CsgRender, AreaSampledIntensityIncreasesWithHoleDiameter) {
  const PartModel bracket = PartModel::load(kParts + "bracket.json");
  checkIntensityIncreases(bracket, "hole_diameter");
  checkIntensityIncreases(bracket, "upright_hole_diameter");
}

// ---------------------------------------------------------------------------
// 5. Determinism.

TEST(CsgRender, BitIdenticalAtAnyThreadCountAndInRegions) {
  const PartModel bracket = PartModel::load(kParts + "bracket.json");
  const TriangleMesh mesh = bracket.mesh(bracket.nominalValues());
  const Machine m = squareMachine(300, 0.3);
  const Pose pose = poseAbout(Vec3(30, 50, -20), Vec3(20, 12.5, 15), Vec3(-2, 3, 500));
  std::vector<Vec3> world;
  const WorldMesh w = posed(mesh, pose, world);
  RenderOptions options;
  options.samples_per_axis = 3;
  auto render = [&](int threads) {
    ImageT<double> out;
    // The band layout follows the arena's concurrency, so the thread count
    // changes how the work is cut.
    tbb::task_arena arena(threads);
    arena.execute([&] { renderPathLength(m, w, options, out); });
    return out;
  };
  const ImageT<double> one = render(1), two = render(2);
  ASSERT_EQ(one.pixels().size(), two.pixels().size());
  int covered = 0;
  for (size_t i = 0; i < one.pixels().size(); ++i) {
    // Bit for bit.
    ASSERT_EQ(std::memcmp(&one.pixels()[i], &two.pixels()[i], sizeof(double)), 0) << i;
    covered += one.pixels()[i] > 0;
  }
  EXPECT_GT(covered, 10000);
  // A region gives the same pixels as the full render.
  options.region = {97, 61, 120, 150};
  ImageT<double> part;
  renderPathLength(m, w, options, part);
  for (int y = 0; y < part.height(); ++y)
    for (int x = 0; x < part.width(); ++x) ASSERT_EQ(part(x, y), one(x + 97, y + 61));
}

// ---------------------------------------------------------------------------
// 6. Union, intersection and difference of two boxes, along the axis.

// Two boxes, A = [-10, 10]^2 x [0, 10] and B, under `op`; with one solid
// only, a plain (non-CSG) part.
std::string boxJson(const Vec3& lo, const Vec3& hi) {
  return fmt::format(R"({{"type": "box", "min": [{}, {}, {}], "max": [{}, {}, {}]}})", lo.x(),
                     lo.y(), lo.z(), hi.x(), hi.y(), hi.z());
}
PartModel boxes(const std::string& op, const std::vector<std::pair<Vec3, Vec3>>& solids) {
  std::string list;
  for (const auto& [lo, hi] : solids) list += (list.empty() ? "" : ", ") + boxJson(lo, hi);
  return partFromText(R"({"description": "boxes", "dimensions": [],
    "shape": {"type": ")" + op + R"(", "solids": [)" + list + "]}}");
}

// Facing the detector (pose: translation only), with B = [bx0, bx1] x
// [by0, by1] x [bz0, bz1]: a ray laterally inside a box over the box's whole
// height crosses its top and bottom faces, path (z1 - z0) |P - S| / D; the
// overlap of two such boxes is their common height. Union = a + b - overlap,
// intersection = overlap, difference = a - overlap. On every pixel, edges
// included, the renders also obey inclusion-exclusion against renders of A
// and B alone: union = A + B - intersection, difference = A - intersection.
void checkTwoBoxes(const Vec3& b_lo, const Vec3& b_hi) {
  const Vec3 a_lo(-10, -10, 0), a_hi(10, 10, 10);
  const PartModel u = boxes("union", {{a_lo, a_hi}, {b_lo, b_hi}});
  const PartModel i = boxes("intersection", {{a_lo, a_hi}, {b_lo, b_hi}});
  const PartModel d = boxes("difference", {{a_lo, a_hi}, {b_lo, b_hi}});
  const PartModel a_alone = boxes("union", {{a_lo, a_hi}});
  const PartModel b_alone = boxes("union", {{b_lo, b_hi}});
  ASSERT_NE(u.csg(), nullptr);
  ASSERT_EQ(a_alone.csg(), nullptr);
  const Machine m = squareMachine(256, 0.4);
  const Vec3 t(2.0, -3.0, 400.0);
  const Pose pose = Pose::fromEulerDeg(Vec3::Zero(), t);
  std::vector<Vec3> world;
  ImageT<double> pu, pi, pd, pa, pb;
  renderPathLength(m, posed(u.mesh({}), pose, world), {}, pu);
  renderPathLength(m, posed(i.mesh({}), pose, world), {}, pi);
  renderPathLength(m, posed(d.mesh({}), pose, world), {}, pd);
  renderPathLength(m, posed(a_alone.mesh({}), pose, world), {}, pa);
  renderPathLength(m, posed(b_alone.mesh({}), pose, world), {}, pb);
  const double dist = m.source_detector_distance_mm;
  const double overlap_height =
      std::max(0.0, std::min(a_hi.z(), b_hi.z()) - std::max(a_lo.z(), b_lo.z()));
  int counts[2][2] = {};
  int edges = 0;
  constexpr double kMargin = 1e-6;
  for (int v = 0; v < m.rows; ++v)
    for (int x = 0; x < m.columns; ++x) {
      ASSERT_GE(pi(x, v), 0.0);
      ASSERT_NEAR(pu(x, v), pa(x, v) + pb(x, v) - pi(x, v), 1e-9) << "pixel " << x << ", " << v;
      ASSERT_NEAR(pd(x, v), pa(x, v) - pi(x, v), 1e-9) << "pixel " << x << ", " << v;
      const Vec3 p = m.detectorPoint(x + 0.5, v + 0.5);
      const double k = (p - m.sourceWorld()).norm() / dist;
      // The ray's (x, y) in the part frame at part height z.
      auto lateral = [&](double z) {
        return Vec2(p.x() * (dist - z - t.z()) / dist - t.x(),
                    p.y() * (dist - z - t.z()) / dist - t.y());
      };
      // 1: inside over the whole height, 0: outside over it, -1: neither.
      auto status = [&](const Vec3& lo, const Vec3& hi) {
        const Vec2 e[2] = {lateral(lo.z()), lateral(hi.z())};
        bool inside = true, outside = false;
        for (int axis = 0; axis < 2; ++axis) {
          inside &= e[0][axis] > lo[axis] + kMargin && e[0][axis] < hi[axis] - kMargin &&
                    e[1][axis] > lo[axis] + kMargin && e[1][axis] < hi[axis] - kMargin;
          outside |= (e[0][axis] < lo[axis] - kMargin && e[1][axis] < lo[axis] - kMargin) ||
                     (e[0][axis] > hi[axis] + kMargin && e[1][axis] > hi[axis] + kMargin);
        }
        return inside ? 1 : outside ? 0 : -1;
      };
      const int in_a = status(a_lo, a_hi), in_b = status(b_lo, b_hi);
      if (in_a < 0 || in_b < 0) {
        ++edges;
        continue;
      }
      const double a = (a_hi.z() - a_lo.z()) * k, b = (b_hi.z() - b_lo.z()) * k;
      const double overlap = in_a && in_b ? overlap_height * k : 0.0;
      const double ea = in_a ? a : 0.0, eb = in_b ? b : 0.0;
      ASSERT_NEAR(pu(x, v), ea + eb - overlap, 1e-9) << "union, pixel " << x << ", " << v;
      ASSERT_NEAR(pi(x, v), overlap, 1e-9) << "intersection, pixel " << x << ", " << v;
      ASSERT_NEAR(pd(x, v), ea - overlap, 1e-9) << "difference, pixel " << x << ", " << v;
      ++counts[in_a][in_b];
    }
  EXPECT_GT(counts[1][1], 1000);
  EXPECT_GT(counts[1][0], 1000);
  EXPECT_GT(counts[0][1], 1000);
  EXPECT_GT(counts[0][0], 1000);
  EXPECT_GT(edges, 100);
}

TEST(CsgRender, UnionIntersectionDifferenceOfTwoBoxes) {
  // Overlapping in all three axes: overlap height 6.
  checkTwoBoxes(Vec3(0, -4, 4), Vec3(20, 16, 14));
}

TEST(CsgRender, BoxesSharingAFace) {
  // B stacked on A's top face over part of it: the shared face gives exit
  // and entry at the same depth from two pieces; union = a + b, intersection
  // = 0, difference = a, whatever order the tie takes.
  checkTwoBoxes(Vec3(0, -4, 10), Vec3(20, 16, 15));
}

// ---------------------------------------------------------------------------
// An extrusion with "holes" renders as the explicit difference of its prisms,
// whatever the hole prisms' length beyond the plate.

TEST(CsgRender, ExtrusionHolesRenderAsTheExplicitDifference) {
  const std::string dimensions = R"("dimensions": [
      {"name": "w", "nominal": 30, "min": 20, "max": 40, "unit": "mm"},
      {"name": "h", "nominal": 6, "min": 2, "max": 10, "unit": "mm"}])";
  const PartModel with_holes = partFromText(R"({"description": "plate with holes", )" + dimensions + R"(,
    "shape": {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
      "profile": [[0, 0], ["w", 0], ["w", 20], [0, 20]], "from": 0, "to": "h",
      "holes": [[[3, 3], [9, 3], [9, 9], [3, 9]], [["w - 8", 10], ["w - 2", 12], ["w - 4", 17]]]}})");
  const PartModel explicit_difference = partFromText(R"({"description": "the same", )" + dimensions + R"(,
    "shape": {"type": "difference", "solids": [
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [[0, 0], ["w", 0], ["w", 20], [0, 20]], "from": 0, "to": "h"},
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [[3, 3], [9, 3], [9, 9], [3, 9]], "from": -2, "to": "h + 1"},
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [["w - 8", 10], ["w - 2", 12], ["w - 4", 17]], "from": -1, "to": "h + 3"}
    ]}})");
  const Machine m = squareMachine(160, 0.5);
  std::mt19937_64 rng(31);
  std::vector<Vec3> wa, wb;
  ImageT<double> a, b;
  int hole_pixels = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const std::vector<double> values = {std::uniform_real_distribution<double>(22, 38)(rng),
                                        std::uniform_real_distribution<double>(2.5, 9)(rng)};
    const Pose pose = randomPose(rng, Vec3(values[0] / 2, 10, values[1] / 2), 450, 8);
    renderPathLength(m, posed(with_holes.mesh(values), pose, wa), {}, a);
    renderPathLength(m, posed(explicit_difference.mesh(values), pose, wb), {}, b);
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u)
        ASSERT_NEAR(a(u, v), b(u, v), 1e-9) << "pose " << trial << " pixel " << u << ", " << v;
    // And the independent CSG of the three convex prisms.
    const double w = values[0], h = values[1];
    const std::vector<Convex> pieces = {
        box({0, 0, 0}, {w, 20, h}), box({3, 3, -1}, {9, 9, h + 1}),
        prismOver({{w - 8, 10}, {w - 2, 12}, {w - 4, 17}}, -1, h + 1)};
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u) {
        const PartRay ray = partRay(m, pose, u, v);
        const double expected = csgPath(pieces, [](uint64_t mask) { return mask == 1; }, ray);
        ASSERT_NEAR(a(u, v), expected, 1e-9) << "pose " << trial << " pixel " << u << ", " << v;
        hole_pixels += expected < csgPath({pieces[0]}, [](uint64_t mask) { return mask == 1; }, ray) - 1e-3;
      }
  }
  EXPECT_GT(hole_pixels, 100);
}

}  // namespace
}  // namespace xgauge
