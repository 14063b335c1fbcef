// The shipped part files (parts/*.json) against docs/conventions.md: names, order and
// nominal values of the dimensions, vertex positions and closed-form volumes
// computed here from docs/conventions.md's own formulas.
#include "xgauge/geometry/part_model.h"

#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace xgauge {
namespace {

PartModel loadPart(const std::string& name) {
  return PartModel::load(std::filesystem::path(XGAUGE_SOURCE_DIR) / "parts" / (name + ".json"));
}

std::vector<std::string> names(const PartModel& model) {
  std::vector<std::string> out;
  for (const Dimension& dimension : model.dimensions()) out.push_back(dimension.name);
  return out;
}

TEST(Parts, EveryShippedPartIsClosedAndOutwardAtNominal) {
  for (const char* name : {"prism_jaw", "wedge_block", "cuboid", "cylinder"}) {
    SCOPED_TRACE(name);
    const PartModel model = loadPart(name);
    EXPECT_EQ(model.name(), name);
    EXPECT_FALSE(model.description().empty());
    const MeshCheck check = checkClosedMesh(model.mesh(model.nominalValues()));
    EXPECT_TRUE(check.ok()) << check.message;
    for (const Dimension& dimension : model.dimensions()) {
      EXPECT_EQ(dimension.unit, "mm");
      EXPECT_LT(dimension.min, dimension.nominal);
      EXPECT_GT(dimension.max, dimension.nominal);
    }
  }
}

// Any values within the bounds that satisfy the constraints give a closed,
// outward mesh with the fixed topology (no cap triangle turning over).
TEST(Parts, EveryValidSampleGivesAClosedOutwardMesh) {
  for (const char* name : {"prism_jaw", "wedge_block", "cuboid", "cylinder"}) {
    SCOPED_TRACE(name);
    const PartModel model = loadPart(name);
    std::mt19937_64 random(12345);
    int valid = 0;
    for (int sample = 0; sample < 2000; ++sample) {
      std::vector<double> values;
      for (const Dimension& dimension : model.dimensions())
        values.push_back(
            std::uniform_real_distribution<double>(dimension.min, dimension.max)(random));
      try {
        model.validate(values);
      } catch (const Error&) {
        continue;
      }
      ++valid;
      TriangleMesh mesh;
      ASSERT_NO_THROW(mesh = model.mesh(values)) << fmt::format("{}", fmt::join(values, ", "));
      const MeshCheck check = checkClosedMesh(mesh);
      ASSERT_TRUE(check.ok()) << check.message;
    }
    EXPECT_GT(valid, 200);
  }
}

// ---------------------------------------------------------------------------
// Prism jaw

struct Prism {  // docs/conventions.md symbols, in the order of the part's dimensions
  double W, c, T, g, a_l, a_r, s_w, s_d;
  std::vector<double> values() const { return {W, c, T, g, a_l, a_r, s_w, s_d}; }
};
constexpr Prism kPrismA = {20.977, 10.438, 13.020, 6.923, 6.848, 6.963, 4.104, 3.951};
constexpr Prism kPrismB = {20.951, 10.462, 10.048, 5.204, 5.101, 5.219, 3.052, 2.903};
constexpr double kPrismLength = 40.0;

// P0..P9 of docs/conventions.md, (x, z).
std::vector<Vec2> prismProfile(const Prism& p) {
  return {{0, 0},
          {p.W, 0},
          {p.W, p.T},
          {p.c + p.a_r, p.T},
          {p.c + p.s_w / 2, p.T - p.g * (1 - p.s_w / (2 * p.a_r))},
          {p.c + p.s_w / 2, p.T - p.g - p.s_d},
          {p.c - p.s_w / 2, p.T - p.g - p.s_d},
          {p.c - p.s_w / 2, p.T - p.g * (1 - p.s_w / (2 * p.a_l))},
          {p.c - p.a_l, p.T},
          {0, p.T}};
}

double shoelaceArea(const std::vector<Vec2>& polygon) {
  double twice = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& a = polygon[i];
    const Vec2& b = polygon[(i + 1) % polygon.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return twice / 2.0;
}

TEST(Parts, PrismJawDimensionsFollowPartsMd) {
  const PartModel model = loadPart("prism_jaw");
  EXPECT_EQ(names(model),
            (std::vector<std::string>{"width", "groove_center", "thickness", "groove_depth",
                                      "groove_left", "groove_right", "slot_width", "slot_depth"}));
  std::vector<std::string> thesis;
  for (const Dimension& dimension : model.dimensions()) thesis.push_back(dimension.thesis);
  EXPECT_EQ(thesis, (std::vector<std::string>{"θ8", "θ7", "θ2", "θ1", "θ3", "θ4", "θ5", "θ6"}));
  EXPECT_EQ(model.nominalValues(), kPrismA.values());
  EXPECT_EQ(model.vertexCount(), 20u);
  EXPECT_EQ(model.triangles().size(), 36u);  // 10 side quads, two caps of 8
}

TEST(Parts, PrismJawVerticesAndVolumeForPrismsAAndB) {
  const PartModel model = loadPart("prism_jaw");
  for (const Prism& prism : {kPrismA, kPrismB}) {
    const TriangleMesh mesh = model.mesh(prism.values());
    const std::vector<Vec2> profile = prismProfile(prism);
    for (size_t i = 0; i < profile.size(); ++i) {
      // Pi at y = 0 is vertex i, at y = L vertex 10 + i.
      const Vec3 bottom(profile[i].x(), 0, profile[i].y());
      const Vec3 top(profile[i].x(), kPrismLength, profile[i].y());
      EXPECT_LT((mesh.vertices[i] - bottom).norm(), 1e-13) << "P" << i;
      EXPECT_LT((mesh.vertices[10 + i] - top).norm(), 1e-13) << "P" << i;
    }
    const MeshCheck check = checkClosedMesh(mesh);
    EXPECT_TRUE(check.ok()) << check.message;
    EXPECT_NEAR(check.volume_mm3, kPrismLength * shoelaceArea(profile), 1e-10);
  }
}

TEST(Parts, PrismJawWidthMovesOnlyTheRightFace) {
  const PartModel model = loadPart("prism_jaw");
  std::vector<Vec3> nominal, wider;
  model.evaluate(model.nominalValues(), nominal);
  model.evaluate(model.values({{"width", 21.5}}), wider);
  for (size_t i = 0; i < nominal.size(); ++i) {
    const bool right_face = i == 1 || i == 2 || i == 11 || i == 12;  // P1, P2 at both ends
    const Vec3 expected = right_face ? nominal[i] + Vec3(21.5 - kPrismA.W, 0, 0) : nominal[i];
    EXPECT_LT((wider[i] - expected).norm(), 1e-14) << i;
  }
}

TEST(Parts, PrismJawConstraintsFromPartsMd) {
  const PartModel model = loadPart("prism_jaw");
  auto violated = [&](const std::map<std::string, double>& overrides) -> std::string {
    try {
      model.validate(model.values(overrides));
    } catch (const Error& e) {
      return e.message();
    }
    return "";
  };
  EXPECT_EQ(violated({}), "");
  EXPECT_NE(violated({{"groove_center", 7.5}, {"groove_left", 8}}).find("cut the left face"),
            std::string::npos);
  EXPECT_NE(violated({{"groove_center", 13}, {"groove_right", 8.5}}).find("cut the right face"),
            std::string::npos);
  EXPECT_NE(violated({{"slot_width", 7.5}, {"groove_left", 3.6}}).find("s_w/2 < a_l"),
            std::string::npos);
  EXPECT_NE(violated({{"slot_width", 7.5}, {"groove_right", 3.6}}).find("s_w/2 < a_r"),
            std::string::npos);
  EXPECT_NE(violated({{"thickness", 9}, {"slot_depth", 4}}).find("back face"), std::string::npos);
}

// ---------------------------------------------------------------------------
// Wedge block

struct Wedge {  // docs/conventions.md table order
  double T, thin, plt, prt, wlt, wrt, wlm, wrm, plm, prm;
  std::vector<double> values() const { return {T, thin, plt, prt, wlt, wrt, wlm, wrm, plm, prm}; }
};
constexpr Wedge kWedgeNominal = {20.0, 0.2, 29.58, 29.66, 8.8, 8.4, 9.2, 8.1, 29.7, 29.65};
constexpr double kWedgeLength = 90.0;  // H

// x at y = 0 of the line through x_mid at y = H/2 and x_top at y = H.
double atBottom(double x_mid, double x_top) { return x_mid - (x_top - x_mid); }

// Block minus pocket. Widths are linear in y, the pocket depth is
// (T - thin) y / H, so the pocket holds (T - thin) H (p(0)/6 + p(H)/3).
double wedgeVolume(const Wedge& w) {
  const double H = kWedgeLength;
  const double outer_mid = (w.prm + w.wrm) + (w.plm + w.wlm);
  const double outer_top = (w.prt + w.wrt) + (w.plt + w.wlt);
  const double pocket_mid = w.prm + w.plm, pocket_top = w.prt + w.plt;
  const double block = w.T * H * (atBottom(outer_mid, outer_top) + outer_top) / 2;
  const double pocket =
      (w.T - w.thin) * H * (atBottom(pocket_mid, pocket_top) / 6 + pocket_top / 3);
  return block - pocket;
}

TEST(Parts, WedgeBlockDimensionsFollowPartsMd) {
  const PartModel model = loadPart("wedge_block");
  EXPECT_EQ(names(model), (std::vector<std::string>{
                              "thickness", "thin_end", "pocket_left_top", "pocket_right_top",
                              "wall_left_top", "wall_right_top", "wall_left_mid", "wall_right_mid",
                              "pocket_left_mid", "pocket_right_mid"}));
  for (size_t i = 0; i < model.dimensions().size(); ++i)
    EXPECT_EQ(model.dimensions()[i].thesis, fmt::format("θ{}", i + 1));
  EXPECT_EQ(model.nominalValues(), kWedgeNominal.values());
  EXPECT_EQ(model.vertexCount(), 14u);
  EXPECT_EQ(model.triangles().size(), 24u);
}

TEST(Parts, WedgeBlockEdgesFloorAndVolume) {
  const PartModel model = loadPart("wedge_block");
  const Wedge other = {18.5, 0.6, 30.1, 28.9, 9.4, 7.7, 8.6, 8.3, 29.2, 29.9};
  for (const Wedge& w : {kWedgeNominal, other}) {
    const TriangleMesh mesh = model.mesh(w.values());
    const auto& v = mesh.vertices;
    const double H = kWedgeLength;
    // Each edge: (vertex at y = 0, vertex at y = H, x at H/2, x at H).
    struct Edge {
      int bottom, top;
      double x_mid, x_top;
    };
    for (const Edge& edge :
         {Edge{0, 6, -(w.plm + w.wlm), -(w.plt + w.wlt)}, Edge{4, 12, -w.plm, -w.plt},
          Edge{4, 11, -w.plm, -w.plt}, Edge{3, 9, w.prm, w.prt}, Edge{3, 10, w.prm, w.prt},
          Edge{1, 7, w.prm + w.wrm, w.prt + w.wrt}}) {
      EXPECT_EQ(v[edge.bottom].y(), 0.0);
      EXPECT_EQ(v[edge.top].y(), H);
      EXPECT_NEAR(v[edge.top].x(), edge.x_top, 1e-13);
      EXPECT_NEAR((v[edge.bottom].x() + v[edge.top].x()) / 2, edge.x_mid, 1e-13);
    }
    // The pocket floor: zero depth at y = 0, thin_end of material at y = H.
    EXPECT_EQ(v[3].z(), w.T);
    EXPECT_EQ(v[4].z(), w.T);
    EXPECT_EQ(v[10].z(), w.thin);
    EXPECT_EQ(v[11].z(), w.thin);
    const MeshCheck check = checkClosedMesh(mesh);
    EXPECT_TRUE(check.ok()) << check.message;
    EXPECT_NEAR(check.volume_mm3, wedgeVolume(w), 1e-9);
  }
}

// ---------------------------------------------------------------------------
// Cuboid and cylinder

TEST(Parts, CuboidVolumeAndBounds) {
  const PartModel model = loadPart("cuboid");
  EXPECT_EQ(names(model), (std::vector<std::string>{"size_x", "size_y", "size_z"}));
  EXPECT_EQ(model.vertexCount(), 8u);
  EXPECT_EQ(model.triangles().size(), 12u);
  for (const std::vector<double>& size :
       {model.nominalValues(), std::vector<double>{12.5, 41.0, 7.25}}) {
    const TriangleMesh mesh = model.mesh(size);
    EXPECT_NEAR(signedVolume(mesh), size[0] * size[1] * size[2], 1e-10);
    const BoundingBox box = boundingBox(mesh);
    EXPECT_EQ(box.max_mm, Vec3(size[0], size[1], size[2]) / 2);
    EXPECT_EQ(box.min_mm, -box.max_mm);
  }
}

TEST(Parts, CylinderVolumeAndChordError) {
  const PartModel model = loadPart("cylinder");
  EXPECT_EQ(names(model), (std::vector<std::string>{"diameter", "height"}));
  EXPECT_EQ(model.nominalValues(), (std::vector<double>{20.0, 30.0}));
  constexpr int kSegments = 256;  // as the file's description states
  EXPECT_EQ(model.vertexCount(), 2u * kSegments + 2);
  EXPECT_EQ(model.triangles().size(), 4u * kSegments);
  const double pi = std::numbers::pi;
  EXPECT_LT(10.0 * (1 - std::cos(pi / kSegments)), 0.001);  // chord error at nominal

  for (const std::vector<double>& dh : {model.nominalValues(), std::vector<double>{13.0, 41.5}}) {
    const double r = dh[0] / 2, h = dh[1];
    const TriangleMesh mesh = model.mesh(dh);
    EXPECT_NEAR(signedVolume(mesh), kSegments / 2.0 * r * r * std::sin(2 * pi / kSegments) * h,
                1e-9);
    for (const Vec3& vertex : mesh.vertices) {
      const double radius = std::hypot(vertex.x(), vertex.z());
      EXPECT_TRUE(radius == 0 || std::abs(radius - r) < 1e-13) << radius;
      EXPECT_EQ(std::abs(vertex.y()), h / 2);
    }
  }
}

}  // namespace
}  // namespace xgauge
