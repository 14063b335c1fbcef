#include "xgauge/xray/contour.h"

#include "test_machines.h"

#include "xgauge/geometry/part_model.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

using testing::kParts;

// The contour of a 20 x 30 x 10 mm cuboid (parts/cuboid.json) at
// `translation` without rotation, seen by a 512^2 detector of 0.2 mm.
std::vector<Segment2> cuboidContour(const Vec3& translation) {
  const PartModel cuboid = PartModel::load(kParts + "cuboid.json");
  const TriangleMesh mesh = cuboid.mesh(std::vector<double>{20.0, 30.0, 10.0});
  Pose pose;
  pose.translation_mm = translation;
  std::vector<Vec3> storage;
  return projectedContour(testing::squareMachine(512, 0.2), testing::posed(mesh, pose, storage));
}

// A cuboid squarely in front of the source on the axis: its side walls face
// away, so the contour is the four edges of its face nearest the source,
// projected with that face's magnification D / (D - z).
TEST(Contour, CuboidFacingTheSourceIsItsNearFace) {
  const auto segments = cuboidContour(Vec3(0.0, 0.0, 400.0));
  ASSERT_EQ(segments.size(), 4u);
  const double m = 1000.0 / (1000.0 - 405.0);  // the near face at z = 400 + 5
  double min_u = 1e9, max_u = -1e9, min_v = 1e9, max_v = -1e9;
  for (const auto& s : segments)
    for (const Vec2& p : s) {
      min_u = std::min(min_u, p.x()), max_u = std::max(max_u, p.x());
      min_v = std::min(min_v, p.y()), max_v = std::max(max_v, p.y());
      // Every end point is a corner of the projected near face.
      EXPECT_NEAR(std::abs(p.x() - 256.0), 10.0 * m / 0.2, 1e-9);
      EXPECT_NEAR(std::abs(p.y() - 256.0), 15.0 * m / 0.2, 1e-9);
    }
  EXPECT_NEAR(max_u - min_u, 20.0 * m / 0.2, 1e-9);
  EXPECT_NEAR(max_v - min_v, 30.0 * m / 0.2, 1e-9);
}

// Moved off axis, one side wall turns to the source and the contour runs
// along the far edge of that wall: still a closed loop of six edges.
TEST(Contour, OffAxisCuboidShowsOneWall) {
  const auto segments = cuboidContour(Vec3(40.0, 0.0, 400.0));
  EXPECT_EQ(segments.size(), 6u);
  // Closed loop: every end point is shared by exactly two segments.
  for (const auto& s : segments)
    for (const Vec2& p : s) {
      int uses = 0;
      for (const auto& t : segments)
        for (const Vec2& q : t) uses += (p - q).norm() < 1e-9 ? 1 : 0;
      EXPECT_EQ(uses, 2);
    }
}

}  // namespace
}  // namespace xgauge
