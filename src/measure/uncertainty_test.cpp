// The uncertainty budget and the self-checks of a measurement, on radiographs
// rendered by xgauge's own renderer with known noise, geometry and material:
// the statistical U against the spread over noise, each influence's
// component against a measurement of radiographs taken with it changed,
// identifiability on a part
// with an exact degeneracy, residual regions where an image was changed.
#include "xgauge/measure/gradient_check.h"
#include "xgauge/measure/measure.h"

#include "xgauge/core/error.h"
#include "xgauge/core/parallel.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/lag.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/random.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/measure/model.h"
#include "xgauge/xray/renderer.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

namespace xgauge {
namespace {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

// A cuboid of known size seen twice (the second shot translated by 30 mm)
// by a 160^2 detector of 0.8 mm pixels, magnification about 2.
struct Scene {
  std::string part_file = kRoot + "/parts/cuboid.json";
  std::map<std::string, double> truth = {{"size_x", 20.6}, {"size_y", 29.4}, {"size_z", 10.3}};
  Pose a = Pose::fromEulerDeg({2.0, 25.0, -1.5}, {-8.0, 1.0, 500.0});
  Vec3 axis = Vec3(1.0, 0.03, 0.05).normalized();
  Machine machine = [] {
    Machine m;
    m.source_detector_distance_mm = 1000.0;
    m.columns = m.rows = 160;
    m.pitch_u_mm = m.pitch_v_mm = 0.8;
    m.cx_px = 80.3, m.cy_px = 79.4;
    m.source_detector_distance_uncertainty_mm = 0.5;
    m.pixel_pitch_uncertainty_relative = 0.0;
    return m;
  }();
  ExponentialSum material = ExponentialSum({{0.6, 0.03}, {0.3, 0.07}, {0.1, 0.25}});
  double noise = 0.0;  // Gaussian sigma added to each pixel
  uint64_t seed = 1;
  // Lab deviations from what the job says.
  double lab_distance_offset_mm = 0.0;
  double lab_rate_scale = 0.0;
  // A bright disc added to radiograph a: centre (px), radius (px), height.
  std::optional<std::array<double, 4>> blob;
  // Detector lag: radiograph b records this fraction of a's signal, and the
  // job names a as b's previous frame (with the machine's `stated_lag` when
  // it is not NaN).
  double lab_lag = 0.0;
  // Added to radiograph b's white region only (the job's [2, 2, 20, 20]).
  double lab_white_offset_b = 0.0;
  bool previous_frame = false;
  double stated_lag = std::numeric_limits<double>::quiet_NaN();
  // A scatter model for the fit: in the job (`scatter_in_job`) or in the
  // material file's "scatter" block, with `curve_moves` when not null.
  std::optional<ScatterModel> scatter;
  bool scatter_in_job = true;
  nlohmann::json curve_moves = nullptr;
  std::string bounds =
      R"({"rotation_deg": [[-5, 5], [15, 35], [-5, 5]], "centre_mm": [[-30, 30], [-30, 30], [470, 530]]})";
  std::string dimension_bounds = "{}";
  std::string acceptance;  // the job's "acceptance" object when not empty
  // A third radiograph, "c", rotated (its own pose), when given; the job's
  // "refine_material" when not empty; the material file's transmission
  // uncertainty when not NaN.
  std::optional<Pose> rotated;
  std::string refine_material;
  double material_uncertainty = std::numeric_limits<double>::quiet_NaN();
  // When not 0: dark and flat frames whose open beam slopes by this much
  // per mm along u, the raw radiographs dark + I (flat - dark).
  double flat_slope_per_mm = 0.0;
  // With `rotated`: the job names "c_before.tif" as c's previous frame, a
  // shot of the part with its sizes scaled by `rotated_previous_scale` at
  // `rotated_previous_pose` (c's pose when not given, where a scale below 1
  // puts its edges inside c's shadow), of which c records `rotated_lab_lag`.
  bool rotated_previous_frame = false;
  double rotated_previous_scale = 1.0;
  std::optional<Pose> rotated_previous_pose;
  double rotated_lab_lag = 0.0;
  // When not empty: the detector characterisation file's text, written as
  // detector.json and named by the machine's detector.characterization.
  std::string detector_file;
};

class Uncertainty : public ::testing::Test {
 protected:
  void SetUp() override {
    setProgressEnabled(false);
    dir_ = fs::temp_directory_path() /
           ("xgauge_uncertainty_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // Renders the scene, writes its job and measures it with the final
  // least-squares stage only, from the true parameters.
  MeasurementResult measureScene(const Scene& s) {
    Machine lab = s.machine;
    lab.source_detector_distance_mm += s.lab_distance_offset_mm;
    Machine stated = s.machine;
    stated.lag_fraction = s.stated_lag;
    nlohmann::json machine = stated.toJson();
    if (!s.detector_file.empty()) {
      std::ofstream(dir_ / "detector.json") << s.detector_file;
      machine["detector"]["characterization"] = "detector.json";
    }
    std::ofstream(dir_ / "machine.json") << machine.dump();
    nlohmann::json material = s.material.toJson();
    if (!std::isnan(s.material_uncertainty))
      material["uncertainty"]["transmission"] = s.material_uncertainty;
    std::string job_scatter;
    if (s.scatter && s.scatter_in_job) {
      job_scatter = R"("scatter": )" + s.scatter->toJson().dump() + ",";
    } else if (s.scatter) {
      material["scatter"] = s.scatter->toJson();
      if (!s.curve_moves.is_null()) material["scatter"]["curve_moves"] = s.curve_moves;
    }
    std::ofstream(dir_ / "material.json") << material.dump();
    const PartModel part = PartModel::load(s.part_file);
    const TriangleMesh mesh = part.mesh(part.values(s.truth));
    Pose b = s.a;
    b.translation_mm += 30.0 * s.axis;
    const auto table =
        TransmissionTable::forMaterial(s.material.withScaledRates(s.lab_rate_scale), 200.0);
    // 2 x 2 samples with the edges 8 x 8, as the final stage renders
    // (schedule.h): a sampled image's walls sit up to a quarter pixel off
    // where a finer one puts them.
    RenderOptions options;
    options.samples_per_axis = 2;
    options.edge_samples_per_axis = 8;
    std::mt19937_64 rng(s.seed);
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::vector<Vec3> world;
    Image previous;
    std::vector<std::pair<std::string, Pose>> shots{{"a", s.a}, {"b", b}};
    if (s.rotated) shots.emplace_back("c", *s.rotated);
    for (const auto& [name, pose] : shots) {
      Image before;  // c's previous frame, when the job names one
      if (name == "c" && s.rotated_previous_frame) {
        std::map<std::string, double> scaled = s.truth;
        for (auto& [dimension, value] : scaled) value *= s.rotated_previous_scale;
        const TriangleMesh smaller = part.mesh(part.values(scaled));
        poseVertices(s.rotated_previous_pose.value_or(pose), smaller.vertices, world);
        renderIntensity(lab, {world, smaller.triangles}, table, options, before);
        for (float& v : before.pixels())
          v = static_cast<float>(static_cast<double>(v) + s.noise * gauss(rng));
        writeTiff(dir_ / "c_before.tif", before, TiffFormat::kFloat32);
      }
      poseVertices(pose, mesh.vertices, world);
      Image image;
      renderIntensity(lab, {world, mesh.triangles}, table, options, image);
      for (int y = 0; y < image.height(); ++y)
        for (int x = 0; x < image.width(); ++x) {
          double v = static_cast<double>(image(x, y)) + s.noise * gauss(rng);
          if (s.blob && name == "a") {
            const auto [bx, by, radius, height] = *s.blob;
            if (std::hypot(x + 0.5 - bx, y + 0.5 - by) <= radius) v += height;
          }
          if (name == "b") v += s.lab_lag * static_cast<double>(previous(x, y));
          if (!before.empty()) v += s.rotated_lab_lag * static_cast<double>(before(x, y));
          if (name == "b" && x >= 2 && x < 22 && y >= 2 && y < 22)
            v += s.lab_white_offset_b;
          image(x, y) = static_cast<float>(v);
        }
      if (name != "c") previous = image;
      // With flat frames the lab adds the job's halo (in a uniform field).
      if (s.flat_slope_per_mm != 0.0 && s.scatter)
        image = s.scatter->apply(std::move(image), s.machine.pitch_u_mm);
      if (s.flat_slope_per_mm != 0.0)
        for (int y = 0; y < image.height(); ++y)
          for (int x = 0; x < image.width(); ++x)
            image(x, y) =
                static_cast<float>(100.0 + static_cast<double>(image(x, y)) * openBeam(s, x));
      writeTiff(dir_ / (name + ".tif"), image, TiffFormat::kFloat32);
    }
    std::string frames;
    if (s.flat_slope_per_mm != 0.0) {
      Image dark(s.machine.columns, s.machine.rows, 100.0f), flat = dark;
      for (int y = 0; y < flat.height(); ++y)
        for (int x = 0; x < flat.width(); ++x)
          flat(x, y) = static_cast<float>(100.0 + openBeam(s, x));
      writeTiff(dir_ / "dark.tif", dark, TiffFormat::kFloat32);
      writeTiff(dir_ / "flat.tif", flat, TiffFormat::kFloat32);
      frames = R"(, "dark": "dark.tif", "flat": "flat.tif")";
    }
    std::ofstream(dir_ / "job.json") << R"({
      "part": ")" + s.part_file + R"(",
      "machine": "machine.json", "material": "material.json", )" +
                                            job_scatter + R"(
      "dimensions": {"bounds": )" + s.dimension_bounds +
                                            R"(},
      "radiographs": [
        {"name": "a", "image": "a.tif", "white_region": [2, 2, 20, 20], "pattern": "free")" +
                                            frames + R"(},
        {"name": "b", "image": "b.tif", "white_region": [2, 2, 20, 20], "pattern": "translated",
         "reference": "a", "distance_mm": 30.0, "distance_uncertainty_mm": 0.01)" +
                                            frames +
                                            (s.previous_frame ? R"(, "previous": "a.tif")" : "") +
                                            R"(})" +
                                            (s.rotated ? R"(,
        {"name": "c", "image": "c.tif", "white_region": [2, 2, 20, 20], "pattern": "rotated",
         "reference": "a")" + frames +
                                                       (s.rotated_previous_frame
                                                            ? R"(, "previous": "c_before.tif")"
                                                            : "") +
                                                       "}"
                                                       : "") +
                                            R"(],
      )" + (s.acceptance.empty() ? std::string() : R"("acceptance": )" + s.acceptance + ",") +
                                            (s.refine_material.empty()
                                                 ? std::string()
                                                 : R"("refine_material": ")" + s.refine_material +
                                                       "\",") +
                                            R"(
      "pose_bounds": )" + s.bounds + R"(})";
    inputs_ = std::make_unique<MeasurementInputs>(loadMeasurementInputs(dir_ / "job.json"));
    model_ = std::make_unique<ForwardModel>(*inputs_);
    // The true parameters: dimensions, the reference centre's world position
    // and angles of a, the axis of b.
    std::vector<double> theta = model_->start();
    const ParameterLayout& p = model_->parameters();
    for (const auto& [name, value] : s.truth) {
      const auto i = static_cast<size_t>(p.index("dim/" + name));
      theta[i] = std::clamp(value, model_->lower()[i], model_->upper()[i]);
    }
    const Vec3 angles = s.a.eulerDeg();
    const Vec3 centre = s.a.apply(model_->referenceCentre());
    for (int k = 0; k < 3; ++k) {
      theta[static_cast<size_t>(p.index(std::string("a/rotation/r") + "xyz"[k]))] = angles[k];
      theta[static_cast<size_t>(p.index(std::string("a/position/") + "xyz"[k]))] = centre[k];
    }
    theta[static_cast<size_t>(p.index("b/axis/azimuth"))] =
        std::atan2(s.axis.z(), s.axis.x()) * kRadToDeg;
    theta[static_cast<size_t>(p.index("b/axis/elevation"))] = std::asin(s.axis.y()) * kRadToDeg;
    if (s.rotated) {
      const Vec3 turned = s.rotated->eulerDeg();
      const Vec3 at = s.rotated->apply(model_->referenceCentre());
      for (int k = 0; k < 3; ++k) {
        theta[static_cast<size_t>(p.index(std::string("c/rotation/r") + "xyz"[k]))] = turned[k];
        theta[static_cast<size_t>(p.index(std::string("c/position/") + "xyz"[k]))] = at[k];
      }
    }
    MeasureOptions least_squares_only;
    least_squares_only.search_poses = false;
    least_squares_only.joint_search = false;
    return measure(*model_, theta, least_squares_only);
  }

  // The scene's open beam (ADU above the dark) at pixel column x.
  static double openBeam(const Scene& s, int x) {
    return 3000.0 *
           (1.0 + s.flat_slope_per_mm * (x + 0.5 - s.machine.cx_px) * s.machine.pitch_u_mm);
  }

  // The measurement again from `nominal`'s parameters with the `moved`
  // inputs (the final least-squares stage only): each dimension must move
  // by `amount` times the component's sensitivity, within 20 %. Returns the
  // largest move predicted.
  static double expectTheResolveMovesAsTheComponentSays(const MeasurementResult& nominal,
                                                        const MeasurementInputs& moved,
                                                        const std::string& name, double amount) {
    ForwardModel model(moved);
    MeasureOptions least_squares_only;
    least_squares_only.search_poses = false;
    least_squares_only.joint_search = false;
    const MeasurementResult result = measure(model, nominal.theta, least_squares_only);
    double largest = 0.0;
    for (size_t k = 0; k < nominal.dimensions.size(); ++k) {
      const std::string& dimension = nominal.dimensions[k].name;
      const double predicted = amount * component(nominal, dimension, name).sensitivity;
      const double actual = result.dimensions[k].value - nominal.dimensions[k].value;
      EXPECT_NEAR(actual, predicted, 0.2 * std::abs(predicted) + 2e-4) << dimension;
      largest = std::max(largest, std::abs(predicted));
    }
    return largest;
  }
  static const UncertaintyComponent& component(const MeasurementResult& r, const std::string& dim,
                                               const std::string& name) {
    for (const auto& d : r.uncertainty.dimensions)
      if (d.name == dim)
        for (const auto& c : d.components)
          if (c.name == name) return c;
    ADD_FAILURE() << "no component " << name << " for " << dim;
    static const UncertaintyComponent none{};
    return none;
  }

  fs::path dir_;
  std::unique_ptr<MeasurementInputs> inputs_;
  std::unique_ptr<ForwardModel> model_;
};

// The fit's Jacobian (the render with derivatives, chained through the part
// model and both poses, the translated one's included) against central
// differences of the residuals, on the pixels where differences with steps
// h and h / 2 agree (elsewhere a sample met an edge within the step; a wall
// seen nearly along the beam makes strips of such steep samples).
TEST_F(Uncertainty, TheFitsJacobianMatchesCentralDifferences) {
  Scene scene;
  scene.noise = 0.005;
  const std::vector<double> theta = measureScene(scene).theta;
  ForwardModel& model = *model_;
  model.setEdgeSamples(0);  // the render with derivatives samples 2 x 2 only
  const std::vector<int> indices = model.jointIndices();
  const std::vector<int> both{0, 1};
  std::vector<double> r, jacobian;
  ASSERT_TRUE(model.residualsAndJacobian(theta, indices, 0, 2, both, r, jacobian));
  std::vector<double> check;
  ASSERT_TRUE(model.residuals(theta, 0, 2, both, check));
  ASSERT_EQ(r, check);  // the same residuals, bit for bit
  // The checker switches the edge refinement off for its renders and back
  // on after (the render with derivatives does not refine).
  model.setEdgeSamples(4);
  const GradientCheck gradients = checkModelGradients(model, theta, indices, both);
  EXPECT_EQ(model.edgeSamples(), 4);
  model.setEdgeSamples(0);
  ASSERT_EQ(gradients.columns.size(), indices.size());
  for (const GradientColumn& c : gradients.columns) {
    // The float images round to about 1e-5 of a column here.
    EXPECT_LT(c.norm_error, 5e-3) << c.name;
    EXPECT_LT(c.kinked, static_cast<long>(r.size()) / 100) << c.name;
    EXPECT_GT(c.pixels, static_cast<long>(r.size()) / 2) << c.name;
  }
  {
    // With the scatter modelled too: its value comes from the same
    // edge-refined coarse render in both (the render with derivatives
    // samples each coarse pixel once, which would differ by up to 1e-4).
    Scene scattered = scene;
    ScatterModel halo;
    halo.weight = 0.1;
    halo.sigma_mm = 20.0;
    scattered.scatter = halo;
    const std::vector<double> at = measureScene(scattered).theta;
    model_->setEdgeSamples(0);
    std::vector<double> rs, js, cs;
    ASSERT_TRUE(model_->residualsAndJacobian(at, model_->jointIndices(), 0, 2, both, rs, js));
    ASSERT_TRUE(model_->residuals(at, 0, 2, both, cs));
    ASSERT_EQ(rs, cs);
    // The same residuals and Jacobian, bit for bit, on one thread (the
    // pixels are assembled in parallel).
    std::vector<double> r1, j1;
    {
      ThreadLimit one(1);
      ASSERT_TRUE(model_->residualsAndJacobian(at, model_->jointIndices(), 0, 2, both, r1, j1));
    }
    EXPECT_EQ(r1, rs);
    EXPECT_EQ(j1, js);
    // In a non-uniform open beam (decision 0041: a steep heel and the
    // machine's cos^3) the halo is K * (I O) / O and a derivative's
    // K * (dI O) / O: the Jacobian still matches central differences.
    for (auto& radiograph : inputs_->radiographs) {
      auto in_field = std::make_shared<PreparedRadiograph>(*radiograph);
      in_field->open_beam = OpenBeamField(inputs_->machine.openBeamGeometry(), 4e-3, -3e-3);
      radiograph = std::move(in_field);
    }
    model_ = std::make_unique<ForwardModel>(*inputs_);
    model_->setEdgeSamples(0);
    std::vector<double> rf, jf, cf;
    ASSERT_TRUE(model_->residualsAndJacobian(at, model_->jointIndices(), 0, 2, both, rf, jf));
    ASSERT_TRUE(model_->residuals(at, 0, 2, both, cf));
    ASSERT_EQ(rf, cf);
    EXPECT_NE(rf, rs);  // the field changes the simulated halo
    model_->setEdgeSamples(4);
    const GradientCheck in_field = checkModelGradients(*model_, at, model_->jointIndices(), both);
    ASSERT_EQ(in_field.columns.size(), model_->jointIndices().size());
    for (const GradientColumn& c : in_field.columns) {
      EXPECT_LT(c.norm_error, 5e-3) << c.name;
      EXPECT_GT(c.pixels, static_cast<long>(rf.size()) / 2) << c.name;
    }
  }
}

TEST_F(Uncertainty, TheStatisticalPartMatchesTheSpreadOverNoise) {
  // 16 noise draws: the standard deviation of each size over them against
  // the mean statistical standard uncertainty the budget reports. With 16
  // draws the sample deviation itself is uncertain by about 18 %.
  std::map<std::string, std::vector<double>> values, reported;
  Scene scene;
  scene.noise = 0.01;
  for (uint64_t seed = 1; seed <= 16; ++seed) {
    scene.seed = seed;
    const MeasurementResult r = measureScene(scene);
    for (const auto& d : r.dimensions) {
      values[d.name].push_back(d.value);
      reported[d.name].push_back(component(r, d.name, "statistical").contribution);
    }
  }
  for (const auto& [name, v] : values) {
    double mean = 0.0, u = 0.0;
    for (double x : v) mean += x / static_cast<double>(v.size());
    double ss = 0.0;
    for (double x : v) ss += (x - mean) * (x - mean);
    const double spread = std::sqrt(ss / static_cast<double>(v.size() - 1));
    for (double x : reported[name]) u += x / static_cast<double>(v.size());
    // Known shortfall: along a weakly determined direction (here the box's
    // depth and height against its distance from the source, seen by a
    // translated pair) the fit's finite-difference Gauss-Newton steps stop
    // at slightly different points of a curved valley for each noise draw,
    // and the linear covariance gives about half of the spread seen
    // (measured: size_y 0.41, size_z 0.50 of it; size_x, across the beam
    // and the translation, 0.9). The bound below catches a budget that loses
    // its statistical part or inflates it; the analytic-derivative issue
    // is expected to close the gap.
    const double floor = name == "size_x" ? 0.6 : 0.35;
    EXPECT_GT(u / spread, floor) << name << ": reported " << u << ", spread " << spread;
    EXPECT_LT(u / spread, 1.6) << name << ": reported " << u << ", spread " << spread;
    // And the fit is unbiased: the mean is within 3 standard errors.
    EXPECT_NEAR(mean, scene.truth.at(name), 3.0 * spread / 4.0 + 1e-4) << name;
  }
}

TEST_F(Uncertainty, AnInfluenceMovesTheResultAsItsReSolveSays) {
  // Radiographs taken with a source-detector distance 2 mm longer than the
  // machine file says: the fit moves each size by about -(2 / u) times the
  // budget's component for D + u (u = 0.5 mm); likewise for a material whose
  // rates are 1 % higher than the material file's.
  Scene clean;
  const MeasurementResult nominal = measureScene(clean);
  Scene far = clean;
  far.lab_distance_offset_mm = 2.0;
  const MeasurementResult moved = measureScene(far);
  Scene dense = clean;
  dense.lab_rate_scale = 0.01;
  const MeasurementResult darker = measureScene(dense);
  const double scale_u =
      clean.material.rateScaleFor(clean.material.transmissionUncertainty(), model_->partSizeMm());
  ASSERT_GT(scale_u, 0.0);
  for (size_t k = 0; k < nominal.dimensions.size(); ++k) {
    const std::string& name = nominal.dimensions[k].name;
    EXPECT_NEAR(nominal.dimensions[k].value, clean.truth.at(name), 2e-3) << name;
    const UncertaintyComponent& d = component(nominal, name, "source-detector distance");
    const double predicted = -2.0 * d.sensitivity;
    const double actual = moved.dimensions[k].value - nominal.dimensions[k].value;
    EXPECT_NEAR(actual, predicted, 0.15 * std::abs(predicted) + 2e-3) << name;
    const UncertaintyComponent& m = component(nominal, name, "material");
    // The component is for rates scaled by scale_u, the data's by 1 %.
    const double predicted_m = -(0.01 / scale_u) * m.sensitivity * m.standard_uncertainty;
    const double actual_m = darker.dimensions[k].value - nominal.dimensions[k].value;
    // size_y lies along a weakly determined direction: where the measurement
    // of the darker radiographs stops along it differs from the linearised
    // prediction by up to 0.003 mm (0.0075 pixels at the part).
    EXPECT_NEAR(actual_m, predicted_m, 0.15 * std::abs(predicted_m) + (name == "size_y" ? 3e-3 : 2e-3))
        << name;
  }
  // The translation's component is for the job's stated uncertainty.
  EXPECT_EQ(component(nominal, "size_x", "translation b").standard_uncertainty, 0.01);
  // The thickness along the beam moves with the material, the sides across
  // it hardly: the budget must tell them apart.
  EXPECT_GT(component(nominal, "size_z", "material").contribution,
            5.0 * component(nominal, "size_y", "material").contribution);
}

// The material's curve refined in situ (job "refine_material": "rate_scale"):
// radiographs taken with every rate 0.65 % higher than the material file's
// (about 2 of the prior's standard uncertainties, which the file's u = 0.001
// gives), the pair plus a shot turned by 40 degrees. Without the refinement
// the size along the beam (size_z) takes the curve's error; with it, the
// edges of the turned shot decide, the rate scale comes out within 3 of its
// standard uncertainties of the lab's, every size moves at least three times
// closer to the truth, and the material's component of size_z shrinks as
// much (the fit absorbs the curve's scale). With a prior 50 times tighter
// the rate scale is held back, inside its bounds, and size_z keeps the
// error. A refinement without a view from another direction, without the
// material's uncertainty or with an unknown name is refused naming the key.
TEST_F(Uncertainty, TheMaterialRefinedInSituTakesTheCurveErrorOffTheDepth) {
  Scene scene;
  scene.noise = 0.002;
  scene.lab_rate_scale = 0.0065;
  scene.rotated = Pose::fromEulerDeg({-1.0, 65.0, 2.0}, {4.0, -2.0, 505.0});
  scene.bounds =
      R"({"rotation_deg": [[-5, 5], [15, 75], [-5, 5]], "centre_mm": [[-30, 30], [-30, 30], [470, 530]]})";
  const MeasurementResult plain = measureScene(scene);
  EXPECT_FALSE(plain.uncertainty.refinement.has_value());
  scene.refine_material = "rate_scale";
  const MeasurementResult refined = measureScene(scene);
  ASSERT_TRUE(refined.uncertainty.refinement.has_value());
  const MaterialRefinementResult& e = *refined.uncertainty.refinement;
  const double prior = scene.material.rateScaleFor(scene.material.transmissionUncertainty(),
                                                   model_->partSizeMm());
  EXPECT_NEAR(e.prior_standard_uncertainty, prior, 1e-12);
  EXPECT_GT(e.standard_uncertainty, 0.0);
  EXPECT_LT(e.standard_uncertainty, 0.5 * prior);  // the radiographs, not the prior, decide
  EXPECT_NEAR(e.rate_scale, scene.lab_rate_scale, 3.0 * e.standard_uncertainty + 1e-4);
  // The curve's change as reported: the refined curve against the file's.
  EXPECT_LT(e.transmission_change, 0.0);  // higher rates: a darker curve
  EXPECT_NEAR(e.transmission_change,
              scene.material.withScaledRates(e.rate_scale).transmission(e.at_path_mm) -
                  scene.material.transmission(e.at_path_mm),
              1e-12);
  double worst_plain = 0.0, worst_refined = 0.0;
  for (size_t k = 0; k < plain.dimensions.size(); ++k) {
    const std::string& name = plain.dimensions[k].name;
    const double before = std::abs(plain.dimensions[k].value - scene.truth.at(name));
    const double after = std::abs(refined.dimensions[k].value - scene.truth.at(name));
    worst_plain = std::max(worst_plain, before), worst_refined = std::max(worst_refined, after);
    EXPECT_LT(after, std::max(before / 3.0, 2e-3)) << name << ": " << before << " -> " << after;
    ASSERT_TRUE(refined.dimensions[k].expanded_uncertainty) << name;
    EXPECT_LT(after, *refined.dimensions[k].expanded_uncertainty) << name;
  }
  EXPECT_GT(worst_plain, 0.02);  // the curve's error shows without the refinement
  EXPECT_LT(component(refined, "size_z", "material").contribution,
            component(plain, "size_z", "material").contribution / 3.0);
  // The rate scale is a parameter of the fit, reported with the curve.
  bool warned = false;
  for (const std::string& w : refined.check.warnings)
    warned |= w.find("material refined in situ") != std::string::npos;
  EXPECT_EQ(warned, std::abs(e.rate_scale) > 3.0 * prior);

  // A prior 50 times tighter (the material states u = 2e-5): the prior
  // holds e back.
  Scene tight = scene;
  tight.material_uncertainty = 2e-5;
  const MeasurementResult held = measureScene(tight);
  ASSERT_TRUE(held.uncertainty.refinement.has_value());
  const MaterialRefinementResult& h = *held.uncertainty.refinement;
  EXPECT_NEAR(h.prior_standard_uncertainty, prior / 50.0, 1e-12);
  // Towards the data, but held well inside its bounds (6 priors), where it
  // would sit without the prior.
  EXPECT_GT(h.rate_scale, h.prior_standard_uncertainty);
  EXPECT_LT(h.rate_scale, 4.5 * h.prior_standard_uncertainty);
  // The curve's error the prior holds back stays in the depth.
  const auto errorOf = [&](const MeasurementResult& r, const std::string& name) {
    for (const auto& d : r.dimensions)
      if (d.name == name) return d.value - scene.truth.at(name);
    ADD_FAILURE() << "no dimension " << name;
    return 0.0;
  };
  EXPECT_GT(std::abs(errorOf(held, "size_z")), 3.0 * std::abs(errorOf(refined, "size_z")));
  bool held_warned = false;
  for (const std::string& w : held.check.warnings)
    held_warned |= w.find("material refined in situ") != std::string::npos;
  EXPECT_EQ(held_warned, std::abs(h.rate_scale) > 3.0 * h.prior_standard_uncertainty);

  // Each refused before any fit, with a message that names what is wrong.
  const auto expectRefused = [&](const Scene& bad, std::vector<std::string> fragments) {
    try {
      measureScene(bad);
      ADD_FAILURE() << "accepted; expected " << fragments.front();
    } catch (const Error& error) {
      for (const std::string& fragment : fragments)
        EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    }
  };
  Scene pair_only = scene;
  pair_only.rotated.reset();
  expectRefused(pair_only, {"/refine_material", "another direction"});
  Scene unstated = scene;
  unstated.material_uncertainty = 0.0;
  expectRefused(unstated, {"/refine_material", "material.json states none"});
  Scene misspelt = scene;
  misspelt.refine_material = "rate-scale";
  expectRefused(misspelt, {"unknown refinement 'rate-scale'"});
}

// Radiograph b records 1 % of a's signal (a is its previous frame). Named
// as b's previous frame, a's lag is estimated (within three standard
// uncertainties of 1 %), subtracted, and its uncertainty enters the budget
// as "detector lag b", whose sensitivity predicts how far the result moves
// when the machine states a fraction off the estimate by 10 u.
TEST_F(Uncertainty, TheLagOfThePreviousFrameIsEstimatedSubtractedAndBudgeted) {
  Scene lagging;
  lagging.noise = 0.003;
  lagging.lab_lag = 0.01;
  const MeasurementResult ignored = measureScene(lagging);
  lagging.previous_frame = true;
  const MeasurementResult corrected = measureScene(lagging);
  ASSERT_TRUE(inputs_->radiographs[1]->lag.has_value());
  EXPECT_FALSE(inputs_->radiographs[0]->lag.has_value());
  const LagEstimate lag = *inputs_->radiographs[1]->lag;
  EXPECT_GT(lag.uncertainty, 0.0);
  EXPECT_NEAR(lag.fraction, 0.01, 3.0 * lag.uncertainty);
  double worst_ignored = 0.0, worst_corrected = 0.0;
  for (size_t k = 0; k < corrected.dimensions.size(); ++k) {
    const std::string& name = corrected.dimensions[k].name;
    worst_ignored = std::max(worst_ignored, std::abs(ignored.dimensions[k].value - lagging.truth.at(name)));
    worst_corrected =
        std::max(worst_corrected, std::abs(corrected.dimensions[k].value - lagging.truth.at(name)));
  }
  EXPECT_LT(worst_corrected, 0.5 * worst_ignored) << worst_corrected << " against " << worst_ignored;

  lagging.stated_lag = lag.fraction + 3.0 * lag.uncertainty;
  const MeasurementResult stated = measureScene(lagging);
  ASSERT_TRUE(inputs_->radiographs[1]->lag.has_value());
  // The machine's fraction is budgeted too, with a tenth of itself when the
  // machine states no uncertainty; its sensitivity is the estimate's.
  EXPECT_TRUE(inputs_->radiographs[1]->lag->stated);
  EXPECT_DOUBLE_EQ(inputs_->radiographs[1]->lag->uncertainty, 0.1 * lagging.stated_lag);
  for (size_t k = 0; k < corrected.dimensions.size(); ++k) {
    const std::string& name = corrected.dimensions[k].name;
    const UncertaintyComponent& c = component(corrected, name, "detector lag b");
    EXPECT_EQ(c.standard_uncertainty, lag.uncertainty);
    const double predicted = 3.0 * c.sensitivity * lag.uncertainty;
    const double actual = stated.dimensions[k].value - corrected.dimensions[k].value;
    EXPECT_NEAR(actual, predicted, 0.2 * std::abs(predicted) + 1e-3) << name;
    const UncertaintyComponent& s = component(stated, name, "detector lag b");
    EXPECT_EQ(s.standard_uncertainty, 0.1 * lagging.stated_lag);
    EXPECT_NEAR(s.sensitivity, c.sensitivity, 0.1 * std::abs(c.sensitivity) + 0.01) << name;
  }
}

// A triple whose rotated shot's previous frame hides its edges: c names as
// its previous frame a shot of a part 0.7 times the size at c's own pose,
// of which it records 0.4 %. That frame's edges all lie in c's shadow, so
// the pair cannot tell the lag (the same frame at a's pose, its edges in
// c's open beam, tells it: 0.0030 +- 0.0006). On a machine whose detector
// characterisation states no lag the job is refused, naming c, its
// previous frame, the machine's lag_fraction and xgauge characterize; with
// the same machine and a characterisation stating lag_fraction 0.004 +-
// 0.0002, exactly that fraction of c_before.tif is subtracted from c as the
// machine's, budgeted as "detector lag c", and every size comes out within
// its expanded uncertainty of the truth.
TEST_F(Uncertainty,
       ATripleWhoseRotatedShotsPreviousFrameHidesItsEdgesMeasuresWithTheCharacterisedLag) {
  Scene scene;
  scene.noise = 0.002;
  scene.rotated = Pose::fromEulerDeg({-1.0, 65.0, 2.0}, {4.0, -2.0, 505.0});
  scene.bounds =
      R"({"rotation_deg": [[-5, 5], [15, 75], [-5, 5]], "centre_mm": [[-30, 30], [-30, 30], [470, 530]]})";
  scene.rotated_previous_frame = true;
  scene.rotated_previous_scale = 0.7;
  scene.rotated_lab_lag = 0.004;
  scene.detector_file = "{}";  // a characterisation without a lag pair
  const std::string shot = (dir_ / "c.tif").string(), before = (dir_ / "c_before.tif").string();

  // The control: the previous frame's edges in c's open beam tell the lag.
  Scene visible = scene;
  visible.rotated_previous_pose = scene.a;
  measureScene(visible);
  ASSERT_TRUE(inputs_->radiographs[2]->lag.has_value());
  const LagEstimate told = *inputs_->radiographs[2]->lag;
  EXPECT_FALSE(told.stated);
  EXPECT_LE(told.uncertainty, kMaxLagUncertainty);
  EXPECT_NEAR(told.fraction, 0.004, 3.0 * told.uncertainty);

  try {
    measureScene(scene);
    ADD_FAILURE() << "expected the lag of c's previous frame to be refused";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind(shot + ": the lag of its previous frame " + before +
                                " cannot be told from the pair",
                            0),
              0u)
        << message;
    EXPECT_NE(message.find("lag_fraction"), std::string::npos) << message;
    EXPECT_NE(message.find("xgauge characterize"), std::string::npos) << message;
  }

  scene.detector_file = R"({"lag_fraction": {"value": 0.004, "uncertainty": 0.0002}})";
  const MeasurementResult result = measureScene(scene);
  EXPECT_EQ(inputs_->machine.lag_fraction, 0.004);
  EXPECT_EQ(inputs_->machine.lag_fraction_uncertainty, 0.0002);
  ASSERT_EQ(inputs_->radiographs.size(), 3u);
  EXPECT_FALSE(inputs_->radiographs[0]->lag.has_value());
  EXPECT_FALSE(inputs_->radiographs[1]->lag.has_value());
  const PreparedRadiograph& c = *inputs_->radiographs[2];
  ASSERT_TRUE(c.lag.has_value());
  EXPECT_EQ(c.lag->fraction, 0.004);
  EXPECT_EQ(c.lag->uncertainty, 0.0002);
  EXPECT_TRUE(c.lag->stated);
  EXPECT_EQ(describeLag(*c.lag), "fraction 0.00400 +- 0.0002 (the machine's)");
  EXPECT_FALSE(c.lag_signal_levels.empty());  // kept for the budget
  // The prepared image is c less 0.004 of c_before.tif, over its white
  // region's mean; without the subtraction it would differ by 2e-3 in the
  // shadow of c that c_before.tif's smaller part leaves open.
  Image expected = readTiff(shot);
  const Image previous = readTiff(before);
  subtractLag(expected, previous, 0.004);
  const double white = meanOf(expected, PixelRect{2, 2, 20, 20});
  Image unsubtracted = readTiff(shot);
  const double unsubtracted_white = meanOf(unsubtracted, PixelRect{2, 2, 20, 20});
  double worst = 0.0, lag_shows = 0.0;
  for (int y = 0; y < expected.height(); ++y)
    for (int x = 0; x < expected.width(); ++x) {
      const double e = static_cast<double>(expected(x, y)) / white;
      worst = std::max(worst, std::abs(static_cast<double>(c.levels[0](x, y)) - e));
      lag_shows = std::max(
          lag_shows, std::abs(static_cast<double>(unsubtracted(x, y)) / unsubtracted_white - e));
    }
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(lag_shows, 1e-3);
  for (const auto& dimension : result.dimensions) {
    const UncertaintyComponent& lag = component(result, dimension.name, "detector lag c");
    EXPECT_EQ(lag.standard_uncertainty, 0.0002) << dimension.name;
    ASSERT_TRUE(dimension.expanded_uncertainty) << dimension.name;
    EXPECT_LT(std::abs(dimension.value - scene.truth.at(dimension.name)),
              *dimension.expanded_uncertainty)
        << dimension.name;
  }
}

// Each radiograph is divided by its white region's mean, whose noise is an
// error common to every pixel: a component "normalisation NAME" with the
// mean's relative standard uncertainty (the region's 400 pixels of noise
// sigma 0.003: 1.5e-4), whose sensitivity predicts how far the result moves
// when b's white region reads 0.3 % (20 u) brighter than its part sees.
TEST_F(Uncertainty, TheWhiteRegionsMeanIsAComponentOfItsOwn) {
  Scene noisy;
  noisy.noise = 0.003;
  const MeasurementResult nominal = measureScene(noisy);
  const double u = inputs_->radiographs[1]->white_mean_uncertainty;
  EXPECT_NEAR(u, 0.003 / 20.0, 0.15 * 0.003 / 20.0);
  Scene brighter = noisy;
  brighter.lab_white_offset_b = 0.003;
  const MeasurementResult moved = measureScene(brighter);
  for (size_t k = 0; k < nominal.dimensions.size(); ++k) {
    const std::string& name = nominal.dimensions[k].name;
    const UncertaintyComponent& c = component(nominal, name, "normalisation b");
    EXPECT_EQ(c.standard_uncertainty, u);
    EXPECT_EQ(c.unit, "relative");
    EXPECT_GT(component(nominal, name, "normalisation a").standard_uncertainty, 0.0);
    const double predicted = 0.003 * c.sensitivity;
    const double actual = moved.dimensions[k].value - nominal.dimensions[k].value;
    // size_y: the weakly determined direction of the test above (measured
    // 0.0015 from the prediction).
    EXPECT_NEAR(actual, predicted, 0.2 * std::abs(predicted) + (name == "size_y" ? 3e-3 : 1e-3))
        << name;
  }
  // The thickness along the beam moves with the intensity; it moved.
  EXPECT_GT(std::abs(0.003 * component(nominal, "size_z", "normalisation b").sensitivity), 0.01);
  // Noise-free radiographs have an exact mean: no such component.
  const MeasurementResult clean = measureScene(Scene{});
  for (const auto& d : clean.uncertainty.dimensions)
    for (const auto& c : d.components) EXPECT_NE(c.name.rfind("normalisation", 0), 0u) << c.name;
}

// A flat frame whose open beam slopes by 3 % across the panel: the flat
// cannot say whether that is the tube's heel (which the halo spreads) or
// the panel's gain (which it does not), the field carries half of it and
// the budget's "open beam's heel" (u = 1 / sqrt(12) of the slope) predicts
// how far each size moves when the field carries all of it. Without flat
// frames the field is uniform and the budget has no such component.
TEST_F(Uncertainty, TheFlatsSlopeThatMayBeTheHeelIsInTheBudget) {
  Scene scene;
  scene.scatter = ScatterModel{};
  scene.scatter->weight = 0.15, scene.scatter->sigma_mm = 30.0;
  scene.flat_slope_per_mm = 2.5e-4;
  const MeasurementResult half = measureScene(scene);
  for (const auto& radiograph : inputs_->radiographs)
    EXPECT_NEAR(radiograph->open_beam.heelUPerMm(), 0.5 * scene.flat_slope_per_mm, 2e-6);
  MeasurementInputs whole = *inputs_;
  for (auto& radiograph : whole.radiographs) {
    auto moved = std::make_shared<PreparedRadiograph>(*radiograph);
    moved->open_beam = moved->open_beam.withHeelShare(1.0);
    radiograph = std::move(moved);
  }
  for (const auto& d : half.dimensions)
    EXPECT_NEAR(component(half, d.name, "open beam's heel").standard_uncertainty,
                1.0 / std::sqrt(12.0), 1e-12);
  // The slope matters to the sizes.
  EXPECT_GT(expectTheResolveMovesAsTheComponentSays(half, whole, "open beam's heel", 0.5), 1e-3);
  // Radiographs that share their dark and flat share one fitted field
  // (loadRadiographs); one that names another flat gets that flat's.
  {
    Image level(scene.machine.columns, scene.machine.rows, 101.0f);
    writeTiff(dir_ / "flat_level.tif", level, TiffFormat::kFloat32);
    nlohmann::json job = nlohmann::json::parse(std::ifstream(dir_ / "job.json"));
    job["radiographs"][1]["flat"] = "flat_level.tif";
    std::ofstream(dir_ / "job_two_flats.json") << job.dump();
    const MeasurementInputs two = loadMeasurementInputs(dir_ / "job_two_flats.json");
    EXPECT_NEAR(two.radiographs[0]->open_beam.heelUPerMm(), 0.5 * scene.flat_slope_per_mm, 2e-6);
    EXPECT_NEAR(two.radiographs[1]->open_beam.heelUPerMm(), 0.0, 1e-9);
  }
  Scene uniform = scene;
  uniform.flat_slope_per_mm = 0.0;
  const MeasurementResult plain = measureScene(uniform);
  for (const auto& d : plain.uncertainty.dimensions)
    for (const auto& c : d.components) EXPECT_NE(c.name, "open beam's heel");
}

// A scatter the job takes from its material, whose file says how the curve
// moves with it: the budget's scatter weight component moves both, which
// to first order is the sum of the two moved alone, and the material
// component keeps only the curve's uncertainty besides the scatter. Both
// are propagated linearly (budget.cpp), so the sum holds on every size,
// size_y's weakly determined one included.
TEST_F(Uncertainty, TheScatterAndTheCurveItCalibratedMoveTogether) {
  Scene apart;
  apart.scatter = ScatterModel{};
  apart.scatter->weight = 0.05, apart.scatter->sigma_mm = 20.0;
  apart.scatter->weight_uncertainty = 0.01, apart.scatter->sigma_uncertainty_mm = 0.0;
  const MeasurementResult independent = measureScene(apart);
  const double scale =
      apart.material.rateScaleFor(apart.material.transmissionUncertainty(), model_->partSizeMm());
  ASSERT_GT(scale, 0.0);
  Scene together = apart;
  together.scatter_in_job = false;
  ScatterCurves curves;
  curves.weight_plus_u = apart.material.withScaledRates(scale);
  curves.transmission_uncertainty_besides = 0.2 * apart.material.transmissionUncertainty();
  together.curve_moves = curves.toJson();
  const MeasurementResult correlated = measureScene(together);
  ASSERT_TRUE(inputs_->scatter_curves.has_value());
  for (size_t k = 0; k < correlated.dimensions.size(); ++k) {
    const std::string& name = correlated.dimensions[k].name;
    const UncertaintyComponent& w = component(independent, name, "scatter weight");
    const UncertaintyComponent& m = component(independent, name, "material");
    const UncertaintyComponent& both = component(correlated, name, "scatter weight");
    const double sum = w.sensitivity * w.standard_uncertainty + m.sensitivity * m.standard_uncertainty;
    EXPECT_NEAR(both.sensitivity * both.standard_uncertainty, sum, 0.15 * std::abs(sum) + 2e-4)
        << name << ": weight " << w.sensitivity * w.standard_uncertainty << ", material "
        << m.sensitivity * m.standard_uncertainty;
    EXPECT_NEAR(component(correlated, name, "material").contribution, 0.2 * m.contribution,
                0.05 * m.contribution + 1e-4)
        << name;
  }
  // A characterised detector whose halo the material was calibrated with
  // (the same kernel in its detector file and in the material's scatter):
  // the job takes the detector's halo and moves it with the curve, as above.
  Scene characterised = together;
  characterised.detector_file =
      nlohmann::json{{"halo", {{"scatter", apart.scatter->toJson()}}}}.dump();
  const MeasurementResult same = measureScene(characterised);
  ASSERT_TRUE(inputs_->scatter_curves.has_value());
  for (const auto& d : correlated.dimensions)
    EXPECT_NEAR(component(same, d.name, "scatter weight").contribution,
                component(correlated, d.name, "scatter weight").contribution, 1e-9)
        << d.name;
  // The same kernel stated with another u than the calibration moved the
  // curve by: apart, as is another halo.
  auto expectApart = [&](const ScatterModel& halo) {
    characterised.detector_file = nlohmann::json{{"halo", {{"scatter", halo.toJson()}}}}.dump();
    measureScene(characterised);
    EXPECT_FALSE(inputs_->scatter_curves.has_value());
  };
  ScatterModel restated = *apart.scatter;
  restated.weight_uncertainty = 0.02;
  expectApart(restated);
  ScatterModel other = *apart.scatter;
  other.weight = 0.06;
  expectApart(other);
}

// A two-width halo with its kernel's end (image/scatter.h): a component of
// its own, the end's shift scaled to the equivalent width's u. Two ends at
// different distances standing for the same u give about the same
// component (the shift is about linear in the move), which an unscaled move
// would not (their distances differ by a factor of two); without an end,
// none.
TEST_F(Uncertainty, AHalosKernelEndIsAComponentScaledToItsU) {
  Scene scene;
  ScatterModel halo;
  halo.shape = HaloShape::kTwoGauss, halo.border = HaloBorder::kOpen;
  halo.weight = 0.12, halo.sigma_mm = 5.0, halo.sigma2_mm = 30.0, halo.fraction2 = 0.4;
  halo.weight_uncertainty = 0.001, halo.sigma_uncertainty_mm = 0.1;
  scene.scatter = halo;
  const MeasurementResult without = measureScene(scene);
  for (const auto& d : without.uncertainty.dimensions)
    for (const auto& c : d.components) EXPECT_NE(c.name, "scatter kernel") << d.name;
  auto withEnd = [&](double sigma2_mm) {
    Scene s = scene;
    HaloKernelEnd end;
    end.shape = HaloShape::kTwoGauss, end.weight = halo.weight, end.sigma_mm = halo.sigma_mm, end.sigma2_mm = sigma2_mm;
    end.fraction2 = halo.fraction2, end.equivalent_sigma_uncertainty_mm = 1.0;
    s.scatter->equivalent_end = end;
    return measureScene(s);
  };
  const MeasurementResult near = withEnd(33.0), far = withEnd(36.0);
  // The ends lie 1.6 and 3.2 mm beyond sigma_eq (17.0 mm): the halo's
  // change is not quite linear over that (a tenth between them), against a
  // factor of two unscaled.
  double largest = 0.0;
  for (const auto& d : far.uncertainty.dimensions)
    largest = std::max(largest, component(far, d.name, "scatter kernel").contribution);
  int sizeable = 0;
  for (const auto& d : near.uncertainty.dimensions) {
    const UncertaintyComponent& a = component(near, d.name, "scatter kernel");
    const UncertaintyComponent& b = component(far, d.name, "scatter kernel");
    EXPECT_NEAR(a.contribution, b.contribution, 0.15 * largest) << d.name;
    EXPECT_DOUBLE_EQ(a.standard_uncertainty, 1.0) << d.name;
    if (b.contribution > 1e-3) ++sizeable;
  }
  EXPECT_GT(sizeable, 0);
  // The other kernel (a tail of the same second moment's order): a
  // component of its own, its whole difference standing for its u, so a u
  // twice that difference doubles it.
  auto withChoice = [&](double scale) {
    Scene s = scene;
    HaloKernelEnd other;
    other.shape = HaloShape::kGaussExp, other.weight = halo.weight, other.sigma_mm = 5.0;
    other.tail_fraction = 0.4, other.tail_length_mm = 12.0;
    const double reach = halo.as(other).equivalentSigmaMm() - halo.equivalentSigmaMm();
    other.equivalent_sigma_uncertainty_mm = scale * std::abs(reach);
    s.scatter->kernel_choice = other;
    return measureScene(s);
  };
  const MeasurementResult once = withChoice(1.0), twice = withChoice(2.0);
  for (const auto& d : once.uncertainty.dimensions)
    EXPECT_NEAR(component(twice, d.name, "scatter kernel choice").contribution,
                2.0 * component(once, d.name, "scatter kernel choice").contribution,
                1e-9 + 1e-6 * component(once, d.name, "scatter kernel choice").contribution)
        << d.name;
}

// A material whose file lists how its curve moves with the inputs of its
// calibration (a wedge's caliper dimensions): each move of at least a tenth
// of the largest is a component of its own, propagated with its own curve,
// and the rest of the curve's u is the "material" component as before, the
// smaller moves folded into it. Here the listed curve is the one a scale of
// the rates gives, so its component must be the material component of the
// same material without moves; the rest, half of u and a twentieth, scales
// that component by their root sum of squares.
TEST_F(Uncertainty, EachOfTheCurvesMovesIsAComponentOfItsOwn) {
  Scene plain;
  const MeasurementResult without = measureScene(plain);
  const double u = plain.material.transmissionUncertainty();
  const double scale = plain.material.rateScaleFor(u, model_->partSizeMm());
  ASSERT_GT(scale, 0.0);
  Scene listed = plain;
  listed.material.setTransmissionUncertainty(u * std::sqrt(1.0 + 0.25 + 0.0025));
  listed.material.setCurveMoves(
      {{"wedge thin_end", "mm", 0.2, 0.01, u, plain.material.withScaledRates(scale)},
       {"wedge wall", "mm", 9.0, 0.02, 0.05 * u, plain.material.withScaledRates(0.05 * scale)}},
      0.5 * u);
  const MeasurementResult with = measureScene(listed);
  const double rest = std::hypot(0.5, 0.05);
  for (size_t k = 0; k < with.dimensions.size(); ++k) {
    const std::string& name = with.dimensions[k].name;
    EXPECT_EQ(with.dimensions[k].value, without.dimensions[k].value) << name;
    const UncertaintyComponent& m = component(without, name, "material");
    const UncertaintyComponent& thin = component(with, name, "material: wedge thin_end");
    EXPECT_EQ(thin.standard_uncertainty, 0.01);
    EXPECT_EQ(thin.unit, "mm");
    EXPECT_NEAR(thin.sensitivity * thin.standard_uncertainty, m.sensitivity * m.standard_uncertainty,
                1e-9 + 1e-6 * m.contribution)
        << name;
    EXPECT_NEAR(component(with, name, "material").contribution, rest * m.contribution,
                1e-6 + 0.02 * m.contribution)
        << name;
    for (const auto& d : with.uncertainty.dimensions)
      for (const auto& c : d.components) EXPECT_NE(c.name, "material: wedge wall");
  }
}

TEST_F(Uncertainty, TwoEdgesThatMoveWithThePartAreReportedAsTheirSum) {
  // A box whose left and right faces are two dimensions measured from the
  // part origin: moving both by the same amount is a translation of the
  // part, which the pose absorbs exactly. Only their sum, the width, is
  // defined by the radiographs. The part model names it, and a second
  // combination of two well-measured sides.
  std::ofstream(dir_.parent_path() / "xgauge_split_cuboid.json") << R"({
    "description": "a box whose side faces are two dimensions from the origin",
    "dimensions": [
      {"name": "left", "nominal": 10.0, "min": 5.0, "max": 15.0, "unit": "mm"},
      {"name": "right", "nominal": 10.0, "min": 5.0, "max": 15.0, "unit": "mm"},
      {"name": "size_y", "nominal": 30.0, "min": 15.0, "max": 45.0, "unit": "mm"},
      {"name": "size_z", "nominal": 10.0, "min": 5.0, "max": 15.0, "unit": "mm"}],
    "derived": [{"name": "hy", "expr": "size_y / 2"}, {"name": "hz", "expr": "size_z / 2"}],
    "combinations": [{"name": "width", "terms": {"left": 1, "right": 1}},
                     {"name": "section", "terms": {"size_y": 2, "size_z": -2}}],
    "shape": {"type": "extrusion", "plane": ["x", "z"], "axis": "y",
      "profile": [["-left", "-hz"], ["right", "-hz"], ["right", "hz"], ["-left", "hz"]],
      "from": "-hy", "to": "hy"}})";
  Scene scene;
  scene.part_file = (dir_.parent_path() / "xgauge_split_cuboid.json").string();
  scene.truth = {{"left", 10.2}, {"right", 10.4}, {"size_y", 29.4}, {"size_z", 10.3}};
  scene.noise = 0.005;
  const MeasurementResult r = measureScene(scene);
  std::map<std::string, std::optional<double>> u;
  for (const auto& d : r.dimensions) u[d.name] = d.expanded_uncertainty;
  ASSERT_TRUE(u["size_y"].has_value());
  ASSERT_TRUE(u["size_z"].has_value());
  const auto named = [&](const std::string& name) -> const MeasurableCombination* {
    for (const auto& c : r.uncertainty.combinations)
      if (c.name == name) return &c;
    return nullptr;
  };
  // The single edges are not identifiable (found from the vertex
  // velocities: the image Jacobian's finite differences blur the direction);
  // their sum is reported with a small U, once.
  EXPECT_FALSE(u["left"].has_value());
  EXPECT_FALSE(u["right"].has_value());
  const MeasurableCombination* sum = named("width");
  ASSERT_NE(sum, nullptr) << "no combination width";
  EXPECT_EQ(sum->expression, "left + right");
  EXPECT_EQ(std::count_if(r.uncertainty.combinations.begin(), r.uncertainty.combinations.end(),
                          [](const auto& c) { return c.expression == "left + right"; }),
            1);
  EXPECT_NEAR(sum->value, 20.6, std::max(sum->expanded, 2e-3));
  EXPECT_GT(sum->expanded, 0.0);
  EXPECT_LT(sum->expanded, 0.1);
  // 2 size_y - 2 size_z: its value, and a U between what the two sides'
  // errors would give fully correlated and fully anticorrelated.
  const MeasurableCombination* section = named("section");
  ASSERT_NE(section, nullptr) << "no combination section";
  EXPECT_EQ(section->expression, "2 size_y - 2 size_z");
  std::map<std::string, double> value;
  for (const auto& d : r.dimensions) value[d.name] = d.value;
  const double y = value.at("size_y"), z = value.at("size_z");
  EXPECT_NEAR(section->value, 2.0 * y - 2.0 * z, 1e-9);
  EXPECT_NEAR(section->value, 2.0 * (29.4 - 10.3), std::max(section->expanded, 2e-3));
  EXPECT_LE(section->expanded, 2.0 * (*u["size_y"] + *u["size_z"]) + 1e-12);
  EXPECT_GE(section->expanded, 2.0 * std::abs(*u["size_y"] - *u["size_z"]) - 1e-12);
}

// A region in the open beam, far from the part's shadow, is a detector
// effect: reported, but none of its area counts for the failure rule.
TEST_F(Uncertainty, AResidualRegionInTheOpenBeamIsNotThePartsArea) {
  Scene scene;
  scene.noise = 0.005;
  scene.blob = std::array<double, 4>{22.0, 22.0, 4.0, 0.04};  // 10 px off the shadow
  const MeasurementResult r = measureScene(scene);
  ASSERT_EQ(r.check.regions.size(), 1u);
  const ResidualRegion& region = r.check.regions[0];
  EXPECT_LT((region.centre_px - Vec2(22.0, 22.0)).norm(), 4.0);
  EXPECT_GT(region.area_mm2, 0.0);
  EXPECT_EQ(region.part_area_mm2, 0.0);
  EXPECT_EQ(r.check.region_share, 0.0);
  EXPECT_TRUE(std::any_of(r.check.warnings.begin(), r.check.warnings.end(), [](const auto& w) {
    return w.find("in the open beam") != std::string::npos;
  }));
}

TEST_F(Uncertainty, AResidualRegionIsReportedWhereTheImageDiffersAndNowhereElse) {
  Scene clean;
  clean.noise = 0.005;
  const MeasurementResult none = measureScene(clean);
  EXPECT_TRUE(none.check.regions.empty()) << none.check.regions.size() << " regions, first at "
                                          << none.check.regions[0].centre_px.transpose();
  Scene spot = clean;
  spot.blob = std::array<double, 4>{70.0, 85.0, 3.0, 0.04};  // inside the shadow of a
  const MeasurementResult found = measureScene(spot);
  ASSERT_EQ(found.check.regions.size(), 1u);
  const ResidualRegion& region = found.check.regions[0];
  EXPECT_EQ(region.radiograph, "a");
  EXPECT_LT((region.centre_px - Vec2(70.0, 85.0)).norm(), 1.0);
  EXPECT_EQ(region.sign, "brighter");
  EXPECT_TRUE(region.part_mm.has_value());
  EXPECT_NEAR(region.part_area_mm2, region.area_mm2, 1e-9);  // all of it on the shadow
  bool warned = false, says_misfit = false;
  for (const auto& w : found.check.warnings) {
    warned |= w.find("residual region") != std::string::npos;
    says_misfit |= w.find("component \"misfit\"") != std::string::npos;
  }
  EXPECT_TRUE(warned);  // a 0.04 spot on noise 0.005 stands far above kRegionWarnSigmas
  EXPECT_GE(found.check.regions[0].sigmas, kRegionWarnSigmas);
  // The misfit term (budget.h, addMisfitTerm): each identifiable dimension's
  // shift without the region's pixels is a component of its U, and u_c is
  // still the root sum of squares of the components; no regions, no term.
  auto misfitOf = [](const DimensionUncertainty& u) -> const UncertaintyComponent* {
    for (const UncertaintyComponent& c : u.components)
      if (c.name == "misfit") return &c;
    return nullptr;
  };
  int with_term = 0;
  for (const DimensionUncertainty& u : found.uncertainty.dimensions) {
    if (!u.identifiable) continue;
    const UncertaintyComponent* m = misfitOf(u);
    ASSERT_NE(m, nullptr) << u.name;
    ++with_term;
    double squares = 0.0;
    for (const UncertaintyComponent& c : u.components) squares += c.contribution * c.contribution;
    EXPECT_NEAR(u.combined, std::sqrt(squares), 1e-12 * (1.0 + u.combined)) << u.name;
    EXPECT_LT(m->contribution, 0.5) << u.name;  // a 3 px spot moves nothing by half a mm
  }
  EXPECT_GT(with_term, 0);
  // The term is warned about where it is a large share of some dimension's
  // u_c, and only there.
  double share = 0.0;
  for (const DimensionUncertainty& u : found.uncertainty.dimensions)
    if (const UncertaintyComponent* m = misfitOf(u); m && u.combined > 0.0)
      share = std::max(share, m->contribution / u.combined);
  EXPECT_EQ(says_misfit, share > kMisfitWarnShare) << "largest share " << share;
  for (const DimensionUncertainty& u : none.uncertainty.dimensions)
    EXPECT_EQ(misfitOf(u), nullptr) << u.name;
}

// A dimension held 1 mm from the truth by its bounds is no measurement
// (self_check.h, AcceptanceRule): it ends at its bound, residual regions
// cover much of the shadows, every retry fails the same way, and the result
// says so; without the bounds the same radiographs measure, with no warning.
TEST_F(Uncertainty, AParameterAtItsBoundAndAPoorFitAreNotAMeasurement) {
  Scene scene;
  scene.noise = 0.005;
  scene.dimension_bounds = R"({"size_x": [21.6, 22.4]})";  // the truth, 20.6, lies 1 mm below
  const MeasurementResult r = measureScene(scene);
  bool bound = false, regions = false, misfit = false;
  for (const auto& f : r.check.failures) {
    bound |= f.find("size_x") != std::string::npos && f.find("lower bound") != std::string::npos;
    regions |= f.find("residual regions cover") != std::string::npos;
  }
  // The rms residual over the whole roi (1.4 to 1.8 times the noise) is
  // diluted by the pixels the wrong width leaves alone: a warning.
  for (const auto& w : r.check.warnings)
    misfit |= w.find("times what the noise") != std::string::npos;
  EXPECT_EQ(r.status, MeasurementStatus::kNotMeasured);
  EXPECT_EQ(r.attempts, 1 + AcceptanceRule{}.retries);
  for (const MeasuredDimension& d : r.dimensions) EXPECT_FALSE(d.decision.has_value());
  EXPECT_TRUE(bound);
  EXPECT_TRUE(regions);
  EXPECT_TRUE(misfit) << "misfit ratios " << r.check.radiographs[0].misfit_ratio << " "
                      << r.check.radiographs[1].misfit_ratio << ", noise "
                      << r.check.radiographs[0].noise_sigma;
  Scene inside = scene;
  inside.dimension_bounds = "{}";
  const MeasurementResult measured = measureScene(inside);
  EXPECT_EQ(measured.status, MeasurementStatus::kMeasured);
  EXPECT_EQ(measured.attempts, 1);
  for (const auto& f : measured.check.failures) ADD_FAILURE() << "unexpected: " << f;
  for (const auto& w : measured.check.warnings) ADD_FAILURE() << "unexpected: " << w;
}

// A fit the rule passes but that leaves more than retry_misfit_ratio times
// the noise is doubtful (self_check.h, AcceptanceRule): it is tried again
// from other starts, and stays measured when no attempt does better; below
// that ratio it is kept as it is. The width held 1 mm off by its bounds
// leaves 1.4 to 1.8 times the noise; the rule's other tests are off.
TEST_F(Uncertainty, ADoubtfulFitIsTriedAgainFromOtherStarts) {
  Scene scene;
  scene.noise = 0.005;
  scene.dimension_bounds = R"({"size_x": [21.6, 22.4]})";
  // (retry_misfit_ratio, attempts): retried twice below the fit's misfit,
  // kept at once above it.
  for (const auto& [ratio, attempts] : {std::pair{1.3, 3}, std::pair{2.5, 1}}) {
    scene.acceptance = fmt::format(
        R"({{"fail_at_bound": false, "max_region_share": 1.0, "retry_misfit_ratio": {},
            "retries": 2}})",
        ratio);
    const MeasurementResult r = measureScene(scene);
    EXPECT_EQ(r.status, MeasurementStatus::kMeasured) << ratio;
    EXPECT_EQ(r.attempts, attempts) << ratio;
    EXPECT_GT(r.check.worstMisfitRatio(), 1.3) << ratio;
    EXPECT_LT(r.check.worstMisfitRatio(), 2.5) << ratio;
  }
}

TEST_F(Uncertainty, PathsBeyondTheMaterialsCalibratedRangeAreWarnedAbout) {
  // The cuboid (20.6 x 29.4 x 10.3 mm) has paths from 10.3 mm (face on) up
  // to its diagonal; a material calibrated to 5 mm is extrapolated over all
  // of them, one calibrated to 100 mm over none.
  Scene scene;
  scene.material.setCalibratedRange(std::array<double, 2>{0.0, 100.0});
  const MeasurementResult wide = measureScene(scene);
  for (const auto& w : wide.check.warnings) ADD_FAILURE() << "unexpected: " << w;
  for (const RadiographCheck& c : wide.check.radiographs) {
    EXPECT_GT(c.longest_path_mm, 10.3) << c.name;
    EXPECT_LT(c.longest_path_mm, std::sqrt(20.6 * 20.6 + 29.4 * 29.4 + 10.3 * 10.3)) << c.name;
  }
  scene.material.setCalibratedRange(std::array<double, 2>{0.0, 5.0});
  int beyond = 0;
  for (const auto& w : measureScene(scene).check.warnings)
    beyond += w.find("beyond the 5.00 mm the material was calibrated to (the longest: a ") !=
                  std::string::npos &&
              w.find(", b ") != std::string::npos;
  EXPECT_EQ(beyond, 1);  // one warning naming both radiographs
  // Calibrated from 15 mm on: most of the cuboid's paths lie below.
  scene.material.setCalibratedRange(std::array<double, 2>{15.0, 100.0});
  const MeasurementResult high = measureScene(scene);
  int below = 0;
  for (const auto& w : high.check.warnings)
    below += w.find("below the 15.00 mm the material was calibrated from (a ") != std::string::npos;
  EXPECT_EQ(below, 1);
  for (const RadiographCheck& c : high.check.radiographs) EXPECT_GT(c.below_range_fraction, 0.05);
  for (const RadiographCheck& c : wide.check.radiographs) EXPECT_EQ(c.below_range_fraction, 0.0);
}

// The curve beyond its calibrated range (docs/method.md, "The curve beyond
// its calibrated range"). A material whose extrapolation envelope starts
// beyond every path of the part adds nothing: no component, the same U to
// the last bit. One calibrated to 9 mm, with e(x) growing by 2e-4 per mm
// beyond, adds a component to every dimension, and more where it was
// calibrated to 6 mm only (the cuboid's paths at the fit's pixel centres
// reach 11.7 mm). The linear propagation agrees with the "material" component's
// render of a common scale s of the rates, which moves the curve by
// s x I'(x): the same envelope, tabulated from 0 mm, gives the same shifts.
TEST_F(Uncertainty, TheCurveBeyondItsCalibratedRangeIsAComponentOfItsOwn) {
  const std::string kName = "material: curve beyond its calibrated range";
  auto contribution = [&](const MeasurementResult& r, const std::string& dim) {
    for (const auto& d : r.uncertainty.dimensions)
      if (d.name == dim)
        for (const auto& c : d.components)
          if (c.name == kName) return c.contribution;
    return 0.0;
  };
  auto growing = [](double from) {
    std::vector<ExtrapolationPoint> points;
    for (int k = 0; k <= 10; ++k) points.push_back({from + 5.0 * k, 1e-3 * k});
    return points;
  };
  Scene plain;
  plain.material.setCalibratedRange(std::array<double, 2>{0.0, 100.0});
  const MeasurementResult without = measureScene(plain);
  Scene inside = plain;
  inside.material.setExtrapolation(growing(100.0));
  const MeasurementResult within = measureScene(inside);
  ASSERT_EQ(within.uncertainty.dimensions.size(), without.uncertainty.dimensions.size());
  for (size_t k = 0; k < within.uncertainty.dimensions.size(); ++k) {
    const DimensionUncertainty& d = within.uncertainty.dimensions[k];
    EXPECT_EQ(d.expanded, without.uncertainty.dimensions[k].expanded) << d.name;
    EXPECT_EQ(d.components.size(), without.uncertainty.dimensions[k].components.size()) << d.name;
    EXPECT_EQ(contribution(within, d.name), 0.0) << d.name;
  }

  Scene beyond9 = plain;
  beyond9.material.setCalibratedRange(std::array<double, 2>{0.0, 9.0});
  beyond9.material.setExtrapolation(growing(9.0));
  const MeasurementResult at9 = measureScene(beyond9);
  Scene beyond6 = beyond9;
  beyond6.material.setCalibratedRange(std::array<double, 2>{0.0, 6.0});
  beyond6.material.setExtrapolation(growing(6.0));
  const MeasurementResult at6 = measureScene(beyond6);
  for (size_t k = 0; k < at9.uncertainty.dimensions.size(); ++k) {
    const DimensionUncertainty& d = at9.uncertainty.dimensions[k];
    const double c9 = contribution(at9, d.name), c6 = contribution(at6, d.name);
    EXPECT_GT(c9, 0.0) << d.name;
    EXPECT_GT(c6, c9) << d.name;
    const double rest = without.uncertainty.dimensions[k].combined;
    EXPECT_NEAR(d.combined, std::hypot(rest, c9), 1e-9 + 1e-6 * d.combined) << d.name;
    EXPECT_EQ(d.expanded, at9.uncertainty.coverage_factor * d.combined) << d.name;
  }

  // e(x) = s x |I'(x)|, the move of a rate scale s, from 0 mm on.
  const double s =
      plain.material.rateScaleFor(plain.material.transmissionUncertainty(), model_->partSizeMm());
  ASSERT_GT(s, 0.0);
  std::vector<ExtrapolationPoint> scale{{0.0, 0.0}};
  for (int k = 1; k <= 400; ++k) {
    const double x = 0.15 * k;
    scale.push_back({x, s * x * std::abs(plain.material.derivative(x))});
  }
  Scene scaled = plain;
  scaled.material.setCalibratedRange(std::array<double, 2>{0.0, 1e-3});
  scaled.material.setExtrapolation(scale);
  const MeasurementResult both = measureScene(scaled);
  for (const auto& d : both.uncertainty.dimensions) {
    const double rendered = component(both, d.name, "material").contribution;
    const double linear = contribution(both, d.name) * std::sqrt(3.0);
    EXPECT_NEAR(linear, rendered, 1e-6 + 0.02 * rendered) << d.name;
  }
}

}  // namespace
}  // namespace xgauge
