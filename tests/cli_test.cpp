// `xgauge render` end to end: outputs that can be checked in closed form, and
// bad input of every kind giving a clear message, a non-zero exit status and
// no output file.
#include "cli_support.h"

#include "xgauge/image/blur.h"
#include "xgauge/image/tiff.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tiffio.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace xgauge {
namespace {

const char* kMachine = R"({"source_detector_distance_mm": 1000,
  "detector": {"columns": 128, "rows": 96, "pixel_pitch_mm": [0.5, 0.5]}})";

TEST_F(Cli, PathLengthOfACuboidFacingTheSource) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r = run("render " + kRoot + "/parts/cuboid.json --machine " + machine +
                              " --quantity path --rotation-deg 0 0 0 --translation-mm 0 0 400"
                              " --set size_z=12.5 -o " +
                              out("path.tif") + " --png " + out("path.png") + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  const Image path = readTiff(out("path.tif"));
  ASSERT_EQ(path.width(), 128);
  ASSERT_EQ(path.height(), 96);
  // The central ray runs along z: path = size_z exactly (float TIFF).
  const double centre = static_cast<double>(path(64, 48));
  EXPECT_NEAR(centre, 12.5 * std::hypot(0.25, 0.25, 1000.0) / 1000.0, 1e-5);
  EXPECT_EQ(path(0, 0), 0.0f);
  EXPECT_TRUE(fs::exists(out("path.png")));
}

// docs/formats.md's CSG example: an STL block minus a drilled hole whose
// position is a dimension. Face-on, a ray through the hole crosses nothing;
// one beside it crosses the block's 10 mm.
TEST_F(Cli, StlBlockWithADrilledHole) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r = run("render " + kRoot + "/examples/stl_with_hole.json --machine " +
                              machine +
                              " --quantity path --rotation-deg 0 0 0 --translation-mm 0 0 400"
                              " --set bore_x=3 -o " + out("path.tif") + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  const Image path = readTiff(out("path.tif"));
  // Pixel (74, 48): x = 5.25 mm on the detector, part x 3.12 to 3.18 mm
  // along the ray inside the block: within the hole (radius 3 about x = 3).
  EXPECT_EQ(path(74, 48), 0.0f);
  // Pixel (58, 48): part x about -1.7 mm, solid block.
  const double u = (58.5 - 64.0) * 0.5, v = (48.0 - 48.5) * 0.5;
  EXPECT_NEAR(static_cast<double>(path(58, 48)), 10.0 * std::hypot(u, v, 1000.0) / 1000.0, 1e-5);
  // Without the hole moved there, the same pixel sees the block.
  const CommandResult moved = run("render " + kRoot + "/examples/stl_with_hole.json --machine " +
                                  machine +
                                  " --quantity path --rotation-deg 0 0 0 --translation-mm 0 0 400"
                                  " --set bore_x=-3 -o " + out("moved.tif") + " -q");
  ASSERT_EQ(moved.status, 0) << moved.output;
  EXPECT_GT(readTiff(out("moved.tif"))(74, 48), 9.9f);
}

TEST_F(Cli, Intensity16BitIsScaledTransmission) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r = run(renderArgs(kRoot + "/parts/cuboid.json", machine, "--format u16 -q"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Image image = readTiff(out("out.tif"));
  EXPECT_EQ(image(0, 0), 65535.0f);  // open beam
  EXPECT_LT(image(64, 48), 65535.0f * 0.6f);
  EXPECT_GT(image(64, 48), 0.0f);
}

TEST_F(Cli, UnknownDimension) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "--set widht=3")),
                     "unknown dimension 'widht'");
}

TEST_F(Cli, ValueOutOfBounds) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "--set size_x=1e6")),
                     "size_x");
}

TEST_F(Cli, NotANumber) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "--set size_x=nan")),
                     "not a finite number");
}

TEST_F(Cli, MissingPartFile) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(out("nope.json"), machine, "")), "nope.json");
}

TEST_F(Cli, MalformedMachineJson) {
  const std::string machine =
      write("machine.json", "{\n  \"source_detector_distance_mm\": 1000,\n  \"detector\": {\n}");
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "")), "machine.json:4");
}

TEST_F(Cli, MisspelledMachineKey) {
  const std::string machine = write("machine.json", R"({"source_detector_distance_mm": 1000,
    "detector": {"columns": 128, "rows": 96, "pixel_pitch_mm": [0.5, 0.5], "principle_point_px": [1, 2]}})");
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "")),
                     "unknown key 'principle_point_px'");
}

// A machine whose "detector" is spelled "detektor": the unknown key is named
// (with the line), not "missing key 'detector'".
TEST_F(Cli, AMisspelledRequiredKeyIsNamedAsUnknown) {
  const std::string machine = write("machine.json", R"({"source_detector_distance_mm": 1000,
    "detektor": {"columns": 128, "rows": 96, "pixel_pitch_mm": [0.5, 0.5]}})");
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "")),
                     "machine.json:2: /detektor: unknown key 'detektor'; did you mean 'detector'?");
}

// An unknown command is named, with the nearest known one, and fails; also
// with --help after it.
TEST_F(Cli, AnUnknownCommandIsNamedWithTheNearestOne) {
  for (const char* args : {"nonsense", "nonsense --help", "-q mesure job.json"}) {
    const auto r = run(args);
    EXPECT_NE(r.status, 0) << args << ": " << r.output;
    const std::string word = std::string(args).find("mesure") != std::string::npos ? "mesure" : "nonsense";
    EXPECT_NE(r.output.find("unknown command '" + word + "'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("commands: render,"), std::string::npos) << r.output;
  }
  EXPECT_NE(run("mesure job.json").output.find("did you mean 'measure'?"), std::string::npos);
  EXPECT_NE(run("inpsect").output.find("did you mean 'inspect'?"), std::string::npos);
  EXPECT_EQ(run("--help").status, 0);  // the help itself still works
}

TEST_F(Cli, OpenMesh) {
  const std::string machine = write("machine.json", kMachine);
  const std::string part = write("open.json", R"({
    "description": "a tetrahedron missing one face",
    "dimensions": [{"name": "s", "nominal": 10, "min": 1, "max": 20, "unit": "mm"}],
    "shape": {"type": "mesh",
      "vertices": [["0","0","0"], ["s","0","0"], ["0","s","0"], ["0","0","s"]],
      "triangles": [[0,2,1], [0,1,3], [1,2,3]]}})");
  expectCleanFailure(run(renderArgs(part, machine, "")), "open.json");
}

TEST_F(Cli, PartBehindTheSource) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r =
      run("render " + kRoot + "/parts/cuboid.json --machine " + machine +
          " --quantity path --rotation-deg 0 0 0 --translation-mm 0 0 1200 -o " + out("out.tif"));
  expectCleanFailure(r, "check the pose");
}

TEST_F(Cli, RegionOutsideTheDetector) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "--region 100 0 64 64")),
                     "outside the 128x96 detector");
}

TEST_F(Cli, EdgeSamplesNotAboveTheSamples) {
  const std::string machine = write("machine.json", kMachine);
  expectCleanFailure(run(renderArgs(kRoot + "/parts/cuboid.json", machine, "-n 4 --edge-samples 4")),
                     "edge samples per pixel axis must be 0 or from 5 to 32, got 4");
}

TEST_F(Cli, MissingMaterialForIntensity) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r =
      run("render " + kRoot + "/parts/cuboid.json --machine " + machine +
          " --rotation-deg 0 0 0 --translation-mm 0 0 400 -o " + out("out.tif"));
  expectCleanFailure(r, "--material");
}

// The derivative images of a part model against central differences: a
// table row per dimension and pose parameter, exit 0; a tolerance nothing
// can meet fails with exit 4 and says so.
TEST_F(Cli, CheckGradientsOfAPartModel) {
  const std::string machine = write("machine.json", kMachine);
  const std::string args = "check-gradients " + kRoot + "/parts/prism_jaw.json --machine " +
                           machine + " --material " + kRoot +
                           "/examples/aluminium_60kev.json --rotation-deg 10 25 -5"
                           " --translation-mm -2 1 400 -n 2";
  const CommandResult r = run(args);
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* row : {"width ", "slot_depth ", "rx ", "z "})
    EXPECT_NE(r.output.find(row), std::string::npos) << row << "\n" << r.output;
  EXPECT_EQ(r.output.find("DISAGREES"), std::string::npos) << r.output;
  const CommandResult strict = run(args + " --tolerance 0");
  EXPECT_EQ(strict.status, 4) << strict.output;
  EXPECT_NE(strict.output.find("DISAGREES"), std::string::npos) << strict.output;
  // A pose outside the beam is an error, not a check.
  expectCleanFailure(run("check-gradients " + kRoot + "/parts/cuboid.json --machine " + machine +
                         " --material " + kRoot +
                         "/examples/aluminium_60kev.json --rotation-deg 0 0 0 "
                         "--translation-mm 0 0 1200"),
                     "check the pose");
}

TEST_F(Cli, OutputFolderMissing) {
  const std::string machine = write("machine.json", kMachine);
  const CommandResult r = run("render " + kRoot + "/parts/cuboid.json --machine " + machine +
                              " --quantity path --rotation-deg 0 0 0 --translation-mm 0 0 400 -o " +
                              out("no/such/folder/out.tif"));
  expectCleanFailure(r, "does not exist");
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

TEST_F(Cli, NormalizeFlatFieldAndWhiteRegion) {
  // raw = dark + gain * 0.5 * open beam, with one dead pixel.
  Image dark(32, 24, 4000.0f), flat(32, 24, 0.0f), raw(32, 24, 0.0f);
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      const float gain = 1.0f + 0.01f * static_cast<float>(x);
      flat(x, y) = 4000.0f + 40000.0f * gain;
      raw(x, y) = 4000.0f + 40000.0f * gain * (x < 16 ? 1.0f : 0.5f);
    }
  flat(20, 10) = dark(20, 10);
  writeTiff(out("dark.tif"), dark, TiffFormat::kFloat32);
  writeTiff(out("flat.tif"), flat, TiffFormat::kFloat32);
  writeTiff(out("raw.tif"), raw, TiffFormat::kFloat32);
  const CommandResult r = run("normalize " + out("raw.tif") + " --dark " + out("dark.tif") +
                              " --flat " + out("flat.tif") + " --white 0 0 8 8 -o " + out("n.tif"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("1 bad pixels repaired"), std::string::npos) << r.output;
  const Image n = readTiff(out("n.tif"));
  EXPECT_FLOAT_EQ(n(3, 3), 1.0f);
  EXPECT_NEAR(n(25, 5), 0.5f, 1e-6);
  EXPECT_NEAR(n(20, 10), 0.5f, 1e-6);  // the dead pixel, repaired
}

TEST_F(Cli, NormalizeRejectsMismatchedFrames) {
  writeTiff(out("raw.tif"), Image(32, 24, 1.0f), TiffFormat::kFloat32);
  writeTiff(out("dark.tif"), Image(16, 24, 0.0f), TiffFormat::kFloat32);
  writeTiff(out("flat.tif"), Image(32, 24, 2.0f), TiffFormat::kFloat32);
  const CommandResult r = run("normalize " + out("raw.tif") + " --dark " + out("dark.tif") +
                              " --flat " + out("flat.tif") + " -o " + out("n.tif"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("16x24"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out("n.tif")));
  const CommandResult none = run("normalize " + out("raw.tif") + " -o " + out("n.tif"));
  EXPECT_NE(none.status, 0);
  EXPECT_FALSE(fs::exists(out("n.tif")));
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// A small valid measurement job, for the bad-input tests to break one piece of.
class MeasureJob : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    write("machine.json", kMachine);
    write("material.json",
          R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.05}]})");
    Image image(128, 96, 1.0f);
    for (int y = 30; y < 60; ++y)
      for (int x = 40; x < 90; ++x) image(x, y) = 0.6f;
    writeTiff(out("a.tif"), image, TiffFormat::kFloat32);
  }
  std::string job(const std::string& radiograph_extra = "", const std::string& top_extra = "",
                  const std::string& image = "a.tif") {
    return write("job.json", R"({
      "part": ")" + kRoot + R"(/parts/cuboid.json",
      "machine": "machine.json", "material": "material.json",
      "radiographs": [{"name": "a", "image": ")" +
                                 image + R"(", "white_region": [0, 0, 16, 16])" + radiograph_extra +
                                 R"(}],
      "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                      "centre_mm": [[-10, 10], [-10, 10], [390, 410]]})" +
                                 top_extra + "}");
  }
  // A radiograph of a 20 x 30 x 10 mm cuboid, turned a little, 400 mm from
  // the detector, in place of the fixture's a.tif, with Gaussian noise of
  // sigma `noise` as a detector's (noise-free, the residual regions'
  // threshold, robust sigmas of the residual itself, finds the small
  // differences between this render's sampling and the fit's at every edge).
  void renderCuboid(double noise, uint64_t seed = 7) {
    const CommandResult rendered =
        run("render " + kRoot + "/parts/cuboid.json --machine " + out("machine.json") +
            " --material " + out("material.json") +
            " --rotation-deg 1 -2 0.5 --translation-mm 1 -2 400 --set size_x=20 --set size_y=30"
            " --set size_z=10 -n 3 --format f32 -o " +
            out("a.tif"));
    ASSERT_EQ(rendered.status, 0) << rendered.output;
    Image image = readTiff(out("a.tif"));
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> gauss(0.0, noise);
    for (int y = 0; y < image.height(); ++y)
      for (int x = 0; x < image.width(); ++x)
        image(x, y) = static_cast<float>(static_cast<double>(image(x, y)) + gauss(rng));
    writeTiff(out("a.tif"), image, TiffFormat::kFloat32);
  }
  void expectJobFailure(const std::string& job_file, const std::string& message) {
    const CommandResult r = run("measure " + job_file + " -o " + out("result") + " -q");
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n"
                                                         << r.output;
    EXPECT_FALSE(fs::exists(out("result") + "/result.json"));
  }
};

TEST_F(MeasureJob, MissingImage) { expectJobFailure(job("", "", "nope.tif"), "nope.tif"); }

TEST_F(MeasureJob, ImageSizeDoesNotMatchTheMachine) {
  writeTiff(out("small.tif"), Image(64, 48, 1.0f), TiffFormat::kFloat32);
  expectJobFailure(job("", "", "small.tif"),
                   "is 64x48 pixels but the machine's detector is 128x96");
}

TEST_F(MeasureJob, RegionOutsideTheImage) {
  expectJobFailure(job(R"(, "roi": [100, 50, 64, 64])"), "roi");
}

TEST_F(MeasureJob, UnknownKey) {
  expectJobFailure(job("", R"(, "schedul": "default")"),
                   "unknown key 'schedul'; did you mean 'schedule'?");
}

TEST_F(MeasureJob, TranslationUncertaintyOnAFreeRadiograph) {
  // Only a translated radiograph has a distance, and so its uncertainty.
  expectJobFailure(job(R"(, "distance_uncertainty_mm": 0.01)"), "distance_uncertainty_mm");
}

TEST_F(MeasureJob, StartOutsideBounds) {
  expectJobFailure(job("", R"(, "dimensions": {"start": {"size_x": 99}})"), "outside the bounds");
}

TEST_F(MeasureJob, NanPixels) {
  // xgauge's writeTiff refuses NaN, so write the file with libtiff directly.
  TIFF* tiff = TIFFOpen(out("nan.tif").c_str(), "w");
  ASSERT_NE(tiff, nullptr);
  TIFFSetField(tiff, TIFFTAG_IMAGEWIDTH, 128);
  TIFFSetField(tiff, TIFFTAG_IMAGELENGTH, 96);
  TIFFSetField(tiff, TIFFTAG_SAMPLESPERPIXEL, 1);
  TIFFSetField(tiff, TIFFTAG_BITSPERSAMPLE, 32);
  TIFFSetField(tiff, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP);
  TIFFSetField(tiff, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tiff, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  std::vector<float> row(128, 1.0f);
  for (uint32_t y = 0; y < 96; ++y) {
    row[7] = y == 5 ? std::numeric_limits<float>::quiet_NaN() : 1.0f;
    ASSERT_EQ(TIFFWriteScanline(tiff, row.data(), y, 0), 1);
  }
  TIFFClose(tiff);
  expectJobFailure(job("", "", "nan.tif"), "pixel (7, 5) is nan");
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// `xgauge calibrate wedge` on a synthetic wedge radiograph: the ramp from
// row 40 (thin end) to row 260 (thick end) in columns 50..149, open beam
// around it. Bad input must fail with a clear message and leave no material.
class CalibrateWedge : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    write("machine.json", R"({"source_detector_distance_mm": 1000,
      "detector": {"columns": 200, "rows": 300, "pixel_pitch_mm": [1.0, 1.0]}})");
    writeTiff(out("wedge.tif"), ramp(40, 260), TiffFormat::kFloat32);
  }
  static Image ramp(int thin, int thick) {
    Image image(200, 300, 1.0f);
    for (int y = std::max(0, thin); y < std::min(300, thick); ++y)
      for (int x = 50; x < 150; ++x) {
        const double path = 0.2 + 19.8 * (y + 0.5 - thin) / (thick - thin);
        image(x, y) =
            static_cast<float>(0.6 * std::exp(-0.05 * path) + 0.4 * std::exp(-0.3 * path));
      }
    return image;
  }
  std::string job(const std::string& extra = "", const std::string& image = "wedge.tif") {
    return write("job.json", R"({"machine": "machine.json",
      "radiograph": {"image": ")" +
                                 image + R"(", "white_region": [5, 5, 30, 30]},
      "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0})" +
                                 extra + "}");
  }
  CommandResult calibrate(const std::string& job_file) {
    return run("calibrate wedge " + job_file + " -o " + out("cal") + " -q");
  }
  void expectFailure(const std::string& job_file, const std::string& message) {
    const CommandResult r = calibrate(job_file);
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n"
                                                         << r.output;
    EXPECT_FALSE(fs::exists(out("cal") + "/material.json"));
  }
};

TEST_F(CalibrateWedge, WritesTheMaterialFiguresAndPlot) {
  const CommandResult r = calibrate(job());
  ASSERT_EQ(r.status, 0) << r.output;
  const size_t at = r.output.find("thin end at row ");
  ASSERT_NE(at, std::string::npos) << r.output;
  EXPECT_NEAR(std::stod(r.output.substr(at + 16)), 40.0, 1.0) << r.output;
  for (const char* file : {"material.json", "calibration.json", "report.html"})
    EXPECT_TRUE(fs::exists(out("cal") + "/" + file)) << file;
  // The shot has no scatter and the halo fit finds none it could not bound:
  // the most an unmeasured halo could change the shadow by counts in the
  // curve's uncertainty.
  std::ifstream in(out("cal") + "/calibration.json");
  const nlohmann::json uncertainty = nlohmann::json::parse(in).at("uncertainty");
  double unmeasured = -1.0;
  for (const auto& influence : uncertainty.at("influences"))
    if (influence.at("name") == "unmeasured scatter halo")
      unmeasured = influence.at("curve_change").get<double>();
  EXPECT_GT(unmeasured, 0.0) << uncertainty.dump();
  EXPECT_LE(unmeasured, 0.0025);
  EXPECT_GE(uncertainty.at("transmission").get<double>(), unmeasured);
}

// With a scatter removed, material.json says how the curve moves with it:
// the curves calibrated with the weight and the width moved by their u
// differ from the curve by the influences calibration.json lists, and the
// uncertainty besides them completes the curve's.
TEST_F(CalibrateWedge, TheMaterialSaysHowItsCurveMovesWithTheScatter) {
  writeTiff(out("scattered.tif"), scatterBlur(ramp(40, 260), 0.08, 20.0), TiffFormat::kFloat32);
  const CommandResult r =
      calibrate(job(R"(, "scatter": {"weight": 0.08, "sigma_mm": 20})", "scattered.tif"));
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json figures = nlohmann::json::parse(std::ifstream(out("cal") + "/calibration.json"));
  const nlohmann::json material = nlohmann::json::parse(std::ifstream(out("cal") + "/material.json"));
  const nlohmann::json& moves = material.at("scatter").at("curve_moves");
  auto curve = [](const nlohmann::json& terms, double x) {
    double sum = 0.0;
    for (const auto& t : terms) sum += t.at("weight").get<double>() * std::exp(-t.at("mu_per_mm").get<double>() * x);
    return sum;
  };
  const double x_max = material.at("calibrated_range_mm")[1].get<double>();
  double scatter_squares = 0.0;
  for (const auto& influence : figures.at("uncertainty").at("influences")) {
    const std::string name = influence.at("name");
    const double change = influence.at("curve_change").get<double>();
    if (name != "scatter weight" && name != "scatter sigma_mm") continue;
    scatter_squares += change * change;
    const nlohmann::json& moved = moves.at(name == "scatter weight" ? "weight_plus_u" : "sigma_mm_plus_u");
    double largest = 0.0;
    for (int i = 0; i <= 2000; ++i) {
      const double x = x_max * i / 2000.0;
      largest = std::max(largest, std::abs(curve(moved.at("terms"), x) - curve(material.at("terms"), x)));
    }
    EXPECT_NEAR(largest, change, 0.02 * change + 1e-6) << name;
    EXPECT_GT(change, 1e-4) << name;
  }
  const double u = material.at("uncertainty").at("transmission").get<double>();
  const double besides = moves.at("transmission_uncertainty_besides").get<double>();
  EXPECT_NEAR(besides * besides + scatter_squares, u * u, 1e-9);
  EXPECT_LT(besides, u);
}

// A shot that records 1 % of the frame before it (the wedge 30 rows lower,
// its sides 20 columns apart): named as its previous frame, the lag is
// estimated, subtracted and recorded in calibration.json.
TEST_F(CalibrateWedge, SubtractsTheLagOfItsPreviousFrame) {
  Image before(200, 300, 1.0f);
  const Image shifted = ramp(70, 290);
  for (int y = 0; y < 300; ++y)
    for (int x = 30; x < 170; ++x) before(x, y) = shifted(std::clamp(x - 20 + (x >= 100 ? 40 : 0), 0, 199), y);
  Image now = ramp(40, 260);
  for (int y = 0; y < 300; ++y)
    for (int x = 0; x < 200; ++x) now(x, y) += 0.01f * before(x, y);
  writeTiff(out("now.tif"), now, TiffFormat::kFloat32);
  writeTiff(out("before.tif"), before, TiffFormat::kFloat32);
  const CommandResult r = calibrate(write("job.json", R"({"machine": "machine.json",
      "radiograph": {"image": "now.tif", "previous": "before.tif", "white_region": [5, 5, 30, 30]},
      "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0}})"));
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json lag =
      nlohmann::json::parse(std::ifstream(out("cal") + "/calibration.json")).at("lag");
  EXPECT_EQ(lag.at("source"), "estimated") << lag;
  EXPECT_NEAR(lag.at("fraction").get<double>(), 0.01, 3.0 * lag.at("uncertainty").get<double>()) << lag;
  EXPECT_LT(lag.at("uncertainty").get<double>(), 0.002) << lag;
}

TEST_F(CalibrateWedge, NoRamp) {
  writeTiff(out("open.tif"), Image(200, 300, 1.0f), TiffFormat::kFloat32);
  expectFailure(job("", "open.tif"), "no ramp found");
}

// A failed calibration leaves what its steps found, under names that say
// failure, and nothing that could be taken for a calibration.
TEST_F(CalibrateWedge, AFailureLeavesItsDiagnosticAndNoMaterial) {
  writeTiff(out("open.tif"), Image(200, 300, 1.0f), TiffFormat::kFloat32);
  expectFailure(job("", "open.tif"), "failed at its step \"find the ramp\"");
  std::ifstream in(out("cal") + "/failed_calibration.json");
  ASSERT_TRUE(in.good());
  const nlohmann::json diagnostic = nlohmann::json::parse(in);
  EXPECT_EQ(diagnostic.at("step"), "find the ramp");
  EXPECT_TRUE(diagnostic.at("ramp").is_null());
  EXPECT_NE(diagnostic.at("error").get<std::string>().find("no ramp found"), std::string::npos);
  EXPECT_TRUE(fs::exists(out("cal") + "/failed_calibration.html"));
  for (const char* file : {"material.json", "calibration.json", "report.html"})
    EXPECT_FALSE(fs::exists(out("cal") + "/" + file)) << file;

  // Failing later, at the fit, it also holds the ramp, the table and the fits tried.
  fs::remove_all(out("cal"));
  expectFailure(job(R"(, "ramp": {"rows": [10, 295]})"), "failed at its step \"fit the curve\"");
  std::ifstream fit_in(out("cal") + "/failed_calibration.json");
  const nlohmann::json late = nlohmann::json::parse(fit_in);
  EXPECT_EQ(late.at("ramp").at("thin_end_row"), 10.0);
  EXPECT_GT(late.at("table").at("path_mm").size(), 100u);
  EXPECT_EQ(late.at("fit").at("fits").size(), 4u);

  // A calibration that succeeds into the same folder removes the failure's
  // diagnostic; one that fails there again removes the material it left.
  const CommandResult ok = calibrate(job());
  ASSERT_EQ(ok.status, 0) << ok.output;
  EXPECT_TRUE(fs::exists(out("cal") + "/material.json"));
  for (const char* file : {"failed_calibration.json", "failed_calibration.html"})
    EXPECT_FALSE(fs::exists(out("cal") + "/" + file)) << file;
  expectFailure(job("", "open.tif"), "failed at its step \"find the ramp\"");
  EXPECT_TRUE(fs::exists(out("cal") + "/failed_calibration.json"));
  for (const char* file : {"material.json", "calibration.json", "report.html"})
    EXPECT_FALSE(fs::exists(out("cal") + "/" + file)) << file;
}

TEST_F(CalibrateWedge, RampRunsOffTheImage) {
  writeTiff(out("cut.tif"), ramp(-60, 260), TiffFormat::kFloat32);
  expectFailure(job("", "cut.tif"), "runs off the image");
}

TEST_F(CalibrateWedge, FitDoesNotConverge) {
  // Rows given past both ends of the ramp: open beam at both ends of the table.
  expectFailure(job(R"(, "ramp": {"rows": [10, 295]})"), "does not converge");
}

TEST_F(CalibrateWedge, MisspelledKeyAndMissingFile) {
  expectFailure(job(R"(, "max_term": 3)"), "unknown key 'max_term'");
  expectFailure(job("", "nope.tif"), "nope.tif");
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// `xgauge calibrate part`: bad input fails before anything is written.
class CalibratePart : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    write("machine.json", kMachine);
    Image image(128, 96, 1.0f);
    for (int y = 30; y < 60; ++y)
      for (int x = 40; x < 90; ++x) image(x, y) = 0.6f;
    writeTiff(out("a.tif"), image, TiffFormat::kFloat32);
  }
  std::string job(const std::string& region, const std::string& top_extra = "") {
    return write("job.json", R"({
      "part": ")" + kRoot + R"(/parts/cuboid.json", "machine": "machine.json",
      "dimensions": {"fixed": {"size_x": 20, "size_y": 16, "size_z": 10}},
      "radiographs": [{"name": "a", "image": "a.tif", "white_region": [0, 0, 16, 16]}],
      "pose_bounds": {"rotation_deg": [[-5, 5], [-5, 5], [-5, 5]],
                      "centre_mm": [[-10, 10], [-10, 10], [390, 410]]},
      "calibration": {"initial": {"radiograph": "a", "region": )" +
                                 region + R"(, "path_mm": 10}}
      )" + top_extra + "}");
  }
  void expectFailure(const std::string& job_file, const std::string& message) {
    const CommandResult r = run("calibrate part " + job_file + " -o " + out("cal") + " -q");
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n"
                                                         << r.output;
    EXPECT_FALSE(fs::exists(out("cal") + "/material.json"));
  }
};

TEST_F(CalibratePart, InitialRegionInTheOpenBeam) {
  expectFailure(job("[2, 2, 10, 10]"), "eq. 3.8 needs one in (0, 1)");
  // The failure names its step and leaves its diagnostic, and only that.
  expectFailure(job("[2, 2, 10, 10]"), "failed at its step \"the initial material");
  std::ifstream in(out("cal") + "/failed_calibration.json");
  ASSERT_TRUE(in.good());
  const nlohmann::json diagnostic = nlohmann::json::parse(in);
  EXPECT_EQ(diagnostic.at("kind"), "part");
  EXPECT_EQ(diagnostic.at("step"), "the initial material (thesis eq. 3.8)");
  EXPECT_TRUE(diagnostic.at("rounds").empty());
  EXPECT_TRUE(fs::exists(out("cal") + "/failed_calibration.html"));
  EXPECT_FALSE(fs::exists(out("cal") + "/calibration.json"));
}

TEST_F(CalibratePart, InitialRegionOutsideTheImage) {
  expectFailure(job("[120, 90, 20, 20]"), "lies outside the 128x96 image");
}

TEST_F(CalibratePart, MaterialIsNotAnInput) {
  expectFailure(job("[50, 35, 10, 10]", R"(, "material": "m.json")"), "leave \"material\" out");
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// The exit status tells a line script the verdicts (measure/tolerance.h):
// the same measurement judged against three tolerance zones built around
// its own value and U.
TEST_F(MeasureJob, ExitStatusGivesTheVerdicts) {
  // A radiograph the model explains (the fixture's flat rectangle fits no
  // cuboid, and the U of such a fit is anything from 0.2 to 15 mm).
  renderCuboid(0.005);
  const CommandResult first = run("measure " + job() + " -o " + out("plain") + " -q");
  ASSERT_EQ(first.status, 0) << first.output;
  EXPECT_TRUE(fs::exists(out("plain") + "/report.html"));
  std::ifstream in(out("plain") + "/result.json");
  const nlohmann::json result = nlohmann::json::parse(in);
  const nlohmann::json& size_x = result.at("dimensions").at(0);
  ASSERT_EQ(size_x.at("name"), "size_x");
  ASSERT_TRUE(size_x.at("expanded_uncertainty").is_number()) << size_x.dump();
  const double value = size_x.at("value_mm").get<double>();
  const double u = size_x.at("expanded_uncertainty").get<double>();
  EXPECT_FALSE(size_x.contains("verdict"));  // no tolerance, no verdict
  auto verdict = [&](double nominal, double lower, double upper, const std::string& name) {
    const std::string tolerances = fmt::format(
        R"(, "unverified_verdicts": true,
            "tolerances": {{"size_x": {{"nominal": {}, "lower": {}, "upper": {}}}}})",
        nominal, lower, upper);
    const CommandResult r =
        run("measure " + job("", tolerances) + " -o " + out(name) + " -q --no-report");
    EXPECT_FALSE(fs::exists(out(name) + "/report.html"));
    EXPECT_TRUE(fs::exists(out(name) + "/result.json")) << r.output;
    std::ifstream file(out(name) + "/result.json");
    const nlohmann::json judged = nlohmann::json::parse(file);
    EXPECT_EQ(judged.at("dimensions").at(0).at("value_mm").get<double>(), value);  // deterministic
    EXPECT_TRUE(judged.at("decision_rule").is_string());
    return std::pair{r.status, judged.at("dimensions").at(0).at("verdict").get<std::string>()};
  };
  // Inside the zone shrunk by U: conforms, exit 0.
  EXPECT_EQ(verdict(value, -(2.0 * u + 0.5), 2.0 * u + 0.5, "conforms"),
            (std::pair<int, std::string>{0, "conforms"}));
  // Outside the zone widened by U: does not conform, exit 3.
  ASSERT_LT(u, 1.0);
  EXPECT_EQ(verdict(value + 1.0 + 2.0 * u, -0.5, 0.5, "nonconforming"),
            (std::pair<int, std::string>{3, "does not conform"}));
  // Inside the zone but within U of its upper limit: inconclusive, exit 2.
  EXPECT_EQ(verdict(value, -(2.0 * u + 0.5), 0.5 * u + 1e-6, "inconclusive"),
            (std::pair<int, std::string>{2, "inconclusive"}));
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// A wrong part model is no measurement (measure/self_check.h,
// AcceptanceRule): the cuboid's size_x held 4 mm short of the radiograph's
// leaves residual regions over much of the shadow; the retry fails the same
// way; exit 1, no verdict even with a tolerance, and the fit's values kept
// apart from the results in result.json, with the reasons.
TEST_F(MeasureJob, AWrongPartModelIsNotMeasured) {
  renderCuboid(0.005);
  const std::string extra =
      R"(, "dimensions": {"free": ["size_y", "size_z"], "fixed": {"size_x": 16}},
         "tolerances": {"size_y": {"lower": -1, "upper": 1}},
         "acceptance": {"retries": 1})";
  const CommandResult r = run("measure " + job("", extra) + " -o " + out("wrong") + " -q");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("NOT MEASURED"), std::string::npos) << r.output;
  std::ifstream in(out("wrong") + "/result.json");
  ASSERT_TRUE(in) << r.output;
  const nlohmann::json result = nlohmann::json::parse(in);
  EXPECT_EQ(result.at("status"), "not measured");
  EXPECT_EQ(result.at("attempts"), 2);
  EXPECT_FALSE(result.contains("dimensions"));
  EXPECT_FALSE(result.contains("uncertainty"));
  ASSERT_FALSE(result.at("failures").empty());
  for (const nlohmann::json& d : result.at("rejected_dimensions"))
    EXPECT_FALSE(d.contains("verdict"));
  EXPECT_TRUE(fs::exists(out("wrong") + "/report.html"));

  // The same job with the right size_x measures, and its verdict is given.
  const std::string right =
      R"(, "dimensions": {"free": ["size_y", "size_z"], "fixed": {"size_x": 20}},
         "tolerances": {"size_y": {"lower": -1, "upper": 1}}, "unverified_verdicts": true)";
  const CommandResult good = run("measure " + job("", right) + " -o " + out("right") + " -q");
  EXPECT_EQ(good.status, 0) << good.output;
  std::ifstream in_right(out("right") + "/result.json");
  const nlohmann::json measured = nlohmann::json::parse(in_right);
  EXPECT_EQ(measured.at("status"), "measured");
  EXPECT_TRUE(measured.at("failures").empty());
  EXPECT_EQ(measured.at("dimensions").at(1).at("verdict"), "conforms");
}

// A misspelled key of the acceptance rule is an error, as every key is.
TEST_F(MeasureJob, MisspelledAcceptanceKey) {
  expectJobFailure(job("", R"(, "acceptance": {"max_misfit": 3})"), "max_misfit");
}

}  // namespace
}  // namespace xgauge

namespace xgauge {
namespace {

// The method verified on a master (measure/verification.h): three noisy
// radiographs of the 20 x 30 x 10 mm cuboid, certified at those values,
// give the bias and repeatability; a fourth radiograph measured with the
// verification gets the substitution's U and a verdict; the same job
// without it says its U is unverified and gives no verdict (exit 2); with
// another material the verification is refused, naming why.
TEST_F(MeasureJob, AVerifiedMethodGivesVerdictsAnUnverifiedOneDoesNot) {
  const std::string tolerance = R"("tolerances": {"size_y": {"lower": -2, "upper": 2}})";
  nlohmann::json verify_job = {
      {"master",
       {{"certificate",
         {{"size_x", {{"value", 20.0}, {"standard_uncertainty", 0.001}}},
          {"size_y", {{"value", 30.0}, {"standard_uncertainty", 0.001}}},
          {"size_z", {{"value", 10.0}, {"standard_uncertainty", 0.001}}}}}}},
      {"measurements", nlohmann::json::array()}};
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    renderCuboid(0.005, seed);
    const std::string image = fmt::format("m{}.tif", seed);
    fs::copy_file(out("a.tif"), out(image), fs::copy_options::overwrite_existing);
    const std::string name = fmt::format("m{}.json", seed);
    fs::copy_file(job("", "", image), out(name), fs::copy_options::overwrite_existing);
    verify_job["measurements"].push_back(out(name));
  }
  const CommandResult verified =
      run("verify " + write("verify.json", verify_job.dump()) + " -o " + out("verified") + " -q");
  ASSERT_EQ(verified.status, 0) << verified.output;
  std::ifstream file(out("verified") + "/verification.json");
  const nlohmann::json verification = nlohmann::json::parse(file);
  ASSERT_EQ(verification.at("dimensions").size(), 3u);
  const nlohmann::json& y = verification.at("dimensions").at(1);
  EXPECT_EQ(y.at("name"), "size_y");
  EXPECT_EQ(y.at("measurements"), 3);
  EXPECT_NEAR(y.at("bias").get<double>(), y.at("mean").get<double>() - 30.0, 1e-12);

  renderCuboid(0.005, 11);  // the workpiece
  const CommandResult r =
      run("measure " + job("", R"(, "verification": "verified/verification.json", )" + tolerance) +
          " -o " + out("workpiece") + " -q");
  EXPECT_EQ(r.status, 0) << r.output;
  std::ifstream in(out("workpiece") + "/result.json");
  const nlohmann::json result = nlohmann::json::parse(in);
  const nlohmann::json& d = result.at("dimensions").at(1);
  ASSERT_TRUE(d.at("verified").get<bool>()) << d.dump();
  EXPECT_EQ(d.at("verdict"), "conforms");
  const nlohmann::json& s = d.at("verification");
  EXPECT_NEAR(d.at("value_mm").get<double>(),
              s.at("fitted_value").get<double>() - y.at("bias").get<double>(), 1e-12);
  const double u =
      std::sqrt(std::pow(y.at("u_cal").get<double>(), 2) + std::pow(y.at("u_p").get<double>(), 2) +
                std::pow(y.at("u_b").get<double>(), 2) + std::pow(s.at("u_w").get<double>(), 2));
  // Three measurements of the master: u_p and u_b known to 2 degrees of
  // freedom, k Student's t at Welch-Satterthwaite's nu (above 2 when they
  // dominate).
  const double repeated =
      std::pow(y.at("u_p").get<double>(), 2) + std::pow(y.at("u_b").get<double>(), 2);
  EXPECT_NEAR(s.at("effective_degrees_of_freedom").get<double>(),
              std::pow(u, 4) / (repeated * repeated / 2.0), 1e-9);
  const double k = s.at("coverage_factor").get<double>();
  EXPECT_GT(k, 2.0);
  EXPECT_LE(k, 4.53);
  EXPECT_NEAR(d.at("expanded_uncertainty").get<double>(), k * u, 1e-12);

  const CommandResult unverified =
      run("measure " + job("", ", " + tolerance) + " -o " + out("unverified") + " -q");
  EXPECT_EQ(unverified.status, 2) << unverified.output;
  EXPECT_NE(unverified.output.find("unverified"), std::string::npos) << unverified.output;
  std::ifstream in_unverified(out("unverified") + "/result.json");
  const nlohmann::json plain = nlohmann::json::parse(in_unverified);
  EXPECT_FALSE(plain.at("dimensions").at(1).at("verified").get<bool>());
  EXPECT_FALSE(plain.at("dimensions").at(1).contains("verdict"));

  write("material2.json",
        R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.0500001}]})");
  std::ifstream job_in(job("", R"(, "verification": "verified/verification.json")"));
  nlohmann::json other = nlohmann::json::parse(job_in);
  other["material"] = "material2.json";
  const CommandResult refused =
      run("measure " + write("other.json", other.dump()) + " -o " + out("refused") + " -q");
  EXPECT_EQ(refused.status, 1) << refused.output;
  EXPECT_NE(refused.output.find("another material"), std::string::npos) << refused.output;
  EXPECT_FALSE(fs::exists(out("refused") + "/result.json"));
}

// xgauge part faces and part check on examples/step/bracket.step: the faces
// listed and drawn, the dimensions checked; and bad parts refused naming the
// dimension and the face, exit 1, nothing written.
TEST_F(Cli, PartFacesAndCheckOfTheStepBracket) {
  const CommandResult faces =
      run("part faces " + kRoot + "/examples/step/bracket.step -o " + out("faces") + " -q");
  ASSERT_EQ(faces.status, 0) << faces.output;
  EXPECT_NE(faces.output.find("#973"), std::string::npos) << faces.output;
  EXPECT_TRUE(fs::exists(out("faces") + "/faces.json"));
  EXPECT_GT(fs::file_size(out("faces") + "/faces.html"), 10000u);
  const CommandResult check =
      run("part check " + kRoot + "/examples/step/bracket.json -o " + out("check") + " -q");
  ASSERT_EQ(check.status, 0) << check.output;
  std::ifstream in(out("check") + "/check.json");
  const nlohmann::json json = nlohmann::json::parse(in);
  EXPECT_EQ(json.at("dimensions").size(), 9u);
  EXPECT_EQ(json.at("dimensions").at(4).at("moved_faces"), nlohmann::json::array({16, 17}));
}

TEST_F(Cli, BadFacesAreRefusedNamingTheDimensionAndTheFace) {
  const std::string step = kRoot + "/examples/step/bracket.step";
  const auto part = [&](const std::string& name, const std::string& dimension,
                        const std::string& file) {
    return write(name, R"({"description": "bad", "dimensions": [)" + dimension +
                           R"(], "shape": {"type": "step", "file": ")" + file + R"("}})");
  };
  const auto length = [](const std::string& moves, const std::string& bounds = "36, \"max\": 44") {
    return R"({"name": "base_length", "nominal": 40, "min": )" + bounds +
           R"(, "unit": "mm", )" + moves + "}";
  };
  write("empty.step", "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\n"
                      "FILE_NAME('empty','2026-12-07T00:00:00',(''),(''),'','','');\n"
                      "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\n"
                      "DATA;\n#1 = CARTESIAN_POINT('',(0.,0.,0.));\nENDSEC;\nEND-ISO-10303-21;\n");
  const struct {
    std::string file, expected;
  } cases[] = {
      {part("nowhere.json", length(R"("offset": {"faces": [{"at": [100, 100, 100]}]})"), step),
       "dimension 'base_length', offset: no face within 0.01 mm of (100, 100, 100); the nearest is "
       "face"},
      {part("edge.json", length(R"("offset": {"faces": [{"at": [40, 0, 2]}]})"), step),
       "dimension 'base_length', offset: (40, 0, 2) lies on 2 faces within 0.01 mm, face"},
      {part("plane.json", length(R"("diameter": {"faces": [{"at": [40, 12.5, 2]}]})"), step),
       "dimension 'base_length', diameter: face 13 of 17 (#859, plane) is a plane"},
      {part("inverts.json",
            length(R"("offset": {"faces": [{"at": [40, 12.5, 2]}], "datum": [{"at": [0, 12.5, 2]}]})",
                   "10, \"max\": 44"),
            step),
       "dimension 'base_length' cannot take"},
      {part("entity.json", length(R"("offset": {"faces": ["#99999"]})"), step),
       "dimension 'base_length', offset: #99999 is no face of the STEP solid"},
      {part("nosolid.json", length(R"("offset": {"faces": [{"at": [40, 12.5, 2]}]})"),
            out("empty.step")),
       "the STEP file holds no shape OpenCASCADE can read"}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.file);
    const std::string folder = out("refused");
    const CommandResult r = run("part check " + c.file + " -o " + folder + " -q");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(c.expected), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(folder)) << r.output;
  }
  // A dimension of a STEP part that names no face moves nothing.
  const std::string nothing = write(
      "nothing.json",
      R"({"description": "d", "dimensions": [{"name": "base_length", "nominal": 40, "min": 36,
          "max": 44, "unit": "mm", "offset": {"faces": [{"at": [40, 12.5, 2]}]}},
          {"name": "spare", "nominal": 1, "min": 0, "max": 2, "unit": "mm"}],
          "shape": {"type": "step", "file": ")" + step + R"("}})");
  const CommandResult moves_nothing = run("part check " + nothing + " -o " + out("n") + " -q");
  EXPECT_EQ(moves_nothing.status, 1) << moves_nothing.output;
  EXPECT_NE(moves_nothing.output.find("dimension 'spare' moves nothing"), std::string::npos)
      << moves_nothing.output;
  EXPECT_FALSE(fs::exists(out("n")));
  // The inverted face is named with the range that can be built.
  const CommandResult inverts = run("part check " + out("inverts.json") + " -o " + out("x") + " -q");
  EXPECT_NE(inverts.output.find("turns over"), std::string::npos) << inverts.output;
  EXPECT_NE(inverts.output.find("can be built from"), std::string::npos) << inverts.output;
}

}  // namespace
}  // namespace xgauge
