// Datasets from recipes: exact truth, determinism, and what a user sees in
// normalized open-beam pixels.
#include "xgauge/lab/dataset.h"

#include "xgauge/core/parallel.h"
#include "xgauge/core/progress.h"
#include "xgauge/image/normalize.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

class Dataset : public ::testing::Test {
 protected:
  void SetUp() override {
    setProgressEnabled(false);
    dir_ = fs::temp_directory_path() /
           ("xgauge_dataset_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "machine.json") << R"({"source_detector_distance_mm": 1000,
      "detector": {"columns": 160, "rows": 120, "pixel_pitch_mm": [0.5, 0.5]}})";
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A small recipe: the cuboid, 3 translations of 7.5 mm, 2 rotations.
  std::string recipe(uint64_t seed, const std::string& extra = "", const std::string& detector = "") {
    const std::string text = R"({
      "description": "test", "seed": )" + std::to_string(seed) + R"(,
      "machine": "machine.json",
      "beam": {"tube_kv": 150,
        "filters": [{"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 1}],
        "detector_window": {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 0.5}},
      "material": {"compound": "Al", "density_g_cm3": 2.699},
      "detector": {"area_samples": 2, "focal_spot": {"fwhm_mm": 0.05, "samples": 3},
        "scatter": {"weight": 0.139, "sigma_px": 20}, "flat_frames": 4,
        "noise": {"dead_pixel_fraction": 0.001})" + detector + R"(},
      "part": {"model": ")" + kRoot + R"(/parts/cuboid.json", "dimensions": {"size_x": 12.5}},
      "shots": {
        "base_pose": {"rotation_deg": [10, 20, 0], "translation_mm": [-15, 0, 500]},
        "translations": {"count": 3, "distance_mm": 7.5, "axis": [1, 0.1, 0.2]},
        "rotations": {"angles_deg": [0, 40], "axis": [0, 1, 0], "angle_jitter_deg": 0.5,
                      "wobble_deg": 0.3}})" + extra + R"(})";
    const fs::path path = dir_ / ("recipe" + std::to_string(seed) + ".json");
    std::ofstream(path) << text;
    return path.string();
  }

  static std::string bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
  }

  fs::path dir_;
};

TEST_F(Dataset, TruthHoldsExactTranslationsAndEveryShot) {
  const Recipe r = Recipe::load(recipe(1));
  const DatasetReport report = simulateDataset(r, dir_ / "out");
  EXPECT_EQ(report.shots, 5);
  for (const char* file : {"t00.tif", "t01.tif", "t02.tif", "r00.tif", "r01.tif", "dark.tif", "flat.tif"})
    EXPECT_TRUE(fs::exists(dir_ / "out" / file)) << file;
  std::ifstream in(dir_ / "out" / "truth.json");
  const auto truth = nlohmann::json::parse(in);
  const auto& shots = truth["shots"];
  ASSERT_EQ(shots.size(), 5u);
  auto translation = [&](size_t i) {
    const auto m = shots[i]["pose"]["matrix"];
    return Vec3(m[3].get<double>(), m[7].get<double>(), m[11].get<double>());
  };
  for (size_t i = 1; i < 3; ++i) {
    EXPECT_EQ(shots[i]["pattern"], "translated");
    EXPECT_EQ(shots[i]["reference"], "t00");
    EXPECT_NEAR((translation(i) - translation(0)).norm(), 7.5 * static_cast<double>(i), 1e-9);
    EXPECT_NEAR(shots[i]["distance_mm"].get<double>(), 7.5 * static_cast<double>(i), 1e-12);
    // Same rotation as the reference.
    for (int k : {0, 1, 2, 4, 5, 6, 8, 9, 10})
      EXPECT_EQ(shots[i]["pose"]["matrix"][k], shots[0]["pose"]["matrix"][k]);
  }
  EXPECT_EQ(truth["part"]["dimensions"]["size_x"], 12.5);
  EXPECT_EQ(truth["part"]["dimensions"]["size_y"], 30.0);  // nominal
  // The raw shot is 16-bit data in the right range, darker behind the part.
  const Image raw = readTiff(dir_ / "out" / "t01.tif");
  EXPECT_EQ(raw.width(), 160);
  const auto range = finiteRange(raw);
  ASSERT_TRUE(range);
  EXPECT_GT(range->max, 40000.0f);
  EXPECT_LT(range->min, 35000.0f);
  // The transmission table starts at 1 and falls.
  const auto& t = truth["transmission"]["transmission"];
  EXPECT_EQ(t[0].get<double>(), 1.0);
  EXPECT_LT(t[100].get<double>(), t[10].get<double>());
}

TEST_F(Dataset, SameSeedSameBytesAtAnyThreadCount) {
  const Recipe r = Recipe::load(recipe(7));
  {
    ThreadLimit one(1);
    simulateDataset(r, dir_ / "one");
  }
  {
    ThreadLimit two(2);
    simulateDataset(r, dir_ / "two");
  }
  for (const char* file : {"t00.tif", "t02.tif", "r01.tif", "dark.tif", "flat.tif", "truth.json"}) {
    const std::string a = bytes(dir_ / "one" / file), b = bytes(dir_ / "two" / file);
    EXPECT_FALSE(a.empty());
    EXPECT_TRUE(a == b) << file << " differs between 1 and 2 threads";
  }
  // A different seed changes the noise (and the stage errors).
  simulateDataset(Recipe::load(recipe(8)), dir_ / "other");
  EXPECT_NE(bytes(dir_ / "one" / "t00.tif"), bytes(dir_ / "other" / "t00.tif"));
}

TEST_F(Dataset, NormalizedOpenBeamSpreadsLikeTheThesis) {
  const Recipe r = Recipe::load(recipe(3));
  const DatasetReport report = simulateDataset(r, dir_ / "out");
  const Image raw = readTiff(dir_ / "out" / "t00.tif");
  const Image dark = readTiff(dir_ / "out" / "dark.tif");
  const Image flat = readTiff(dir_ / "out" / "flat.tif");
  // Flat-field correct the white region (dead pixels, where flat == dark, left out).
  const PixelRect w = report.white_region;
  std::vector<float> values;
  for (int y = w.y; y < w.bottom(); ++y)
    for (int x = w.x; x < w.right(); ++x)
      if (flat(x, y) > dark(x, y) + 1.0f) values.push_back((raw(x, y) - dark(x, y)) / (flat(x, y) - dark(x, y)));
  ASSERT_GT(values.size(), 200u);
  double mean = 0.0;
  for (float v : values) mean += static_cast<double>(v);
  mean /= static_cast<double>(values.size());
  std::sort(values.begin(), values.end());
  const double low = static_cast<double>(values[values.size() / 200]) / mean;  // 0.5th percentile
  const double high = static_cast<double>(values[values.size() * 199 / 200]) / mean;
  // Photon noise of 40,000 photons per pixel: sigma ~ 0.5 %; 2.6 sigma ~ 1.3 %.
  EXPECT_GT(low, 0.975);
  EXPECT_LT(low, 0.995);
  EXPECT_GT(high, 1.005);
  EXPECT_LT(high, 1.025);
}

TEST_F(Dataset, EdgePixelsAreSampledFinerAndOnlyThey) {
  // The same seed with and without the edge refinement. The photon noise is
  // drawn row by row from one stream per row, so a row's pixels stay
  // identical up to the first pixel whose mean the refinement changed: that
  // must be on the part's silhouette (or its edges inside), never in the open
  // beam before it, and rows away from the shadow stay identical.
  simulateDataset(Recipe::load(recipe(4)), dir_ / "refined");
  simulateDataset(Recipe::load(recipe(4, "", R"(, "edge_samples": 0)")), dir_ / "plain");
  const Image refined = readTiff(dir_ / "refined" / "t00.tif");
  const Image plain = readTiff(dir_ / "plain" / "t00.tif");
  const Image flat = readTiff(dir_ / "plain" / "flat.tif");
  const int h = plain.height(), w = plain.width();
  std::vector<int> first_shadow(h, w), first_differ(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = w - 1; x >= 0; --x) {
      if (plain(x, y) < 0.9f * flat(x, y)) first_shadow[y] = x;
      if (refined(x, y) != plain(x, y)) first_differ[y] = x;
    }
  int rows_changed = 0;
  for (int y = 0; y < h; ++y) {
    int near_shadow = w;  // the first shadow pixel within 2 rows
    for (int k = std::max(0, y - 2); k <= std::min(h - 1, y + 2); ++k)
      near_shadow = std::min(near_shadow, first_shadow[k]);
    if (first_differ[y] == w) continue;
    ++rows_changed;
    ASSERT_LT(near_shadow, w) << "row " << y << " changed away from the part's shadow";
    EXPECT_GE(first_differ[y], near_shadow - 3) << "row " << y << " changed in the open beam";
  }
  EXPECT_GT(rows_changed, 20);
  EXPECT_EQ(bytes(dir_ / "refined" / "flat.tif"), bytes(dir_ / "plain" / "flat.tif"));
}

TEST_F(Dataset, RotationsTurnAboutThePivot) {
  const std::string path = recipe(5);
  const Recipe r = Recipe::load(path);
  // r00 (0 degrees plus jitter and wobble) stays close to its base pose;
  // r01 turns by about 40 degrees about the vertical axis.
  const ShotPlan& r1 = r.shots[4];
  EXPECT_EQ(r1.name, "r01");
  const double angle = Eigen::AngleAxisd(r1.pose.rotation * r.shots[3].pose.rotation.transpose()).angle();
  EXPECT_NEAR(angle * kRadToDeg, 40.0, 3.0);
  // The pivot (the cuboid's centre, its part origin) keeps its world position up to the wobble.
  EXPECT_LT((r1.pose.translation_mm - r.shots[3].pose.translation_mm).norm(), 1.0);
}

TEST_F(Dataset, BadRecipesNameTheKey) {
  auto expect = [&](const std::string& extra, const std::string& message) {
    try {
      const Recipe r = Recipe::load(recipe(9, extra));
      simulateDataset(r, dir_ / "bad");
      FAIL() << "expected an error for " << extra;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir_ / "bad" / "truth.json"));
  };
  expect(R"(, "white_region": [150, 0, 64, 64])", "outside the 160x120 detector");
  expect(R"(, "whit_region": [0, 0, 8, 8])", "unknown key 'whit_region'");
  try {
    simulateDataset(Recipe::load(recipe(9, "", R"(, "edge_samples": 2)")), dir_ / "bad");
    FAIL() << "edge samples not above the area samples accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("edge_samples"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("more than area_samples (2)"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir_ / "bad" / "truth.json"));
  try {
    Recipe::load(dir_ / "missing.json");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.json"), std::string::npos);
  }
}

}  // namespace
}  // namespace xgauge
