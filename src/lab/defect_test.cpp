// Simulated defects: the chord of a ray through a void in closed form, the
// check that a void lies inside the part, and a void's mark on a radiograph:
// only where its rays go, brightest where truth.json says it projects.
#include "xgauge/lab/defect.h"

#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/recipe.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

// The nominal cuboid: 20 x 30 x 10 mm centred on the part origin.
TriangleMesh cuboid() {
  const PartModel model = PartModel::load(kRoot + "/parts/cuboid.json");
  return model.mesh(model.values({}));
}

TEST(SegmentSphereChord, MatchesClosedForms) {
  const Vec3 centre(1.0, -2.0, 400.0);
  const double r = 0.75;
  const Vec3 source(0.0, 0.0, 1000.0);
  const Vec3 ray = (centre - source).normalized();
  const Vec3 across = ray.unitOrthogonal();
  // A segment along the ray direction passing at distance d from the centre,
  // both ends far outside the sphere.
  const auto chordAt = [&](double d) {
    const Vec3 foot = centre + d * across;
    return segmentSphereChordMm(foot - 600.0 * ray, foot + 400.0 * ray, centre, r);
  };
  EXPECT_NEAR(chordAt(0.0), 2.0 * r, 1e-12);  // through the centre: the diameter
  for (double d : {0.1, 0.5, 0.7, 0.749})
    EXPECT_NEAR(chordAt(d), 2.0 * std::sqrt(r * r - d * d), 1e-9) << "d = " << d;
  EXPECT_NEAR(chordAt(r), 0.0, 1e-6);  // tangent
  EXPECT_EQ(chordAt(1.5 * r), 0.0);    // miss
  EXPECT_EQ(chordAt(100.0), 0.0);
  // From the source to the true detector point behind the centre.
  const Vec3 detector_point = source + (source.z() / -ray.z()) * ray;
  EXPECT_NEAR(segmentSphereChordMm(source, detector_point, centre, r), 2.0 * r, 1e-12);
  // A segment that ends at the centre holds half the diameter; one that stops
  // short of the sphere holds nothing.
  EXPECT_NEAR(segmentSphereChordMm(source, centre, centre, r), r, 1e-12);
  EXPECT_EQ(segmentSphereChordMm(source, centre - 2.0 * r * ray, centre, r), 0.0);
}

TEST(ClosestPointOnTriangle, EachRegion) {
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  EXPECT_TRUE(closestPointOnTriangle(Vec3(0.5, 0.5, 3), a, b, c).isApprox(Vec3(0.5, 0.5, 0)));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(-1, -1, 1), a, b, c).isApprox(a));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(3, -1, 0), a, b, c).isApprox(b));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(1, -1, 0), a, b, c).isApprox(Vec3(1, 0, 0)));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(2, 2, 0), a, b, c).isApprox(Vec3(1, 1, 0)));
}

TEST(VoidInsidePart, AcceptsAVoidInsideAndRefusesOnePokingOut) {
  const TriangleMesh mesh = cuboid();
  EXPECT_TRUE(insideMesh(mesh, Vec3(9.9, 14.9, 4.9)));
  EXPECT_FALSE(insideMesh(mesh, Vec3(10.1, 0.0, 0.0)));
  EXPECT_NEAR(distanceToTrianglesMm(mesh, Vec3(1.0, 2.0, 3.5)), 1.5, 1e-12);  // to z = 5
  EXPECT_FALSE(voidOutsidePart(mesh, Vec3(0, 0, 0), 4.9));
  // 0.5 mm from the front face z = 5: a radius of 1 crosses it.
  const auto poking = voidOutsidePart(mesh, Vec3(0, 0, 4.5), 1.0);
  ASSERT_TRUE(poking);
  EXPECT_NE(poking->find("pokes out"), std::string::npos) << *poking;
  const auto outside = voidOutsidePart(mesh, Vec3(0, 0, 6.0), 0.5);
  ASSERT_TRUE(outside);
  EXPECT_NE(outside->find("not inside"), std::string::npos) << *outside;
}

TEST(ReadDefects, RefusesBadEntriesNamingTheKey) {
  const TriangleMesh mesh = cuboid();
  const auto read = [&](const std::string& json) {
    const ConfigNode root = ConfigNode::parse(json, "recipe.json");
    const auto defects = readDefects(root.at("defects"), mesh);
    root.finish();
    return defects;
  };
  const auto defects =
      read(R"({"defects": [{"type": "void", "centre_mm": [1, 2, 3], "diameter_mm": 1.5}]})");
  ASSERT_EQ(defects.size(), 1u);
  EXPECT_EQ(defects[0].centre_part_mm, Vec3(1, 2, 3));
  EXPECT_EQ(defects[0].diameter_mm, 1.5);
  const auto expect = [&](const std::string& json, const std::string& message) {
    try {
      read(json);
      FAIL() << "expected an error for " << json;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 4.5], "diameter_mm": 2}]})",
         "/defects/0/centre_mm");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 4.5], "diameter_mm": 2}]})",
         "pokes out");
  expect(R"({"defects": [{"type": "crack", "centre_mm": [0, 0, 0], "diameter_mm": 1}]})",
         "/defects/0/type");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 0], "diameter_mm": 0.01}]})",
         "/defects/0/diameter_mm");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 0], "diameter_mm": 21}]})",
         "/defects/0/diameter_mm");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0], "diameter_mm": 1}]})",
         "/defects/0/centre_mm");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 0], "diameter_mm": 1,
                          "diametr_mm": 1}]})",
         "unknown key 'diametr_mm'");
  expect(R"({"defects": [{"type": "void", "centre_mm": [0, 0, 0], "diameter_mm": 2},
                         {"type": "void", "centre_mm": [1.5, 0, 0], "diameter_mm": 2}]})",
         "/defects/1");
}

// Pixels with at least one of their n x n sample rays (renderer.h's grid)
// through the sphere.
ImageT<uint8_t> crossedPixels(const Machine& machine, const WorldSphere& sphere, int n) {
  ImageT<uint8_t> crossed(machine.columns, machine.rows, 0);
  for (int v = 0; v < machine.rows; ++v)
    for (int u = 0; u < machine.columns; ++u)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Vec3 p = machine.detectorPoint(u + (i + 0.5) / n, v + (j + 0.5) / n);
          if (segmentSphereChordMm(machine.sourceWorld(), p, sphere.centre_mm, sphere.radius_mm) >
              0)
            crossed(u, v) = 1;
        }
  return crossed;
}

TEST(CarveVoids, ChangesOnlyThePixelsWhoseRaysCrossTheVoid) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = 160;
  machine.rows = 120;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.5;
  machine.cx_px = 81.3;  // off the image centre, as real principal points are
  machine.cy_px = 58.6;
  const TriangleMesh mesh = cuboid();
  const Pose pose = Pose::fromEulerDeg(Vec3(10, 20, 5), Vec3(2.0, -1.0, 500.0));
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  const WorldMesh posed{world, mesh.triangles, nullptr};
  const TransmissionTable table([](double x) { return std::exp(-0.05 * x); },
                                [](double x) { return -0.05 * std::exp(-0.05 * x); }, 60.0, 0.01);
  const int n = 3;
  Image plain;
  renderIntensity(machine, posed, table, RenderOptions{n, {}}, plain);
  const WorldSphere sphere{pose.apply(Vec3(3.0, -5.0, 1.0)), 1.0};
  Image carved = plain;
  carveVoids(machine, posed, std::span(&sphere, 1), table, n, carved);

  const ImageT<uint8_t> crossed = crossedPixels(machine, sphere, n);
  int changed = 0, best_u = -1, best_v = -1;
  float best = 0.0f;
  for (int v = 0; v < machine.rows; ++v)
    for (int u = 0; u < machine.columns; ++u) {
      const float increase = carved(u, v) - plain(u, v);
      if (!crossed(u, v)) {
        ASSERT_EQ(carved(u, v), plain(u, v)) << "pixel " << u << ", " << v;
        continue;
      }
      EXPECT_GE(increase, 0.0f);
      changed += increase > 0.0f;
      if (increase > best) best = increase, best_u = u, best_v = v;
    }
  // The shadow: about pi (2 mm x 2 / 0.5 mm)^2 / 4 = 50 pixels.
  EXPECT_GT(changed, 30);
  EXPECT_LT(changed, 90);
  // Through the centre the void removes 2 mm of 0.05/mm: I rises by e^0.1.
  const Vec2 centre = machine.project(sphere.centre_mm);
  EXPECT_LE(std::abs(best_u + 0.5 - centre.x()), 1.0);
  EXPECT_LE(std::abs(best_v + 0.5 - centre.y()), 1.0);
  const int cu = static_cast<int>(centre.x()), cv = static_cast<int>(centre.y());
  EXPECT_NEAR(carved(cu, cv) / plain(cu, cv), std::exp(0.1), 0.01);
}

class DefectDataset : public ::testing::Test {
 protected:
  void SetUp() override {
    setProgressEnabled(false);
    dir_ = fs::temp_directory_path() /
           ("xgauge_defect_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "machine.json") << R"({"source_detector_distance_mm": 1000,
      "detector": {"columns": 160, "rows": 120, "pixel_pitch_mm": [0.5, 0.5],
                   "principal_point_px": [78.5, 61.25]}})";
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The cuboid in two translated shots, no scatter, and a detector whose
  // output depends on each pixel's own intensity only (no photon noise, gain
  // spread, dead pixels or lag), so a void can change nothing else.
  fs::path recipe(const std::string& name, const std::string& defects) {
    const std::string text = R"({
      "description": "defect test", "seed": 11, "machine": "machine.json",
      "beam": {"tube_kv": 150, "filters": [],
        "detector_window": {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 0.5}},
      "material": {"compound": "Al", "density_g_cm3": 2.699},
      "detector": {"area_samples": 2, "flat_frames": 1,
        "noise": {"photon_noise": false, "gain_pixel_sigma": 0, "gain_smooth_sigma": 0,
                  "dead_pixel_fraction": 0, "ghost_fraction": 0, "quantize_16bit": false}},
      "part": {"model": ")" + kRoot +
                             R"(/parts/cuboid.json"},
      "shots": {"base_pose": {"rotation_deg": [10, 20, 0], "translation_mm": [-6, 0, 500]},
                "translations": {"count": 2, "distance_mm": 8, "axis": [1, 0.2, 0]}},
      "white_region": [0, 0, 8, 8])" +
                             defects + "}";
    const fs::path path = dir_ / (name + ".json");
    std::ofstream(path) << text;
    return path;
  }

  fs::path dir_;
};

TEST_F(DefectDataset, VoidBrightensOnlyItsShadowWhereTruthSaysItProjects) {
  const Vec3 centre_part(3.0, -5.0, 1.0);
  const double diameter = 2.0;
  simulateDataset(Recipe::load(recipe("plain", "")), dir_ / "plain");
  simulateDataset(
      Recipe::load(recipe("void", R"(, "defects": [{"type": "void", "centre_mm": [3, -5, 1],
                                                    "diameter_mm": 2}])")),
      dir_ / "void");

  std::ifstream in(dir_ / "void" / "truth.json");
  const auto truth = nlohmann::json::parse(in);
  ASSERT_EQ(truth["defects"].size(), 1u);
  EXPECT_EQ(truth["defects"][0]["type"], "void");
  EXPECT_EQ(truth["defects"][0]["diameter_mm"], diameter);
  EXPECT_EQ(truth["defects"][0]["centre_mm"][1], -5.0);
  const Machine machine = Machine::fromConfig(ConfigNode::fromJson(truth["machine"], "truth"));
  for (const auto& shot : truth["shots"]) {
    SCOPED_TRACE(shot["name"].get<std::string>());
    const auto& defect = shot["defects"][0];
    Mat4 matrix;
    for (int k = 0; k < 16; ++k) matrix(k / 4, k % 4) = shot["pose"]["matrix"][k].get<double>();
    const Pose pose = Pose::fromMatrix(matrix);
    const Vec3 world = pose.apply(centre_part);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(defect["centre_world_mm"][k].get<double>(), world[k], 1e-9);
    const double pu = defect["centre_px"][0], pv = defect["centre_px"][1];
    EXPECT_NEAR(defect["diameter_px"][0].get<double>(),
                diameter * 1000.0 / (1000.0 - world.z()) / 0.5, 1e-9);

    // Raw images of the same seed: equal except where the void's rays go.
    const std::string file = shot["file"];
    const Image plain = readTiff(dir_ / "plain" / file);
    const Image with_void = readTiff(dir_ / "void" / file);
    const ImageT<uint8_t> crossed = crossedPixels(machine, {world, 0.5 * diameter}, 2);
    int changed = 0, best_u = -1, best_v = -1;
    float best = 0.0f;
    for (int v = 0; v < machine.rows; ++v)
      for (int u = 0; u < machine.columns; ++u) {
        const float increase = with_void(u, v) - plain(u, v);
        if (!crossed(u, v)) {
          ASSERT_EQ(increase, 0.0f) << "pixel " << u << ", " << v;
          continue;
        }
        changed += increase > 0.0f;
        if (increase > best) best = increase, best_u = u, best_v = v;
      }
    EXPECT_GT(changed, 30);
    EXPECT_LE(std::abs(best_u + 0.5 - pu), 1.0) << "brightest at column " << best_u;
    EXPECT_LE(std::abs(best_v + 0.5 - pv), 1.0) << "brightest at row " << best_v;
  }
}

TEST_F(DefectDataset, RecipeRefusesAVoidPokingOutOfThePart) {
  try {
    Recipe::load(recipe("bad", R"(, "defects": [{"type": "void", "centre_mm": [9.5, 0, 0],
                                                 "diameter_mm": 1.5}])"));
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/defects/0/centre_mm"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("pokes out"), std::string::npos) << e.what();
  }
}

TEST(PrismVoidDataset, VoidLiesInsideTheJaw) {
  // The dataset recipe loads, which checks its void against the jaw.
  const Recipe recipe = Recipe::load(kRoot + "/datasets/prism_a_small_void.json");
  ASSERT_EQ(recipe.defects.size(), 1u);
  EXPECT_EQ(recipe.defects[0].diameter_mm, 1.5);
  EXPECT_EQ(recipe.shots.size(), 2u);
}

}  // namespace
}  // namespace xgauge
