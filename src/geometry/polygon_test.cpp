#include "xgauge/geometry/polygon.h"

#include <gtest/gtest.h>

#include <numeric>

namespace xgauge {
namespace {

double triangleArea(std::span<const Vec2> polygon, const Triangle& t) {
  return orient2d(polygon[t[0]], polygon[t[1]], polygon[t[2]]) / 2.0;
}

// Every triangle has the polygon's winding and nonzero area, and together
// they cover the polygon's area.
void expectValidTriangulation(const std::vector<Vec2>& polygon) {
  const std::vector<Triangle> triangles = triangulatePolygon(polygon);
  ASSERT_EQ(triangles.size(), polygon.size() - 2);
  const double area = signedArea(polygon);
  double sum = 0.0;
  for (const Triangle& t : triangles) {
    const double a = triangleArea(polygon, t);
    EXPECT_GT(a * area, 1e-9 * area * area) << "triangle with the wrong winding or no area";
    sum += a;
  }
  EXPECT_NEAR(sum, area, 1e-12 * std::abs(area));
}

TEST(Polygon, SignedAreaFollowsWinding) {
  const std::vector<Vec2> square = {{0, 0}, {2, 0}, {2, 3}, {0, 3}};
  EXPECT_EQ(signedArea(square), 6.0);
  const std::vector<Vec2> reversed(square.rbegin(), square.rend());
  EXPECT_EQ(signedArea(reversed), -6.0);
}

TEST(Polygon, TriangulatesConvexConcaveAndClockwise) {
  expectValidTriangulation({{0, 0}, {2, 0}, {2, 3}, {0, 3}});
  // An L and a comb (several reflex vertices).
  expectValidTriangulation({{0, 0}, {4, 0}, {4, 1}, {1, 1}, {1, 3}, {0, 3}});
  expectValidTriangulation({{0, 0},
                            {7, 0},
                            {7, 3},
                            {6, 3},
                            {6, 1},
                            {5, 1},
                            {5, 3},
                            {4, 3},
                            {4, 1},
                            {3, 1},
                            {3, 3},
                            {2, 3},
                            {2, 1},
                            {1, 1},
                            {1, 3},
                            {0, 3}});
  expectValidTriangulation({{0, 3}, {1, 3}, {1, 1}, {4, 1}, {4, 0}, {0, 0}});  // clockwise
}

TEST(Polygon, CollinearVerticesGiveNoZeroAreaTriangles) {
  // A rectangle whose top edge holds two extra vertices, and a triangle with
  // a vertex in the middle of each side.
  expectValidTriangulation({{0, 0}, {6, 0}, {6, 2}, {4, 2}, {2, 2}, {0, 2}});
  expectValidTriangulation({{0, 0}, {1, 0}, {2, 0}, {1.5, 1}, {1, 2}, {0.5, 1}});
}

TEST(Polygon, SimplicityProblemsAreNamed) {
  EXPECT_EQ(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {1, 0}, {1, 1}}), "");
  EXPECT_EQ(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {1, 1}, {1, 0}, {0, 1}}),
            "edges 0-1 and 2-3 touch or cross");  // bow tie
  EXPECT_EQ(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {1, 0}, {1, 0}, {0, 1}}),
            "vertices 1 and 2 coincide (zero-length edge)");
  EXPECT_EQ(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {2, 0}, {1, 0}, {1, 1}}),
            "the edges at vertex 1 fold back onto each other");
  // A vertex touching a non-neighbouring edge.
  EXPECT_NE(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {4, 0}, {4, 2}, {2, 0}, {0, 2}}), "");
  EXPECT_NE(simplePolygonProblem(std::vector<Vec2>{{0, 0}, {1, 0}}), "");
}

TEST(Polygon, TriangulatingANonSimplePolygonFails) {
  EXPECT_THROW(triangulatePolygon(std::vector<Vec2>{{0, 0}, {1, 1}, {1, 0}, {0, 1}}), Error);
}

}  // namespace
}  // namespace xgauge
