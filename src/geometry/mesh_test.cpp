#include "xgauge/geometry/mesh.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

// Axis-aligned box [0, sx] x [0, sy] x [0, sz]; vertex i has bit 0 -> x,
// bit 1 -> y, bit 2 -> z at the upper side. Outward triangles.
TriangleMesh box(double sx, double sy, double sz) {
  TriangleMesh mesh;
  for (int i = 0; i < 8; ++i)
    mesh.vertices.emplace_back(i & 1 ? sx : 0, i & 2 ? sy : 0, i & 4 ? sz : 0);
  mesh.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

TEST(Mesh, BoxVolumeAndBounds) {
  TriangleMesh mesh = box(2, 3, 5);
  for (Vec3& v : mesh.vertices) v += Vec3(100, -50, 7);  // far from the origin
  EXPECT_NEAR(signedVolume(mesh), 30.0, 1e-11);
  const BoundingBox bounds = boundingBox(mesh);
  EXPECT_EQ(bounds.min_mm, Vec3(100, -50, 7));
  EXPECT_EQ(bounds.max_mm, Vec3(102, -47, 12));
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_TRUE(check.ok()) << check.message;
  EXPECT_NEAR(check.volume_mm3, 30.0, 1e-11);
}

TEST(Mesh, FlippedBoxIsInward) {
  TriangleMesh mesh = box(1, 1, 1);
  flipOrientation(mesh);
  EXPECT_NEAR(signedVolume(mesh), -1.0, 1e-15);
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_EQ(check.problem, MeshCheck::Problem::kInward);
  EXPECT_NE(check.message.find("oriented inward (negative volume"), std::string::npos)
      << check.message;
}

TEST(Mesh, MissingTriangleIsOpen) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.triangles.pop_back();  // (1, 7, 5)
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_EQ(check.problem, MeshCheck::Problem::kOpenEdge);
  EXPECT_EQ(check.message, "edge (1, 5) is used by 1 triangle (triangle 4): the mesh is open");
}

TEST(Mesh, OneFlippedTriangleIsInconsistent) {
  TriangleMesh mesh = box(1, 1, 1);
  std::swap(mesh.triangles[3][1], mesh.triangles[3][2]);
  EXPECT_EQ(checkClosedMesh(mesh).problem, MeshCheck::Problem::kInconsistentOrientation);
}

TEST(Mesh, ThirdTriangleOnAnEdgeIsNotManifold) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.vertices.emplace_back(0.5, -1, -1);
  mesh.triangles.push_back({0, 1, 8});
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_EQ(check.problem, MeshCheck::Problem::kNonManifoldEdge);
  EXPECT_NE(check.message.find("edge (0, 1) is used by 3 triangles"), std::string::npos);
}

TEST(Mesh, RepeatedVertexIsDegenerate) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.triangles[7] = {2, 2, 3};
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_EQ(check.problem, MeshCheck::Problem::kDegenerateTriangle);
  EXPECT_NE(check.message.find("triangle 7 is degenerate"), std::string::npos) << check.message;
}

TEST(Mesh, ZeroAreaSliverIsAcceptedWhenTheSurfaceIsClosed) {
  // Split the box edge (0, 1) at its midpoint m on one side only, and close
  // the gap with the sliver (0, 1, m): closed and consistent, and flat. It
  // adds nothing to any path (xray renderer_test renders it).
  TriangleMesh mesh = box(1, 1, 1);
  mesh.vertices.emplace_back(0.5, 0, 0);  // m = 8
  // Triangle 1 (0, 3, 1) uses 1 -> 0; replace it with (8, 3, 1) and (0, 3, 8).
  mesh.triangles[1] = {8, 3, 1};
  mesh.triangles.push_back({0, 3, 8});
  mesh.triangles.push_back({0, 8, 1});  // the sliver
  const MeshCheck check = checkClosedMesh(mesh);
  EXPECT_TRUE(check.ok()) << check.message;
  EXPECT_EQ(check.zero_area_triangles, 1u);
  EXPECT_NEAR(check.volume_mm3, checkClosedMesh(box(1, 1, 1)).volume_mm3, 1e-12);
  // Without the sliver the same surface is open along (0, 1): a zero-area
  // triangle is accepted only where the surface needs it.
  mesh.triangles.pop_back();
  EXPECT_EQ(checkClosedMesh(mesh).problem, MeshCheck::Problem::kOpenEdge);
}

TEST(Mesh, BadIndexAndEmpty) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.triangles[0][2] = 8;
  EXPECT_EQ(checkClosedMesh(mesh).problem, MeshCheck::Problem::kBadIndex);
  EXPECT_EQ(checkClosedMesh(TriangleMesh{}).problem, MeshCheck::Problem::kEmpty);
}

TEST(Mesh, RequireThrowsWithLocation) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.triangles.pop_back();
  try {
    requireClosedMesh(mesh, SourceLocation::at("part.json", "/shape"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "part.json");
    EXPECT_EQ(std::string(e.what()),
              "part.json: /shape: edge (1, 5) is used by 1 triangle (triangle 4): the mesh is "
              "open");
  }
  EXPECT_NO_THROW(requireClosedMesh(box(1, 2, 3), {}));
}

}  // namespace
}  // namespace xgauge
