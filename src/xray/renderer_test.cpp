// Closed-form and invariant checks of the renderer (issue: foundation).
#include "xgauge/xray/renderer.h"

#include "test_machines.h"

#include "xgauge/core/parallel.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_sum.h"

#include <gtest/gtest.h>

#include <numbers>
#include <random>

namespace xgauge {
namespace {

using testing::kParts;
using testing::posed;
using testing::randomPose;
using testing::squareMachine;

// Ray from the source to the centre of pixel (u, v) of a region.
struct Ray {
  Vec3 origin, target;  // source, detector point
};
Ray pixelRay(const Machine& m, int u, int v) {
  return {m.sourceWorld(), m.detectorPoint(u + 0.5, v + 0.5)};
}

TriangleMesh cuboid(double sx, double sy, double sz) {
  TriangleMesh mesh;
  for (int i = 0; i < 8; ++i)
    mesh.vertices.emplace_back((i & 1 ? 0.5 : -0.5) * sx, (i & 2 ? 0.5 : -0.5) * sy,
                               (i & 4 ? 0.5 : -0.5) * sz);
  // Outward, counter-clockwise seen from outside.
  mesh.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                    {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return mesh;
}

TEST(Renderer, OnATiltedDetectorTheCuboidsPathsAreThoseOfItsPixelsRays) {
  // The same slab seen by a panel tilted about both its axes and turned in
  // its plane: each pixel's point sample lies on the ray to its own tilted
  // detector point, through a slab of thickness sz.
  for (const Vec3& angles : {Vec3(0.4, -0.3, 0.2), Vec3(-6.0, 8.0, 3.0)}) {
    SCOPED_TRACE(angles.transpose());
    Machine m = squareMachine(256, 0.4);
    m.setDetectorPose(angles.x(), angles.y(), angles.z());
    const double sx = 20, sy = 30, sz = 10;
    const Pose pose = Pose::fromEulerDeg(Vec3::Zero(), Vec3(2.0, -3.0, 400.0));
    std::vector<Vec3> world;
    ImageT<double> path;
    renderPathLength(m, posed(cuboid(sx, sy, sz), pose, world), {}, path);
    int checked = 0;
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u) {
        const Ray ray = pixelRay(m, u, v);
        const Vec3 along = ray.target - ray.origin;
        bool both = true;
        for (double z : {405.0, 395.0}) {
          const Vec3 hit = ray.origin + (z - ray.origin.z()) / along.z() * along;
          both &= std::abs(hit.x() - 2.0) < 0.5 * sx - 1e-6 &&
                  std::abs(hit.y() + 3.0) < 0.5 * sy - 1e-6;
        }
        if (!both) continue;
        ASSERT_NEAR(path(u, v), sz * along.norm() / std::abs(along.z()), 1e-9)
            << "pixel " << u << ", " << v;
        ++checked;
      }
    EXPECT_GT(checked, 4000);
  }
}

TEST(Renderer, CuboidFacingTheSourceHasClosedFormPathLength) {
  const Machine m = squareMachine(256, 0.4);
  const double sx = 20, sy = 30, sz = 10;
  const TriangleMesh box = cuboid(sx, sy, sz);
  const Pose pose = Pose::fromEulerDeg(Vec3::Zero(), Vec3(2.0, -3.0, 400.0));
  std::vector<Vec3> world;
  ImageT<double> path;
  renderPathLength(m, posed(box, pose, world), {}, path);

  int checked = 0;
  const double d = m.source_detector_distance_mm;
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.columns; ++u) {
      const Ray ray = pixelRay(m, u, v);
      // Does the ray cross both the front (z = 405) and the back (z = 395) face?
      bool both = true;
      for (double z : {405.0, 395.0}) {
        const Vec3 hit = ray.origin + (d - z) / d * (ray.target - ray.origin);
        both &= std::abs(hit.x() - 2.0) < 0.5 * sx - 1e-6 && std::abs(hit.y() + 3.0) < 0.5 * sy - 1e-6;
      }
      if (!both) continue;
      // Through a slab of thickness sz the path is sz / cos(angle to the z axis).
      const double expected = sz * (ray.target - ray.origin).norm() / d;
      ASSERT_NEAR(path(u, v), expected, 1e-9) << "pixel " << u << ", " << v;
      ++checked;
    }
  EXPECT_GT(checked, 4000);
}

// Monotone-chain convex hull, counter-clockwise.
std::vector<Vec2> convexHull(std::vector<Vec2> p) {
  std::sort(p.begin(), p.end(), [](const Vec2& a, const Vec2& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Vec2& o, const Vec2& a, const Vec2& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Vec2> hull(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], p[i - 1]) <= 0) --k;
    hull[k++] = p[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

TEST(Renderer, CuboidSilhouetteIsTheProjectionOfItsCorners) {
  const Machine m = squareMachine(256, 0.4);
  const TriangleMesh box = cuboid(20, 30, 10);
  const Pose pose = Pose::fromEulerDeg(Vec3(25, -40, 15), Vec3(-3.0, 4.0, 450.0));
  std::vector<Vec3> world;
  ImageT<double> path;
  renderPathLength(m, posed(box, pose, world), {}, path);

  std::vector<Vec2> corners;
  for (const Vec3& w : world) corners.push_back(m.project(w));
  const std::vector<Vec2> hull = convexHull(corners);
  int inside = 0, outside = 0;
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.columns; ++u) {
      const Vec2 c(u + 0.5, v + 0.5);
      // Signed distance to the hull (positive inside), in pixels.
      double distance = HUGE_VAL;
      for (size_t i = 0; i < hull.size(); ++i) {
        const Vec2& a = hull[i];
        const Vec2& b = hull[(i + 1) % hull.size()];
        const Vec2 e = (b - a).normalized();
        distance = std::min(distance, e.x() * (c.y() - a.y()) - e.y() * (c.x() - a.x()));
      }
      if (distance > 1e-6) {
        ASSERT_GT(path(u, v), 0.0) << "pixel " << u << ", " << v;
        ++inside;
      } else if (distance < -1e-6) {
        ASSERT_EQ(path(u, v), 0.0) << "pixel " << u << ", " << v;
        ++outside;
      }
    }
  EXPECT_GT(inside, 5000);
  EXPECT_GT(outside, 5000);
}

// The prism jaw as three convex prisms (docs/conventions.md profile), for an independent
// path length: a bottom slab and the two blocks left and right of the slot.
struct ConvexPrism {
  std::vector<Vec2> profile;  // (x, z), counter-clockwise
};

std::vector<ConvexPrism> jawPieces(double W, double c, double T, double g, double al, double ar,
                                   double sw, double sd) {
  const double zs = T - g - sd;
  const double z4 = T - g * (1 - sw / (2 * ar)), z7 = T - g * (1 - sw / (2 * al));
  return {{{{0, 0}, {W, 0}, {W, zs}, {0, zs}}},
          {{{0, zs}, {c - sw / 2, zs}, {c - sw / 2, z7}, {c - al, T}, {0, T}}},
          {{{c + sw / 2, zs}, {W, zs}, {W, T}, {c + ar, T}, {c + sw / 2, z4}}}};
}

// Length of the segment origin -> target inside a convex prism extruded along
// y over [0, length] (Cyrus-Beck clipping), in the part frame.
double chord(const ConvexPrism& prism, double length, const Vec3& o, const Vec3& target) {
  const Vec3 dir = target - o;
  double lo = 0.0, hi = 1.0;
  auto clip = [&](const Vec3& normal, double offset) {  // normal . X <= offset
    const double nd = normal.dot(dir), no = normal.dot(o);
    if (nd == 0.0) {
      if (no > offset) hi = -1.0;
      return;
    }
    const double s = (offset - no) / nd;
    if (nd > 0) hi = std::min(hi, s);
    else lo = std::max(lo, s);
  };
  clip(Vec3(0, 1, 0), length);
  clip(Vec3(0, -1, 0), 0.0);
  const auto& p = prism.profile;
  for (size_t i = 0; i < p.size(); ++i) {
    const Vec2 a = p[i], b = p[(i + 1) % p.size()];
    const Vec3 normal(b.y() - a.y(), 0.0, -(b.x() - a.x()));  // outward for CCW in (x, z)
    clip(normal, normal.x() * a.x() + normal.z() * a.y());
  }
  return std::max(0.0, hi - lo) * dir.norm();
}

TEST(Renderer, PrismJawMatchesIndependentCsgOnRandomPoses) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const std::vector<double> values = jaw.nominalValues();
  auto value = [&](const char* name) { return values[static_cast<size_t>(jaw.dimensionIndex(name))]; };
  const auto pieces = jawPieces(value("width"), value("groove_center"), value("thickness"),
                                value("groove_depth"), value("groove_left"),
                                value("groove_right"), value("slot_width"), value("slot_depth"));
  const TriangleMesh mesh = jaw.mesh(values);
  const Machine m = squareMachine(160, 0.5);
  std::mt19937_64 rng(2024);
  std::vector<Vec3> world;
  ImageT<double> path;
  int hits = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 20; ++trial) {
    // Rotate about the jaw's centre, then place it between source and detector.
    const Pose turn = randomPose(rng, Vec3::Zero(), 450.0, 8.0);
    Pose pose = turn;
    pose.translation_mm = turn.translation_mm - turn.rotation * Vec3(10.5, 20.0, 6.5);
    renderPathLength(m, posed(mesh, pose, world), {}, path);
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u) {
        const Ray ray = pixelRay(m, u, v);
        // The ray in the part frame.
        const Vec3 o = pose.rotation.transpose() * (ray.origin - pose.translation_mm);
        const Vec3 t = pose.rotation.transpose() * (ray.target - pose.translation_mm);
        double expected = 0.0;
        for (const auto& piece : pieces) expected += chord(piece, 40.0, o, t);
        worst = std::max(worst, std::abs(path(u, v) - expected));
        hits += expected > 0;
      }
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_GT(hits, 20 * 2000);
}

double diameter(const std::vector<Vec3>& vertices) {
  double d2 = 0.0;
  for (size_t i = 0; i < vertices.size(); ++i)
    for (size_t j = i + 1; j < vertices.size(); ++j)
      d2 = std::max(d2, (vertices[i] - vertices[j]).squaredNorm());
  return std::sqrt(d2);
}

// Renders `poses` poses and checks every pixel: entries == exits on every
// sample ray, and 0 <= path <= the part's diameter.
void checkWatertight(const TriangleMesh& mesh, const Vec3& centre, int poses, uint64_t seed) {
  const Machine m = squareMachine(256, 0.4);
  const double limit = diameter(mesh.vertices) + 1e-9;
  std::mt19937_64 rng(seed);
  std::vector<Vec3> world;
  for (int trial = 0; trial < poses; ++trial) {
    Pose pose;
    if (trial % 10 == 0) {
      // Axis-aligned poses whose vertices project onto sample-centre rows and
      // columns: every edge passes through sample centres (ties everywhere).
      std::uniform_int_distribution<int> quarter(0, 3), shift(-40, 40);
      pose = Pose::fromEulerDeg(Vec3(90.0 * quarter(rng), 90.0 * quarter(rng), 90.0 * quarter(rng)),
                                Vec3::Zero());
      pose.translation_mm = -pose.rotation * centre + Vec3(0.2 * shift(rng), 0.2 * shift(rng), 500.0);
    } else {
      pose = randomPose(rng, Vec3::Zero(), 500.0, 15.0);
      pose.translation_mm -= pose.rotation * centre;
    }
    const RenderDiagnostics d = renderDiagnostics(m, posed(mesh, pose, world), {});
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u) {
        ASSERT_EQ(d.unbalanced(u, v), 0) << "pose " << trial << " pixel " << u << ", " << v;
        ASSERT_EQ(d.entries(u, v), d.exits(u, v));
        ASSERT_GE(d.min_path_mm(u, v), -1e-9) << "pose " << trial;
        ASSERT_LE(d.max_path_mm(u, v), limit) << "pose " << trial;
      }
  }
}

TEST(Renderer, WatertightPrismJaw10000Poses) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  checkWatertight(jaw.mesh(jaw.nominalValues()), Vec3(10.5, 20.0, 6.5), 10000, 1);
}

// CAD exports hold zero-area slivers; a closed surface with one renders as
// watertight as without, and to the same paths.
TEST(Renderer, ZeroAreaSliverKeepsTheSurfaceWatertight) {
  const TriangleMesh plain = cuboid(20, 30, 10);
  TriangleMesh sliver = plain;
  sliver.vertices.push_back(0.5 * (plain.vertices[0] + plain.vertices[1]));  // m = 8
  sliver.triangles[0] = {0, 2, 8};
  sliver.triangles.push_back({8, 2, 1});
  sliver.triangles.push_back({0, 8, 1});  // zero area
  ASSERT_EQ(checkClosedMesh(sliver).zero_area_triangles, 1u);
  checkWatertight(sliver, Vec3::Zero(), 2000, 3);
  const Machine m = squareMachine(128, 0.8);
  std::mt19937_64 rng(4);
  std::vector<Vec3> a, b;
  for (int trial = 0; trial < 50; ++trial) {
    const Pose pose = randomPose(rng, Vec3::Zero(), 500.0, 15.0);
    ImageT<double> with, without;
    renderPathLength(m, posed(sliver, pose, a), {}, with);
    renderPathLength(m, posed(plain, pose, b), {}, without);
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.columns; ++u)
        ASSERT_NEAR(with(u, v), without(u, v), 1e-9) << "pose " << trial << " pixel " << u << ", " << v;
  }
}

// A cylinder as CAD exports it: caps triangulated as strips, whose first
// and last triangles become slivers of (almost) zero area as the segments
// grow; 50,000 segments, 200,000 triangles.
TriangleMesh stripCylinder(uint32_t n, double radius, double height) {
  TriangleMesh mesh;
  for (int ring = 0; ring < 2; ++ring)
    for (uint32_t i = 0; i < n; ++i) {
      const double angle = 2.0 * std::numbers::pi * i / n;
      mesh.vertices.emplace_back(radius * std::cos(angle), radius * std::sin(angle),
                                 ring ? 0.5 * height : -0.5 * height);
    }
  for (uint32_t i = 0; i < n; ++i) {  // sides, outward
    const uint32_t j = (i + 1) % n;
    mesh.triangles.push_back({i, j, n + j});
    mesh.triangles.push_back({i, n + j, n + i});
  }
  // Each cap: the strip 0, 1, n-1, 2, n-2, ... with alternating winding.
  std::vector<uint32_t> strip = {0};
  for (uint32_t k = 1; strip.size() < n; ++k) {
    strip.push_back(k);
    if (strip.size() < n) strip.push_back(n - k);
  }
  for (int top = 0; top < 2; ++top)
    for (size_t k = 0; k + 2 < strip.size(); ++k) {
      Triangle t = {strip[k], strip[k + 1], strip[k + 2]};
      if (k % 2 == 1) std::swap(t[0], t[1]);
      if (top) {
        for (uint32_t& v : t) v += n;
      } else {
        std::swap(t[1], t[2]);  // the bottom faces -z
      }
      mesh.triangles.push_back(t);
    }
  return mesh;
}

TEST(Renderer, StripTriangulatedCylinderWithSliversIsWatertight) {
  const TriangleMesh mesh = stripCylinder(50000, 10.0, 20.0);
  const MeshCheck check = checkClosedMesh(mesh);
  ASSERT_TRUE(check.ok()) << check.message;
  EXPECT_GT(check.zero_area_triangles, 0u);
  std::printf("%zu of %zu triangles have zero area\n", check.zero_area_triangles, mesh.triangles.size());
  EXPECT_NEAR(check.volume_mm3, std::numbers::pi * 100.0 * 20.0, 0.01);
  checkWatertight(mesh, Vec3::Zero(), 15, 5);
}

TEST(Renderer, WatertightCylinder10000Poses) {
  const PartModel cylinder = PartModel::load(kParts + "cylinder.json");
  checkWatertight(cylinder.mesh(cylinder.nominalValues()), Vec3::Zero(), 10000, 2);
}

TEST(Renderer, AreaSampledIntensityIsMonotoneInWidth) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const auto material = ExponentialSum({{0.6, 0.03}, {0.3, 0.08}, {0.1, 0.3}});
  const auto table = TransmissionTable::forMaterial(material, 100.0);
  const Machine m = squareMachine(512, 0.2);
  const Pose pose = Pose::fromEulerDeg(Vec3(8, 12, 3), Vec3(-10.5, -20.0, 420.0));
  RenderOptions options;
  options.samples_per_axis = 4;
  const double nominal = jaw.nominalValues()[static_cast<size_t>(jaw.dimensionIndex("width"))];
  std::vector<Vec3> world;
  Image image;
  double previous = HUGE_VAL;
  for (int step = -50; step <= 50; ++step) {
    const double width = nominal + 0.001 * step;
    const TriangleMesh mesh = jaw.mesh(jaw.values({{"width", width}}));
    renderIntensity(m, posed(mesh, pose, world), table, options, image);
    double sum = 0.0;
    for (float p : image.pixels()) sum += static_cast<double>(p);
    // More material, less light: strictly decreasing, no flat step.
    ASSERT_LT(sum, previous) << "width " << width;
    previous = sum;
  }
}

// The path image of the prism jaw at `pose` on a 300^2 detector: the same
// with one thread, and a region's pixels those of the full render.
ImageT<double> expectRegionAndThreadsIdentical(const Pose& pose, const RenderOptions& options) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const TriangleMesh mesh = jaw.mesh(jaw.nominalValues());
  const Machine m = squareMachine(300, 0.3);
  std::vector<Vec3> world;
  const WorldMesh w = posed(mesh, pose, world);
  ImageT<double> full, one_thread, part;
  renderPathLength(m, w, options, full);
  {
    ThreadLimit limit(1);
    renderPathLength(m, w, options, one_thread);
  }
  EXPECT_EQ(full.pixels().size(), one_thread.pixels().size());
  EXPECT_TRUE(std::equal(full.pixels().begin(), full.pixels().end(), one_thread.pixels().begin()));
  RenderOptions region = options;
  region.region = {97, 61, 120, 150};
  renderPathLength(m, w, region, part);
  int nonzero = 0, differ = 0;
  for (int y = 0; y < part.height(); ++y)
    for (int x = 0; x < part.width(); ++x) {
      differ += part(x, y) != full(x + 97, y + 61);
      nonzero += part(x, y) > 0;
    }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(nonzero, 1000);
  return full;
}

TEST(Renderer, RegionAndThreadCountGiveIdenticalPixels) {
  RenderOptions options;
  options.samples_per_axis = 3;
  expectRegionAndThreadsIdentical(Pose::fromEulerDeg(Vec3(30, 50, -20), Vec3(-8, -15, 500)),
                                  options);
}

// A jaw whose side walls stand along the beam: 2 x 2 point samples see each
// wall only where it passes a sample column, so the image moves in steps as
// the width grows; with the bent pixels refined at 16 x 16 it follows the
// width in steps 8 times finer, and it comes close to a 16 x 16 render
// everywhere, while 2 x 2 alone does not.
TEST(Renderer, EdgeRefinementApproachesTheFinelySampledImage) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const auto material = ExponentialSum({{0.6, 0.03}, {0.3, 0.08}, {0.1, 0.3}});
  const auto table = TransmissionTable::forMaterial(material, 100.0);
  const Machine m = squareMachine(256, 0.4);
  // Part x along detector columns, the profile's walls parallel to the beam
  // near the principal point.
  const Pose pose = Pose::fromEulerDeg(Vec3(0, 0, 0), Vec3(-10.5, -20.0, 600.0));
  const TriangleMesh mesh = jaw.mesh(jaw.nominalValues());
  std::vector<Vec3> world;
  const WorldMesh w = posed(mesh, pose, world);
  RenderOptions coarse, refined, fine;
  coarse.samples_per_axis = refined.samples_per_axis = 2;
  refined.edge_samples_per_axis = fine.samples_per_axis = 16;
  ImageT<double> a, b, c;
  renderIntensity(m, w, table, coarse, a);
  renderIntensity(m, w, table, refined, b);
  renderIntensity(m, w, table, fine, c);
  double coarse_error = 0.0, refined_error = 0.0;
  for (size_t k = 0; k < c.pixels().size(); ++k) {
    coarse_error = std::max(coarse_error, std::abs(a.pixels()[k] - c.pixels()[k]));
    refined_error = std::max(refined_error, std::abs(b.pixels()[k] - c.pixels()[k]));
  }
  EXPECT_GT(coarse_error, 0.02);
  // What is left: pixels whose bend stays below the threshold (1e-3), whose
  // 2 x 2 error is of that order.
  EXPECT_LT(refined_error, 2e-3);

  // The right wall on the principal ray, seen edge-on along its whole
  // height; the image sum against the width in steps of 1/64 of a pixel at
  // the part: 2 x 2 moves only where the wall passes one of the 2 sample
  // columns of a pixel, refined at 16 x 16 where it passes one of 16.
  const double nominal = jaw.nominalValues()[static_cast<size_t>(jaw.dimensionIndex("width"))];
  const Pose on_axis = Pose::fromEulerDeg(Vec3(0, 0, 0), Vec3(-nominal, -20.0, 600.0));
  const double pixel_at_part = 0.4 * (1000.0 - 600.0) / 1000.0;
  int coarse_moves = 0, refined_moves = 0;
  double coarse_previous = 0.0, refined_previous = 0.0;
  for (int step = 0; step <= 64; ++step) {
    const TriangleMesh wider = jaw.mesh(jaw.values({{"width", nominal + pixel_at_part * step / 64.0}}));
    const WorldMesh ww = posed(wider, on_axis, world);
    renderIntensity(m, ww, table, coarse, a);
    renderIntensity(m, ww, table, refined, b);
    double sa = 0.0, sb = 0.0;
    for (size_t k = 0; k < a.pixels().size(); ++k) sa += a.pixels()[k], sb += b.pixels()[k];
    if (step > 0) {
      coarse_moves += std::abs(sa - coarse_previous) > 1e-6;
      refined_moves += std::abs(sb - refined_previous) > 1e-6;
    }
    coarse_previous = sa, refined_previous = sb;
  }
  EXPECT_LE(coarse_moves, 4);
  EXPECT_GE(refined_moves, 14);
}

TEST(Renderer, EdgeRefinementKeepsRegionsAndThreadCountsIdentical) {
  const Pose pose = Pose::fromEulerDeg(Vec3(3, 20, -2), Vec3(-8, -15, 500));
  RenderOptions options;
  options.samples_per_axis = 2;
  options.edge_samples_per_axis = 8;
  options.edge_threshold = 0.05;  // mm of path
  const ImageT<double> refined = expectRegionAndThreadsIdentical(pose, options);
  options.edge_samples_per_axis = 0;
  const ImageT<double> plain = expectRegionAndThreadsIdentical(pose, options);
  int changed = 0;
  for (size_t k = 0; k < refined.pixels().size(); ++k)
    changed += refined.pixels()[k] != plain.pixels()[k];
  EXPECT_GT(changed, 100);  // the refinement did something
  options.edge_samples_per_axis = 2;  // not more than n
  const Machine m = squareMachine(300, 0.3);
  const TriangleMesh box = cuboid(10, 10, 10);
  std::vector<Vec3> world;
  ImageT<double> out;
  EXPECT_THROW(renderPathLength(m, posed(box, pose, world), options, out), Error);
}

TEST(Renderer, RejectsPartsOutsideTheBeamAndBadOptions) {
  const Machine m = squareMachine(64, 0.5);
  const TriangleMesh box = cuboid(10, 10, 10);
  std::vector<Vec3> world;
  ImageT<double> path;
  EXPECT_THROW(renderPathLength(m, posed(box, Pose::fromEulerDeg(Vec3::Zero(), Vec3(0, 0, 998)), world), {}, path), Error);
  EXPECT_THROW(renderPathLength(m, posed(box, Pose::fromEulerDeg(Vec3::Zero(), Vec3(0, 0, 2)), world), {}, path), Error);
  const WorldMesh ok = posed(box, Pose::fromEulerDeg(Vec3::Zero(), Vec3(0, 0, 500)), world);
  RenderOptions options;
  options.samples_per_axis = 0;
  EXPECT_THROW(renderPathLength(m, ok, options, path), Error);
  options.samples_per_axis = 1;
  options.region = {60, 0, 10, 10};
  EXPECT_THROW(renderPathLength(m, ok, options, path), Error);
}

}  // namespace
}  // namespace xgauge
