// Calibration on synthetic data with a known answer: ramps whose rows are
// known, a wedge and a cuboid rendered with a known material, the scatter
// around a wedge.
#include "xgauge/calibrate/part.h"

#include "core/expect_error.h"
#include "image/test_folder.h"
#include "xgauge/calibrate/halo.h"
#include "xgauge/calibrate/ramp.h"
#include "xgauge/calibrate/wedge.h"
#include "xgauge/report/calibration.h"

#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/detector.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

class Calibrate : public ::testing::Test {
 protected:
  void SetUp() override { setProgressEnabled(false); }
  TestFolder folder_;
  const fs::path dir_ = folder_.path();
};

double curve(double x) { return 0.6 * std::exp(-0.05 * x) + 0.4 * std::exp(-0.3 * x); }

// A 300 x 600 open-beam image with a wedge whose ramp runs from 0.2 mm at row
// `thin` to 20 mm at row `thick` (pixel edges) in columns 60..239, walls of
// 20 mm beside it, and (`rise_rows` > 0) a perspective-like fall of the path
// from 20 mm to 0 over that many rows beyond the thick end; noise sigma 0.005.
Image syntheticRamp(int thin, int thick, int rise_rows, uint64_t seed) {
  Image image(300, 600, 1.0f);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.005);
  const int step = thick > thin ? 1 : -1;
  for (int y = 0; y < image.height(); ++y) {
    // Path along the ramp, by the row's centre.
    const double c = y + 0.5;
    const double s = (c - thin) / (thick - thin);  // 0 at the thin end, 1 at the thick end
    double path = 0.0;
    if (s >= 0.0 && s <= 1.0) path = 0.2 + 19.8 * s;
    const double beyond = (c - thick) * step;  // rows past the thick end
    if (rise_rows > 0 && beyond > 0.0 && beyond < rise_rows)
      path = 20.0 * (1.0 - beyond / rise_rows);
    const bool in_block =
        (s >= 0.0 && s <= 1.0) || (rise_rows > 0 && beyond > 0.0 && beyond < rise_rows);
    for (int x = 0; x < image.width(); ++x) {
      double value = 1.0;
      if (x >= 60 && x < 240)
        value = curve(path);
      else if (in_block && ((x >= 40 && x < 60) || (x >= 240 && x < 260)))
        value = curve(20.0);
      image(x, y) = static_cast<float>(value + noise(rng));
    }
  }
  return image;
}

TEST(CurveFit, PicksTheSmallestNumberOfTermsThatFitsWithinTheNoise) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1e-4);
  std::vector<double> x, one, two, step;
  for (int i = 0; i <= 400; ++i) {
    x.push_back(0.05 * i);
    one.push_back(std::exp(-0.1 * x.back()) + noise(rng));
    two.push_back(0.7 * std::exp(-0.05 * x.back()) + 0.3 * std::exp(-0.4 * x.back()) + noise(rng));
    step.push_back(x.back() < 10.0 ? 0.9 : 0.2);
  }
  const CurveFit a = fitCurve(x, one, {.max_terms = 4, .noise = 1e-4}, "one");
  EXPECT_EQ(a.best().terms, 1) << a.choice;
  ASSERT_EQ(a.fits.size(), 4u);
  const CurveFit b = fitCurve(x, two, {.max_terms = 4, .noise = 1e-4}, "two");
  EXPECT_EQ(b.best().terms, 2) << b.choice;
  EXPECT_LT(b.best().report.rms_residual, 1.25e-4);
  // Within the noise, the table shows only the noise carried into the
  // curve: 1e-4 sqrt(4 / 401) for two terms' four parameters.
  EXPECT_NEAR(b.tableUncertainty(), 1e-4 * std::sqrt(4.0 / 401.0), 0.2e-5);
  // Not an attenuation curve: the fit cannot converge to it.
  expectErrorMentioning([&] { fitCurve(x, step, {.max_terms = 4, .noise = 1e-4}, "step.tif"); },
                        "does not converge");
}

TEST(CurveFit, RatesStayAboveTheFloorAndTheMisfitCountsInTheUncertainty) {
  // A table that levels off at 0.1, as a detector offset or a wrong white
  // region makes it: without a floor the fit takes a constant term (rate
  // ~0), which no material has; with the floor every rate is at least it,
  // and what the floored curve cannot follow shows as misfit in its
  // uncertainty.
  std::vector<double> x, levelling;
  for (int i = 0; i <= 400; ++i) {
    x.push_back(0.05 * i);
    levelling.push_back(0.05 + 0.95 * std::exp(-0.3 * x.back()));
  }
  const CurveFit free = fitCurve(x, levelling, {.max_terms = 3, .noise = 1e-4}, "free");
  EXPECT_LT(free.best().fitted.front().mu_per_mm, 0.01);
  const double floor = 0.002;
  const CurveFit floored = fitCurve(
      x, levelling, {.max_terms = 3, .noise = 1e-4, .rate_floor_per_mm = floor}, "floored");
  for (const TermsFit& f : floored.fits)
    for (const ExponentialTerm& t : f.fitted) EXPECT_GE(t.mu_per_mm, floor);
  EXPECT_GT(floored.best().report.rms_residual, 3e-4)
      << toJson(floored).dump();  // the floor costs fit
  EXPECT_NEAR(floored.tableUncertainty(), floored.best().report.rms_residual, 0.2e-4);
  EXPECT_DOUBLE_EQ(toJson(floored)["rate_floor_per_mm"].get<double>(), floor);
}

TEST(RampDetection, FindsTheRowsOfASyntheticRampWithinTwoRows) {
  struct Case {
    int thin, thick, rise;
  };
  for (const Case c :
       {Case{100, 500, 0}, Case{500, 100, 0}, Case{80, 470, 60}, Case{520, 130, 60}}) {
    SCOPED_TRACE(::testing::Message()
                 << "thin " << c.thin << " thick " << c.thick << " rise " << c.rise);
    const RampDetection ramp =
        detectRamp(syntheticRamp(c.thin, c.thick, c.rise, 7), {}, "synthetic");
    EXPECT_NEAR(ramp.thin_row, c.thin, 2.0);
    EXPECT_NEAR(ramp.thick_row, c.thick, 2.0);
    EXPECT_EQ(ramp.thinEndOnTop(), c.thin < c.thick);
    // The band lies inside the ramp's columns and is most of them.
    EXPECT_GE(ramp.column_begin, 60);
    EXPECT_LE(ramp.column_end, 240);
    EXPECT_GT(ramp.column_end - ramp.column_begin, 100);
    // Row noise: 0.005 over the band's width.
    const double expected = 0.005 / std::sqrt(ramp.column_end - ramp.column_begin);
    EXPECT_NEAR(ramp.row_noise, expected, 0.3 * expected);
  }
}

TEST(RampDetection, ColumnDarkeningDoesNotHideTheOpenBeam) {
  // A flat panel's signal-dependent column darkening: each column reads
  // lower by 2 % of its mean attenuation, so the open beam above and below
  // the wedge lies about 0.007 below 1 in the wedge's columns, more than the
  // shadow threshold's margin.
  for (const auto& [thin, thick] : {std::pair{100, 500}, std::pair{500, 100}}) {
    Image image = syntheticRamp(thin, thick, 0, 5);
    for (int x = 0; x < image.width(); ++x) {
      double attenuation = 0.0;
      for (int y = 0; y < image.height(); ++y)
        attenuation += 1.0 - static_cast<double>(image(x, y));
      const double drop = 0.02 * attenuation / image.height();
      for (int y = 0; y < image.height(); ++y)
        image(x, y) = static_cast<float>(static_cast<double>(image(x, y)) - drop);
    }
    const RampDetection ramp = detectRamp(image, {}, "darkened");
    EXPECT_NEAR(ramp.thin_row, thin, 2.0);
    EXPECT_NEAR(ramp.thick_row, thick, 2.0);
    EXPECT_GE(ramp.column_begin, 60);
    EXPECT_LE(ramp.column_end, 240);
  }
}

TEST(RampDetection, OverridesAreUsedAsGiven) {
  RampOptions options;
  options.columns = std::array<int, 2>{100, 200};
  options.rows = std::array<double, 2>{101.5, 498.0};
  const RampDetection ramp = detectRamp(syntheticRamp(100, 500, 0, 3), options, "synthetic");
  EXPECT_EQ(ramp.column_begin, 100);
  EXPECT_EQ(ramp.column_end, 200);
  EXPECT_EQ(ramp.thin_row, 101.5);
  EXPECT_EQ(ramp.thick_row, 498.0);
  EXPECT_FALSE(ramp.automatic_rows);
  // Columns alone: the rows are still found.
  options.rows.reset();
  const RampDetection found = detectRamp(syntheticRamp(100, 500, 0, 3), options, "synthetic");
  EXPECT_NEAR(found.thin_row, 100.0, 2.0);
  EXPECT_NEAR(found.thick_row, 500.0, 2.0);
}

TEST(RampDetection, RejectsImagesWithoutAWholeRamp) {
  // Open beam only.
  expectErrorMentioning([] { detectRamp(Image(300, 600, 1.0f), {}, "open.tif"); }, "no ramp found");
  // A uniform block: a shadow that does not darken along the columns.
  Image block(300, 600, 1.0f);
  for (int y = 100; y < 500; ++y)
    for (int x = 60; x < 240; ++x) block(x, y) = 0.3f;
  expectErrorMentioning([&] { detectRamp(block, {}, "block.tif"); }, "no ramp found");
  // A ramp cut by the image's top or bottom edge does not span the thickness range.
  expectErrorMentioning([] { detectRamp(syntheticRamp(-50, 500, 0, 1), {}, "cut.tif"); },
                        "runs off the image");
  expectErrorMentioning([] { detectRamp(syntheticRamp(100, 620, 0, 1), {}, "cut.tif"); },
                        "runs off the image");
  // Overrides outside the image.
  RampOptions bad;
  bad.columns = std::array<int, 2>{250, 400};
  expectErrorMentioning([&] { detectRamp(syntheticRamp(100, 500, 0, 1), bad, "x.tif"); },
                        "outside the image");
}

// A machine whose 512 x 512 detector of 0.8 mm pixels sees the whole wedge
// block (90 mm) at magnification 3.85.
Machine wedgeMachine() {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = 512;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.8;
  machine.cx_px = 256.3, machine.cy_px = 255.1;
  return machine;
}

// The aluminium-like curve the wedge tests render with.
const ExponentialSum kWedgeCurve({{0.55, 0.045}, {0.35, 0.13}, {0.1, 0.5}});

// The wedge block at `pose` (its dimensions nominal but for `dims`),
// rendered with kWedgeCurve and `samples` x `samples` area samples per
// pixel: no scatter, no noise.
Image renderWedgeBlock(const Machine& machine, const Pose& pose, int samples,
                       const std::map<std::string, double>& dims = {}) {
  const PartModel part = PartModel::load(kRoot + "/parts/wedge_block.json");
  const TriangleMesh mesh = part.mesh(part.values(dims));
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  RenderOptions options;
  options.samples_per_axis = samples;
  // Edges and silhouettes 8 x 8, as a measurement's final stage renders
  // (measure/schedule.h).
  options.edge_samples_per_axis = samples < 8 ? 8 : 0;
  Image image;
  renderIntensity(machine, {world, mesh.triangles},
                  TransmissionTable::forMaterial(kWedgeCurve, 200.0), options, image);
  return image;
}

// The wedge block 740 mm from the source as a calibration shot: `machine`
// written to machine.json, the block rendered, blurred by the thesis's
// scatter (w 0.139, sigma 50 mm), normalized by the white region [8, 8, 40,
// 40] as a measured image is and written to wedge.tif; returns its pose.
Pose writeWedgeShot(const Machine& machine, const fs::path& dir) {
  std::ofstream(dir / "machine.json") << machine.toJson().dump();
  const Pose pose = Pose::fromEulerDeg(Vec3(0, 0, 0), Vec3(0.0, -45.0, 740.0));
  Image image = renderWedgeBlock(machine, pose, 3);
  image = scatterBlur(std::move(image), 0.139, 50.0 / machine.pitch_u_mm);
  const double open = meanOf(image, PixelRect{8, 8, 40, 40});
  for (float& p : image.pixels()) p = static_cast<float>(static_cast<double>(p) / open);
  writeTiff(dir / "wedge.tif", image, TiffFormat::kFloat32);
  return pose;
}

TEST_F(Calibrate, WedgeGivesBackTheMaterialItWasRenderedWith) {
  const Machine machine = wedgeMachine();
  const ExponentialSum& truth = kWedgeCurve;
  // The detector's scatter, and the white-region normalization a measured image gets.
  const Pose pose = writeWedgeShot(machine, dir_);
  std::ofstream(dir_ / "job.json") << R"({
    "machine": "machine.json",
    "radiograph": {"image": "wedge.tif", "white_region": [8, 8, 40, 40]},
    "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0},
    "scatter": {"weight": 0.139, "sigma_mm": 50.0},
    "rate_floor": {"compound": "Al", "density_g_cm3": 2.699, "tube_kv": 300}})";
  const WedgeCalibrationJob job = WedgeCalibrationJob::load(dir_ / "job.json");
  const WedgeCalibration result = calibrateFromWedge(job);
  ASSERT_TRUE(job.rate_floor);
  for (const ExponentialTerm& t : result.material.terms())
    EXPECT_GE(t.mu_per_mm, job.rate_floor->per_mm);

  // The ramp's ends: the back face's edges at part y = 90 (thin) and 0 (thick).
  const double thin = machine.project(pose.apply(Vec3(0, 90, 0))).y();
  const double thick = machine.project(pose.apply(Vec3(0, 0, 0))).y();
  EXPECT_NEAR(result.ramp.thin_row, thin, 2.0);
  EXPECT_NEAR(result.ramp.thick_row, thick, 2.0);
  EXPECT_NEAR(result.back_face_z_mm, 740.0, 10.0);
  // The thin end is 0.2 mm: eq. 3.7 moves the axis by about that much.
  EXPECT_LT(result.x0_mm, -0.1);
  EXPECT_GT(result.x0_mm, -0.3);
  const CurveDeviation dev =
      curveDeviation([&](double x) { return result.material.transmission(x); },
                     [&](double x) { return truth.transmission(x); }, 20.0);
  EXPECT_LT(dev.max_abs, 2e-3) << "at " << dev.at_mm << " mm";
  EXPECT_DOUBLE_EQ(result.material.transmission(0.0), 1.0);
  // The curve's uncertainty: its table and four influences (scatter weight
  // and width, thickness, ramp length) combined; at k = 2 it covers the
  // deviation from the truth.
  ASSERT_EQ(result.influences.size(), 4u);
  double variance = result.table_uncertainty * result.table_uncertainty;
  for (const CurveInfluence& i : result.influences) variance += i.change * i.change;
  EXPECT_DOUBLE_EQ(result.material.transmissionUncertainty(), std::sqrt(variance));
  EXPECT_LE(dev.max_abs, 2.0 * result.material.transmissionUncertainty());
  ASSERT_TRUE(result.material.calibratedRange());
  EXPECT_NEAR((*result.material.calibratedRange())[1], 20.0, 0.5);
  EXPECT_LT((*result.material.calibratedRange())[0], 1.0);

  writeWedgeCalibration(job, result, {}, dir_ / "out");
  EXPECT_TRUE(fs::exists(dir_ / "out" / "material.json"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "report.html"));
  const ExponentialSum reread = ExponentialSum::load(dir_ / "out" / "material.json");
  EXPECT_EQ(reread.transmission(7.0), result.material.transmission(7.0));
  EXPECT_EQ(reread.transmissionUncertainty(), result.material.transmissionUncertainty());
  EXPECT_EQ(reread.calibratedRange(), result.material.calibratedRange());
  // The curve's freedom beyond its range (docs/method.md, "The curve beyond
  // its calibrated range") is written with it: 0 at the range's end, more
  // beyond, where it covers how far the calibrated curve's difference from
  // the rendered one grows beyond what it is at the range's end (the
  // in-range u covers that: 0.0002 of 0.0036; the growth came to 0.92 of e
  // at 25 mm, 0.46 at 30, 0.16 at 40).
  const std::vector<ExtrapolationPoint>& beyond = result.material.extrapolation();
  ASSERT_GE(beyond.size(), 2u);
  EXPECT_NEAR(beyond.front().path_mm, (*result.material.calibratedRange())[1], 0.5);
  EXPECT_EQ(beyond.front().half_width, 0.0);
  ASSERT_EQ(reread.extrapolation().size(), beyond.size());
  EXPECT_EQ(reread.extrapolation().back().half_width, beyond.back().half_width);
  const double end = beyond.front().path_mm;
  auto deviation = [&](double x) {
    return result.material.transmission(x) - truth.transmission(x);
  };
  EXPECT_GT(result.material.extrapolationHalfWidth(25.0), 0.0);
  for (double x : {30.0, 40.0}) {
    EXPECT_GT(result.material.extrapolationHalfWidth(x),
              result.material.extrapolationHalfWidth(25.0));
    EXPECT_LE(std::abs(deviation(x) - deviation(end)), result.material.extrapolationHalfWidth(x))
        << x;
  }
  // The thickness's and the ramp length's curves are listed for the budget
  // (the scatter's go with the scatter); the rest of u is the table's and
  // the scatter's.
  ASSERT_EQ(reread.curveMoves().size(), 2u);
  double listed = 0.0;
  for (const CurveMove& move : reread.curveMoves()) {
    EXPECT_TRUE(move.name == "wedge max_thickness_mm" || move.name == "wedge ramp_length_mm")
        << move.name;
    EXPECT_GT(move.curve_change, 0.0);
    listed += move.curve_change * move.curve_change;
  }
  EXPECT_NEAR(reread.curveMovesBesides() * reread.curveMovesBesides() + listed,
              std::pow(reread.transmissionUncertainty(), 2), 1e-12);

  // An open-beam radiograph: a clear error and no material file.
  writeTiff(dir_ / "wedge.tif", Image(512, 512, 1.0f), TiffFormat::kFloat32);
  expectErrorMentioning([&] { calibrateFromWedge(job); }, "no ramp found");
}

// A characterised two-width halo with its kernel's end and other kernel
// (image/scatter.h): the curve is calibrated again with each one's kernel
// removed, its change scaled to the equivalent width's u, counted in the
// curve's u and written for the budget beside the weight's and width's
// curves.
TEST_F(Calibrate, AHalosKernelEndMovesTheCurveScaledToItsU) {
  const Machine machine = wedgeMachine();
  writeWedgeShot(machine, dir_);
  // Two Gaussians, the second's share 0 (the Gaussian the shot has); the
  // end adds a wide part: sigma_eq from 50 to sqrt(0.95 50^2 + 0.05 150^2)
  // = 60.2 mm, standing for u = 5 mm: the scale is 5 / 10.2.
  std::ofstream(dir_ / "job.json") << R"({
    "machine": "machine.json",
    "radiograph": {"image": "wedge.tif", "white_region": [8, 8, 40, 40]},
    "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0},
    "scatter": {"weight": 0.139, "shape": "two_gauss", "sigma1_mm": 50.0, "sigma2_mm": 150.0,
                "fraction2": 0.0, "equivalent_end": {"weight": 0.139, "sigma1_mm": 50.0,
                "sigma2_mm": 150.0, "fraction2": 0.05, "equivalent_sigma_uncertainty_mm": 5.0},
                "kernel_choice": {"shape": "gauss_exp", "weight": 0.14, "sigma_mm": 50.0,
                "tail_fraction": 0.05, "tail_length_mm": 60.0,
                "equivalent_sigma_uncertainty_mm": 3.9907}}})";
  const WedgeCalibrationJob job = WedgeCalibrationJob::load(dir_ / "job.json");
  const WedgeCalibration result = calibrateFromWedge(job);
  const CurveInfluence *kernel = nullptr, *choice = nullptr;
  for (const CurveInfluence& i : result.influences) {
    if (i.name == kScatterKernelInfluence) kernel = &i;
    if (i.name == kScatterKernelChoiceInfluence) choice = &i;
  }
  ASSERT_NE(kernel, nullptr);
  ASSERT_NE(choice, nullptr);
  ASSERT_TRUE(choice->moved.has_value());
  // The other kernel: sigma_eq sqrt(0.95 50^2 + 3 0.05 60^2) = 53.9907 mm,
  // its u 3.9907: scaled by u over the distance, 1.
  const double choice_scale = 3.9907 / (std::sqrt(0.95 * 2500.0 + 3.0 * 0.05 * 3600.0) - 50.0);
  EXPECT_NEAR(choice_scale, 1.0, 1e-3);
  EXPECT_NEAR(choice->change,
              choice_scale * largestDifference(result.material, *choice->moved, result.x_max_mm),
              1e-12);
  EXPECT_GT(choice->change, 0.0);
  ASSERT_TRUE(kernel->moved.has_value());
  EXPECT_DOUBLE_EQ(kernel->uncertainty, 5.0);
  EXPECT_NEAR(kernel->value, 50.0, 1e-9);
  const double reach = std::sqrt(0.95 * 50.0 * 50.0 + 0.05 * 150.0 * 150.0) - 50.0;
  EXPECT_NEAR(kernel->change,
              5.0 / reach * largestDifference(result.material, *kernel->moved, result.x_max_mm),
              1e-12);
  EXPECT_GT(kernel->change, 0.0);
  double variance = result.table_uncertainty * result.table_uncertainty;
  for (const CurveInfluence& i : result.influences) variance += i.change * i.change;
  EXPECT_DOUBLE_EQ(result.material.transmissionUncertainty(), std::sqrt(variance));
  writeWedgeCalibration(job, result, {}, dir_ / "out");
  const nlohmann::json material =
      nlohmann::json::parse(std::ifstream(dir_ / "out" / "material.json"));
  const nlohmann::json& moves = material.at("scatter").at("curve_moves");
  EXPECT_TRUE(moves.contains("equivalent_end")) << moves.dump();
  EXPECT_TRUE(moves.contains("kernel_choice")) << moves.dump();
  EXPECT_TRUE(material.at("scatter").contains("equivalent_end"));
  // The curve's u besides the scatter's moves leaves the kernel's out.
  double besides = result.table_uncertainty * result.table_uncertainty;
  for (const CurveInfluence& i : result.influences)
    if (i.name != kScatterWeightInfluence && i.name != kScatterWidthInfluence &&
        i.name != kScatterKernelInfluence && i.name != kScatterKernelChoiceInfluence)
      besides += i.change * i.change;
  EXPECT_NEAR(moves.at("transmission_uncertainty_besides").get<double>(), std::sqrt(besides),
              1e-12);
}

// A wedge turned by 90 degrees: its ramp runs along the rows, and the
// calibration reads it from the transposed radiograph.
TEST_F(Calibrate, ATurnedWedgeIsReadAlongItsRows) {
  const Machine machine = wedgeMachine();
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  Pose pose = Pose::fromEulerDeg(Vec3(0, 0, 90), Vec3(0.0, 0.0, 740.0));
  pose.translation_mm += pose.rotation * Vec3(0.0, -45.0, 0.0);
  writeTiff(dir_ / "wedge.tif", renderWedgeBlock(machine, pose, 3), TiffFormat::kFloat32);
  std::ofstream(dir_ / "job.json") << R"({
    "machine": "machine.json",
    "radiograph": {"image": "wedge.tif", "white_region": [8, 8, 40, 40]},
    "wedge": {"max_thickness_mm": 20.0, "ramp_length_mm": 90.0},
    "scatter": {"weight": 0, "sigma_mm": 1}})";
  const WedgeCalibrationJob job = WedgeCalibrationJob::load(dir_ / "job.json");
  const WedgeCalibration result = calibrateFromWedge(job);
  EXPECT_TRUE(result.turned);
  // The thin end (part y = 90) and the thick end (y = 0), as columns of the
  // radiograph: rows of the transposed one.
  EXPECT_NEAR(result.ramp.thin_row, machine.project(pose.apply(Vec3(0, 90, 0))).x(), 2.0);
  EXPECT_NEAR(result.ramp.thick_row, machine.project(pose.apply(Vec3(0, 0, 0))).x(), 2.0);
  const CurveDeviation dev =
      curveDeviation([&](double x) { return result.material.transmission(x); },
                     [&](double x) { return kWedgeCurve.transmission(x); }, 20.0);
  EXPECT_LT(dev.max_abs, 2e-3) << "at " << dev.at_mm << " mm";
}

// The wedge fitted as a known part (wedge_part.h) on set-ups the ramp
// method cannot read: turned, tilted, a few tenths off nominal, seen whole or
// in part, the principal point off centre, with scatter and noise. Nothing
// about the pose is given.
struct KnownWedgeCase {
  int side;
  double pitch_mm, magnification;
  Vec3 rotation_deg;        // tilts and the turn about the beam
  Vec2 centre_offset_mm;    // of the block's centre from the beam's axis, at its depth
  double weight, sigma_mm;  // the detector's scatter, given in the job
};

TEST_F(Calibrate, AWedgeFittedAsAKnownPartGivesBackItsMaterial) {
  const std::map<std::string, double> dims{{"thickness", 20.23},       {"thin_end", 0.41},
                                           {"pocket_left_top", 29.37}, {"pocket_right_top", 29.88},
                                           {"wall_left_top", 8.62},    {"wall_right_top", 8.57},
                                           {"wall_left_mid", 9.41},    {"wall_right_mid", 7.86},
                                           {"pocket_left_mid", 29.52}, {"pocket_right_mid", 29.81}};
  const KnownWedgeCase setups[] = {
      // Whole, turned by 90 degrees and tilted; scatter.
      {256, 0.8, 1.6, Vec3(2.5, -3.5, 90.0), Vec2(3.0, -2.0), 0.12, 40.0},
      // A third of it off the detector's side, turned by 200 degrees.
      {320, 0.4, 1.3, Vec3(-4.0, 1.5, 200.0), Vec2(35.0, 0.0), 0.0, 1.0},
      // A corner (the thin end of the left wall) of a wedge turned by 90
      // degrees, on a detector 68 mm across at the wedge: the calibration
      // grid's s04, whose tilt the local fit left 2.7 degrees off until the
      // tilts were searched again (part.cpp, retryTilts).
      {256, 0.4, 1.5, Vec3(0.19, 0.61, 90.0), Vec2(28.0, 21.0), 0.144, 113.0},
  };
  int index = 0;
  for (const KnownWedgeCase& c : setups) {
    SCOPED_TRACE(::testing::Message() << "setup " << index);
    Machine machine;
    machine.source_detector_distance_mm = 900.0;
    machine.columns = machine.rows = c.side;
    machine.pitch_u_mm = machine.pitch_v_mm = c.pitch_mm;
    machine.cx_px = 0.5 * c.side + 11.3, machine.cy_px = 0.5 * c.side - 7.6;
    std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
    const double z = 900.0 * (1.0 - 1.0 / c.magnification);
    Pose pose =
        Pose::fromEulerDeg(c.rotation_deg, Vec3(c.centre_offset_mm.x(), c.centre_offset_mm.y(), z));
    pose.translation_mm -= pose.rotation * Vec3(0.0, 45.0, dims.at("thickness") / 2);
    Image image = renderWedgeBlock(machine, pose, 3, dims);
    if (c.weight > 0.0) image = scatterBlur(std::move(image), c.weight, c.sigma_mm / c.pitch_mm);
    std::mt19937_64 rng(40 + static_cast<uint64_t>(index));
    std::normal_distribution<double> noise(0.0, 0.002);
    for (float& p : image.pixels()) p = static_cast<float>(static_cast<double>(p) + noise(rng));
    writeTiff(dir_ / "wedge.tif", image, TiffFormat::kFloat32);
    nlohmann::json job = {
        {"machine", "machine.json"},
        {"radiograph", {{"image", "wedge.tif"}, {"white_region", {2, 2, 12, 12}}}},
        {"wedge", {{"model", kRoot + "/parts/wedge_block.json"}, {"dimensions", dims}}},
        {"scatter", {{"weight", c.weight}, {"sigma_mm", c.sigma_mm}}},
        {"rate_floor", {{"compound", "Al"}, {"density_g_cm3", 2.699}, {"tube_kv", 300}}}};
    std::ofstream(dir_ / "job.json") << job.dump();
    const WedgeCalibrationJob loaded = WedgeCalibrationJob::load(dir_ / "job.json");
    const WedgeCalibration result = calibrateFromWedge(loaded);
    ASSERT_TRUE(result.part);
    // The pose: the turn and the tilts within a tenth of a degree.
    const Mat3 error =
        result.part->measurement.radiographs.front().pose.rotation * pose.rotation.transpose();
    EXPECT_LT(std::acos(std::clamp(0.5 * (error.trace() - 1.0), -1.0, 1.0)) * kRadToDeg, 0.1);
    EXPECT_NEAR(result.magnification, c.magnification, 0.01 * c.magnification);
    for (const ExponentialTerm& t : result.material.terms())
      EXPECT_GE(t.mu_per_mm, loaded.rate_floor->per_mm);
    // 5 % to 95 % of the thickness, as the grid (docs/results.md) measures.
    double worst = 0.0;
    for (int i = 0; i <= 90; ++i) {
      const double x = dims.at("thickness") * (0.05 + 0.01 * i);
      worst =
          std::max(worst, std::abs(result.material.transmission(x) - kWedgeCurve.transmission(x)));
    }
    EXPECT_LT(worst, 1e-3);
    // The curve's uncertainty holds the table's and one influence per
    // caliper value (and the scatter's weight and width when there is one).
    EXPECT_EQ(result.influences.size(), dims.size() + (c.weight > 0.0 ? 2u : 0u));
    EXPECT_GE(2.0 * result.material.transmissionUncertainty(), worst);
    // Its freedom beyond the table (docs/method.md, "The curve beyond its
    // calibrated range"), from the table's end on.
    ASSERT_GE(result.material.extrapolation().size(), 2u);
    EXPECT_EQ(result.material.extrapolation().front().path_mm,
              (*result.material.calibratedRange())[1]);
    EXPECT_EQ(result.material.extrapolation().front().half_width, 0.0);
    EXPECT_GT(result.material.extrapolationHalfWidth(1.5 * dims.at("thickness")), 0.0);
    // Each caliper value's curve is listed for the budget, with its change.
    ASSERT_EQ(result.material.curveMoves().size(), dims.size());
    for (const CurveMove& move : result.material.curveMoves()) {
      EXPECT_TRUE(move.name.starts_with("wedge ")) << move.name;
      EXPECT_EQ(move.standard_uncertainty, loaded.caliper_uncertainty_mm);
      EXPECT_NEAR(largestDifference(result.material, move.curve, result.x_max_mm),
                  move.curve_change, 1e-12 + 1e-6 * move.curve_change);
    }
    // Its outputs: material.json as the curve, and the pose fit's result.
    const fs::path out = dir_ / ("out" + std::to_string(index++));
    writeWedgeCalibration(loaded, result, {}, out, false);
    EXPECT_EQ(ExponentialSum::load(out / "material.json").transmission(7.0),
              result.material.transmission(7.0));
    EXPECT_TRUE(fs::exists(out / "poses" / "result.json"));
  }
}

// A wedge job with a model: every caliper value is given, by name, within
// the model's bounds, and the ramp method's keys are refused.
TEST_F(Calibrate, AWedgeModelsCaliperValuesAreCheckedByName) {
  std::ofstream(dir_ / "machine.json") << wedgeMachine().toJson().dump();
  const std::string model = kRoot + "/parts/wedge_block.json";
  nlohmann::json dims = {{"thickness", 20.0},        {"thin_end", 0.2},
                         {"pocket_left_top", 29.58}, {"pocket_right_top", 29.66},
                         {"wall_left_top", 8.8},     {"wall_right_top", 8.4},
                         {"wall_left_mid", 9.2},     {"wall_right_mid", 8.1},
                         {"pocket_left_mid", 29.7},  {"pocket_right_mid", 29.65}};
  auto write = [&](const nlohmann::json& wedge, const nlohmann::json& extra) {
    nlohmann::json job = {
        {"machine", "machine.json"},
        {"radiograph", {{"image", "wedge.tif"}, {"white_region", {8, 8, 40, 40}}}},
        {"wedge", wedge}};
    if (extra.is_object()) job.update(extra);
    std::ofstream(dir_ / "job.json") << job.dump();
    return dir_ / "job.json";
  };
  const auto good = WedgeCalibrationJob::load(write({{"model", model}, {"dimensions", dims}}, {}));
  ASSERT_TRUE(good.model);
  EXPECT_EQ(good.caliper.size(), 10u);
  EXPECT_DOUBLE_EQ(good.caliper_uncertainty_mm, 0.01);
  nlohmann::json missing = dims;
  missing.erase("thin_end");
  expectErrorMentioning(
      [&] {
        WedgeCalibrationJob::load(write({{"model", model}, {"dimensions", missing}}, {}));
      },
      "'thin_end' is missing");
  nlohmann::json unknown = dims;
  unknown["thikness"] = 20.0;
  expectErrorMentioning(
      [&] {
        WedgeCalibrationJob::load(write({{"model", model}, {"dimensions", unknown}}, {}));
      },
      "thikness");
  nlohmann::json outside = dims;
  outside["thickness"] = 40.0;
  expectErrorMentioning(
      [&] {
        WedgeCalibrationJob::load(write({{"model", model}, {"dimensions", outside}}, {}));
      },
      "thickness");
  expectErrorMentioning(
      [&] {
        WedgeCalibrationJob::load(
            write({{"model", model}, {"dimensions", dims}, {"ramp_length_mm", 90.0}}, {}));
      },
      "the wedge's model gives its dimensions");
  expectErrorMentioning(
      [&] {
        WedgeCalibrationJob::load(
            write({{"model", model}, {"dimensions", dims}}, {{"ramp", {{"rows", {10, 400}}}}}));
      },
      "no ramp to give");
}

TEST_F(Calibrate, KnownCuboidGivesBackTheMaterialItWasRenderedWith) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = 320;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.4;
  machine.cx_px = 161.3, machine.cy_px = 158.9;
  std::ofstream(dir_ / "machine.json") << machine.toJson().dump();
  const ExponentialSum truth({{0.6, 0.03}, {0.3, 0.09}, {0.1, 0.4}});
  const PartModel part = PartModel::load(kRoot + "/parts/cuboid.json");
  const std::map<std::string, double> dims{{"size_x", 20.0}, {"size_y", 30.0}, {"size_z", 12.0}};
  const TriangleMesh mesh = part.mesh(part.values(dims));
  RenderOptions options;
  options.samples_per_axis = 2;
  options.edge_samples_per_axis = 8;  // as the fit's final stage (measure/schedule.h)
  std::vector<Vec3> world;
  const auto table = TransmissionTable::forMaterial(truth, 200.0);
  const std::pair<const char*, Pose> shots[] = {
      {"a", Pose::fromEulerDeg(Vec3(3, 25, 0), Vec3(-2.0, 1.0, 700.0))},
      {"b", Pose::fromEulerDeg(Vec3(-2, 62, 4), Vec3(3.0, -1.0, 705.0))}};
  for (const auto& [name, pose] : shots) {
    poseVertices(pose, mesh.vertices, world);
    Image image;
    renderIntensity(machine, {world, mesh.triangles}, table, options, image);
    writeTiff(dir_ / (std::string(name) + ".tif"), image, TiffFormat::kFloat32);
  }
  // The initial region: the centre of the first shadow, whose path the
  // rendered path length gives (a user would take it from the drawing).
  Image path;
  poseVertices(shots[0].second, mesh.vertices, world);
  RenderOptions centre;
  centre.region = PixelRect{150, 150, 1, 1};
  renderPathLength(machine, {world, mesh.triangles}, centre, path);
  std::ofstream(dir_ / "job.json") << R"({
    "part": ")" + kRoot + R"(/parts/cuboid.json",
    "machine": "machine.json",
    "dimensions": {"fixed": {"size_x": 20.0, "size_y": 30.0, "size_z": 12.0}},
    "radiographs": [
      {"name": "a", "image": "a.tif", "white_region": [4, 4, 30, 30], "pattern": "free"},
      {"name": "b", "image": "b.tif", "white_region": [4, 4, 30, 30], "pattern": "rotated", "reference": "a"}],
    "pose_bounds": {"rotation_deg": [[-8, 8], [0, 90], [-8, 8]], "centre_mm": [[-20, 20], [-20, 20], [680, 720]]},
    "loss": "l2",
    "calibration": {"terms": 3, "rounds": 3,
                    "initial": {"radiograph": "a", "region": [149, 149, 3, 3], "path_mm": )" +
                                          std::to_string(path(0, 0)) + R"(}}})";
  const PartCalibrationJob job = PartCalibrationJob::load(dir_ / "job.json");
  const PartCalibration result = calibrateFromPart(job);
  EXPECT_GT(result.initial_mu_per_mm, 0.03);
  ASSERT_FALSE(result.rounds.empty());
  const CurveDeviation dev =
      curveDeviation([&](double x) { return result.material.transmission(x); },
                     [&](double x) { return truth.transmission(x); }, result.max_path_mm);
  EXPECT_LT(dev.max_abs, 2e-3) << "at " << dev.at_mm << " mm";
  EXPECT_GT(result.max_path_mm, 15.0);
  writePartCalibration(job, result, {}, dir_ / "out");
  EXPECT_TRUE(fs::exists(dir_ / "out" / "material.json"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "poses" / "result.json"));
}

TEST_F(Calibrate, APartCalibrationTakesNoTolerances) {
  // Refused before any other file is read.
  std::ofstream(dir_ / "job.json") << R"({
    "part": "part.json", "machine": "machine.json",
    "tolerances": {"size_x": {"lower": -0.1, "upper": 0.1}},
    "radiographs": [{"name": "a", "image": "a.tif", "white_region": [4, 4, 30, 30]}],
    "pose_bounds": {"rotation_deg": [[0, 0], [0, 0], [0, 0]], "centre_mm": [[0, 0], [0, 0], [700, 700]]},
    "calibration": {"initial": {"radiograph": "a", "region": [149, 149, 3, 3], "path_mm": 10}}})";
  try {
    PartCalibrationJob::load(dir_ / "job.json");
    ADD_FAILURE() << "tolerances were accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "a calibration judges no part: leave \"tolerances\" out");
    EXPECT_EQ(e.where().key_path, "/tolerances");
    EXPECT_EQ(e.where().line, 3);
  }
}

// The scatter from the halo around a wedge block, over a range of detectors,
// magnifications, weights and widths, with the panel's column darkening and
// noise: known answers from the lab's own effects.
struct Case {
  int side;  // detector columns = rows
  double pitch_mm;
  double magnification;  // of the block's back face
  double offset_px;      // principal point right of the centre
  double turn_deg;       // the block turned about the beam
  double weight, sigma_px, darkening;
  HaloBorder border = HaloBorder::kMirror;  // what the halo sees beyond the panel
};

// The wedge block rendered with an aluminium-like curve, scattered, darkened,
// noisy (sigma 0.003) and normalized by its open beam's level far from the
// block (the corner), as a flat field and white region would.
Image wedgeShot(const Case& s, uint64_t seed) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = s.side;
  machine.pitch_u_mm = machine.pitch_v_mm = s.pitch_mm;
  machine.cx_px = 0.5 * s.side + s.offset_px, machine.cy_px = 0.5 * s.side - 3.3;
  const double z = 1000.0 * (1.0 - 1.0 / s.magnification);  // from the detector
  // The block's centre on the beam's axis, turned about it.
  Pose pose = Pose::fromEulerDeg(Vec3(0, 0, s.turn_deg), Vec3(0.0, 0.0, z));
  pose.translation_mm += pose.rotation * Vec3(0.0, -45.0, 0.0);
  Image image = renderWedgeBlock(machine, pose, 2);
  if (s.border == HaloBorder::kMirror) {
    image = scatterBlur(std::move(image), s.weight, s.sigma_px);
  } else {
    ScatterModel halo;
    halo.weight = s.weight, halo.sigma_mm = s.sigma_px * s.pitch_mm, halo.border = s.border;
    image = halo.apply(std::move(image), s.pitch_mm, 1.0f);
  }
  darkenColumns(image, s.darkening);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.003);
  double open = 0.0;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) open += static_cast<double>(image(x, y)) / 64.0;
  for (float& p : image.pixels())
    p = static_cast<float>(static_cast<double>(p) / open + noise(rng));
  return image;
}

TEST(ScatterHalo, WeightAndWidthComeBackOverARangeOfSetups) {
  setProgressEnabled(false);
  const Case setups[] = {
      // side, pitch, magnification, offset, turn, weight, sigma px, darkening
      {512, 0.4, 2.0, 0.0, 0.0, 0.139, 250.0, 0.0},
      {1024, 0.2, 1.5, 40.0, 90.0, 0.06, 400.0, 0.015},
      {640, 0.3, 1.8, -50.0, 180.0, 0.19, 200.0, 0.01},
  };
  int index = 0;
  for (const Case& s : setups) {
    SCOPED_TRACE(::testing::Message() << "setup " << index);
    const Image image = wedgeShot(s, 7 + static_cast<uint64_t>(index++));
    const HaloFit fit = fitScatterHalo(image, s.pitch_mm, "shot.tif");
    EXPECT_NEAR(fit.scatter.weight, s.weight, 0.15 * s.weight);
    EXPECT_NEAR(fit.scatter.sigma_mm, s.sigma_px * s.pitch_mm, 0.25 * s.sigma_px * s.pitch_mm);
    EXPECT_NEAR(fit.column_darkening, s.darkening, 0.005);
    // Each uncertainty covers the fit's error (k = 2, as a budget's U).
    EXPECT_LE(std::abs(fit.scatter.weight - s.weight), 2.0 * fit.scatter.weight_uncertainty)
        << "weight " << fit.scatter.weight << " +- " << fit.scatter.weight_uncertainty;
    EXPECT_LE(std::abs(fit.scatter.sigma_mm - s.sigma_px * s.pitch_mm),
              2.0 * fit.scatter.sigma_uncertainty_mm)
        << "sigma " << fit.scatter.sigma_mm << " +- " << fit.scatter.sigma_uncertainty_mm;
    EXPECT_GE(fit.correlation, 1.0);
    // Without the scatter and the darkening the open beam is flat at 1.
    EXPECT_NEAR(fit.primary(3, 3), 1.0, 0.02);
    EXPECT_NEAR(fit.primary(s.side - 4, s.side / 2), 1.0, 0.02);
  }
}

// A halo whose panel sees open beam beyond its edges, and one mirrored:
// each border comes back, and with it the weight and width within their
// stated uncertainties. Fitted with the mirror alone, the open-border shot's
// halo is not found.
TEST(ScatterHalo, ThePanelsBorderComesBackWithTheHalo) {
  setProgressEnabled(false);
  for (const HaloBorder border : {HaloBorder::kOpen, HaloBorder::kMirror}) {
    SCOPED_TRACE(toString(border));
    const Case s{512, 0.4, 2.0, 0.0, 0.0, 0.139, 125.0, 0.0, border};
    const Image image = wedgeShot(s, 11);
    const HaloFit fit = fitScatterHalo(image, s.pitch_mm, "shot.tif");
    EXPECT_EQ(fit.scatter.border, border);
    EXPECT_LE(std::abs(fit.scatter.weight - s.weight), 2.0 * fit.scatter.weight_uncertainty)
        << "weight " << fit.scatter.weight << " +- " << fit.scatter.weight_uncertainty;
    EXPECT_LE(std::abs(fit.scatter.sigma_mm - s.sigma_px * s.pitch_mm),
              2.0 * fit.scatter.sigma_uncertainty_mm)
        << "sigma " << fit.scatter.sigma_mm << " +- " << fit.scatter.sigma_uncertainty_mm;
    EXPECT_NEAR(fit.primary(3, 3), 1.0, 0.02);
  }
  HaloOptions mirror_only;
  mirror_only.borders = {HaloBorder::kMirror};
  const Case open{512, 0.4, 2.0, 0.0, 0.0, 0.139, 125.0, 0.0, HaloBorder::kOpen};
  // (It ends at a narrow width with a weight no scintillator has, 0.69,
  // and is refused as no scatter, or, should it pass, off by far more.)
  try {
    const HaloFit wrong = fitScatterHalo(wedgeShot(open, 11), 0.4, "shot.tif", mirror_only);
    EXPECT_GT(std::abs(wrong.scatter.weight - 0.139), 0.01) << wrong.scatter.weight;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit the open beam"), std::string::npos)
        << e.what();
  }
}

TEST(ScatterHalo, ADetectorWithoutScatterGetsNoneWithItsBound) {
  setProgressEnabled(false);
  const Image image = wedgeShot({512, 0.4, 2.0, 0.0, 0.0, 0.0, 250.0, 0.0}, 3);
  // A halo much wider than the open beam is a near-uniform level there, so
  // over the whole search (to 1.5 times the detector's side) the open beam
  // cannot tell "none" from a wide halo, and says so.
  expectErrorMentioning([&] { fitScatterHalo(image, 0.4, "shot.tif"); }, "does not decide");
  // Searched to half the side, it bounds the halo: none, with the most a
  // halo that fits as well could change the shadow by.
  HaloOptions narrower;
  narrower.max_sigma_fraction = 0.5;
  const HaloFit fit = fitScatterHalo(image, 0.4, "shot.tif", narrower);
  EXPECT_FALSE(fit.scatter.enabled());
  EXPECT_GT(fit.unseen_change, 0.0);
  EXPECT_LE(fit.unseen_change, 0.005 / 3.0);  // a third of the largest bound allowed
  EXPECT_NEAR(fit.column_darkening, 0.0, 0.005);
}

// A corner of a part seen with an open strip beside it, its path known (a
// posed known part): primary 1 in the strip, a dark ramp elsewhere, the
// halo's sigma in pixels, noise 0.003, normalized by the strip's corner.
struct CornerShot {
  Image normalized, path_mm;
};
CornerShot cornerShot(int side, double weight, double sigma_px, uint64_t seed) {
  CornerShot out{Image(side, side, 1.0f), Image(side, side, 0.0f)};
  for (int y = side / 4; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      out.normalized(x, y) = static_cast<float>(0.3 + 0.4 * x / side);
      out.path_mm(x, y) = 10.0f;
    }
  out.normalized = scatterBlur(std::move(out.normalized), weight, sigma_px);
  const double open = static_cast<double>(out.normalized(2, 2));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.003);
  for (float& p : out.normalized.pixels())
    p = static_cast<float>(static_cast<double>(p) / open + noise(rng));
  return out;
}

// A halo wider than the detector beside a part that fills three quarters of
// it: the open strip cannot tell the halo from the open level. It is refused
// as undecided, or the weight it states covers the truth at two standard
// uncertainties; never "no scatter" with a small uncertainty. A narrower
// halo on the same shot is found.
TEST(ScatterHalo, AHaloWiderThanTheOpenBeamIsNotTakenForNone) {
  setProgressEnabled(false);
  for (const double weight : {0.14, 0.08}) {
    SCOPED_TRACE(::testing::Message() << "weight " << weight);
    const CornerShot shot = cornerShot(256, weight, 300.0, 5);
    try {
      const HaloFit fit = fitScatterWithPaths(shot.normalized, shot.path_mm, 0.2, "shot.tif");
      EXPECT_LE(std::abs(fit.scatter.weight - weight), 2.0 * fit.scatter.weight_uncertainty)
          << "weight " << fit.scatter.weight << " +- " << fit.scatter.weight_uncertainty;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("does not decide"), std::string::npos) << e.what();
    }
  }
  const CornerShot narrow = cornerShot(256, 0.1, 40.0, 6);
  const HaloFit fit = fitScatterWithPaths(narrow.normalized, narrow.path_mm, 0.2, "shot.tif");
  EXPECT_NEAR(fit.scatter.weight, 0.1, 0.015);
  EXPECT_NEAR(fit.scatter.sigma_mm, 8.0, 2.0);
}

TEST(ScatterHalo, SaysSoWhenTheRadiographCannotDecide) {
  setProgressEnabled(false);
  // An open beam: no outline to find a halo around.
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.003);
  Image open(256, 256, 1.0f);
  for (float& p : open.pixels()) p = static_cast<float>(1.0 + noise(rng));
  expectErrorMentioning([&] { fitScatterHalo(open, 0.4, "open.tif"); }, "sharp outline");
  // The block filling the detector: too little open beam around it.
  const Image filled = wedgeShot({256, 0.2, 2.0, 0.0, 0.0, 0.139, 250.0, 0.0}, 4);
  expectErrorMentioning([&] { fitScatterHalo(filled, 0.2, "filled.tif"); }, "give the job");
}

}  // namespace
}  // namespace xgauge
