// `xgauge characterize` end to end on a small detector simulated here: raw
// 16-bit dark and flat series, an edge shot, a crosstalk shot and a lag
// pair, with a known halo, lag, crosstalk and bad pixels; then a machine
// naming the detector file it wrote.
#include "cli_support.h"

#include "xgauge/image/scatter.h"
#include "xgauge/image/tiff.h"
#include "xgauge/xray/detector_file.h"
#include "xgauge/xray/machine.h"

#include <nlohmann/json.hpp>

#include <fstream>
#include <random>

namespace xgauge {
namespace {

constexpr int kWidth = 192, kHeight = 160;
constexpr double kPitch = 0.5, kWeight = 0.12, kSigma = 10.0, kLag = 0.005, kCrosstalk = 0.004;
constexpr double kDark = 1000.0, kGain = 20000.0;

class Characterize : public Cli {
 protected:
  // A raw frame: dark + gain (signal + c column mean), noise, dead and hot
  // pixels, 16 bits.
  std::string frame(const std::string& name, const Image& signal, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    Image raw(kWidth, kHeight);
    for (int x = 0; x < kWidth; ++x) {
      double mean = 0.0;
      for (int y = 0; y < kHeight; ++y) mean += static_cast<double>(signal(x, y));
      mean /= kHeight;
      for (int y = 0; y < kHeight; ++y) {
        const double s = static_cast<double>(signal(x, y)) + kCrosstalk * mean;
        const double gain = x == 40 && y == 30 ? 0.0 : kGain;              // dead
        const double dark = kDark + (x == 150 && y == 20 ? 8000.0 : 0.0);  // hot
        raw(x, y) = static_cast<float>(dark + gain * s + 4.0 * noise(rng) +
                                       std::sqrt(gain * std::max(s, 0.0) / 2.0) * noise(rng));
      }
    }
    writeTiff(out(name), raw, TiffFormat::kUInt16);
    return name;
  }
  static Image plate(int x0, int x1, int y0, int y1) {
    Image t(kWidth, kHeight, 1.0f);
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) t(x, y) = 0.0f;
    return t;
  }
};

TEST_F(Characterize, MeasuresTheDetectorAndAMachineNamesIt) {
  ScatterModel halo;
  halo.weight = kWeight, halo.sigma_mm = kSigma, halo.border = HaloBorder::kOpen;
  const Image open(kWidth, kHeight, 1.0f), none(kWidth, kHeight, 0.0f);
  for (int k = 0; k < 4; ++k)
    frame(fmt::format("dark_{}.tif", k), none, 10 + static_cast<uint64_t>(k));
  for (int k = 0; k < 4; ++k)
    frame(fmt::format("flat_{}.tif", k), open, 20 + static_cast<uint64_t>(k));
  frame("edge.tif", halo.apply(plate(15, 95, 12, 148), kPitch, 1.0f), 30);
  frame("crosstalk.tif", halo.apply(plate(10, 96, 8, 80), kPitch, 1.0f), 31);
  frame("bright.tif", open, 32);
  Image after(kWidth, kHeight, static_cast<float>(kLag));
  frame("after.tif", after, 33);
  write("machine.json", R"({"source_detector_distance_mm": 1000,
    "detector": {"columns": 192, "rows": 160, "pixel_pitch_mm": [0.5, 0.5]}})");
  const std::string job = write("job.json", R"({"machine": "machine.json",
    "darks": "dark_*.tif", "flats": ["flat_0.tif", "flat_1.tif", "flat_2.tif", "flat_3.tif"],
    "shots": {"edge": "edge.tif", "crosstalk": "crosstalk.tif",
              "lag": {"bright": "bright.tif", "after": "after.tif"}}})");
  const CommandResult r = run("characterize " + job + " -o " + out("char"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("halo: gaussian kernel, open border"), std::string::npos) << r.output;
  const auto d = nlohmann::json::parse(std::ifstream(out("char/detector.json")));
  const auto& s = d["halo"]["scatter"];
  EXPECT_NEAR(s["weight"].get<double>(), kWeight, 0.05 * kWeight) << r.output;
  EXPECT_NEAR(s["sigma_mm"].get<double>(), kSigma, 0.05 * kSigma) << r.output;
  EXPECT_NEAR(d["lag_fraction"]["value"].get<double>(), kLag, 3e-4) << r.output;
  EXPECT_NEAR(d["crosstalk"]["value"].get<double>(), kCrosstalk, 1.5e-3) << r.output;
  EXPECT_EQ(d["bad_pixels"]["dead"], 1);
  EXPECT_EQ(d["bad_pixels"]["hot"], 1);
  EXPECT_EQ(d["inputs"].size(), 12u);  // 4 darks, 4 flats, 4 shots
  const auto bad = nlohmann::json::parse(std::ifstream(out("char/bad_pixels.json")));
  EXPECT_EQ(bad["dead"][0], nlohmann::json({40, 30}));
  EXPECT_EQ(bad["hot"][0], nlohmann::json({150, 20}));

  // A machine naming it: its lag, and its halo for jobs without a scatter.
  const std::string machine =
      write("machine_characterized.json", R"({"source_detector_distance_mm": 1000,
    "detector": {"columns": 192, "rows": 160, "pixel_pitch_mm": [0.5, 0.5],
                 "characterization": "char/detector.json"}})");
  const Machine m = Machine::load(machine);
  EXPECT_NEAR(m.lag_fraction, d["lag_fraction"]["value"].get<double>(), 1e-12);
  const auto file = detectorFileOf(machine);
  ASSERT_TRUE(file && file->halo);
  EXPECT_EQ(file->halo->border, HaloBorder::kOpen);
  EXPECT_NEAR(file->halo->weight, s["weight"].get<double>(), 1e-12);
}

TEST_F(Characterize, AStepThatCannotDecideFailsWithoutOutput) {
  const Image open(kWidth, kHeight, 1.0f), none(kWidth, kHeight, 0.0f);
  frame("dark.tif", none, 1), frame("dark2.tif", none, 2), frame("flat.tif", open, 3);
  frame("edge.tif", open, 4);  // no plate
  write("machine.json", R"({"source_detector_distance_mm": 1000,
    "detector": {"columns": 192, "rows": 160, "pixel_pitch_mm": [0.5, 0.5]}})");
  const std::string job = write("job.json", R"({"machine": "machine.json",
    "darks": ["dark.tif", "dark2.tif"], "flats": "flat.tif", "shots": {"edge": "edge.tif"}})");
  const CommandResult r = run("characterize " + job + " -o " + out("char"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("characterize, edge"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out("char/detector.json")));
  // A misspelled key names itself.
  const std::string bad = write("bad.json", R"({"machine": "machine.json", "darks": "dark.tif",
    "flats": "flat.tif", "shots": {"egde": "edge.tif"}})");
  const CommandResult m = run("characterize " + bad + " -o " + out("char2"));
  EXPECT_EQ(m.status, 1) << m.output;
  EXPECT_NE(m.output.find("egde"), std::string::npos) << m.output;
}

// The replica lab's characterisation session (`"characterization"` in a
// recipe, lab/characterization.h): xgauge characterize reads the job it
// writes and finds the halo, lag and column darkening the frames were made
// with, the halo with the mirror border the replica's blur has.
TEST_F(Characterize, TheReplicaLabsSessionGivesBackItsDetector) {
  auto recipe = nlohmann::json::parse(std::ifstream(kRoot + "/tests/data/report_cuboid.json"));
  recipe["machine"] = kRoot + "/tests/data/report_machine.json";
  recipe["part"]["model"] = kRoot + "/parts/cuboid.json";
  recipe["detector"]["scatter"] = {{"weight", 0.12}, {"sigma_px", 25.0}};
  recipe["detector"]["noise"]["ghost_fraction"] = 0.004;
  recipe["characterization"] = {{"frames", 4}};
  const std::string file = write("recipe.json", recipe.dump(2));
  const CommandResult sim = run("simulate " + file + " -o " + out("data") + " --quiet");
  ASSERT_EQ(sim.status, 0) << sim.output;
  const auto truth = nlohmann::json::parse(std::ifstream(out("data/truth.json")));
  ASSERT_EQ(truth["characterization"]["job"], "characterization/characterize.json");
  EXPECT_TRUE(fs::exists(out("data/characterization/darks/dark_003.tif")));
  const CommandResult r =
      run("characterize " + out("data/characterization/characterize.json") + " -o " + out("det"));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto d = nlohmann::json::parse(std::ifstream(out("det/detector.json")));
  const auto& s = d["halo"]["scatter"];
  EXPECT_EQ(s["border"], "mirror") << r.output;
  EXPECT_NEAR(s["weight"].get<double>(), 0.12, 0.01 * 0.12) << r.output;
  EXPECT_NEAR(s["sigma_mm"].get<double>(), 25.0 * 0.4, 0.03 * 25.0 * 0.4) << r.output;
  EXPECT_NEAR(d["lag_fraction"]["value"].get<double>(), 0.004, 1e-4) << r.output;
  EXPECT_LT(d["crosstalk"]["value"].get<double>(),
            3.0 * d["crosstalk"]["uncertainty"].get<double>() + 1e-12);
}

}  // namespace
}  // namespace xgauge
