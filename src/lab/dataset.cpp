#include "xgauge/lab/dataset.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/characterization.h"
#include "xgauge/lab/defect.h"
#include "xgauge/lab/detector.h"
#include "xgauge/lab/random.h"
#include "xgauge/lab/spectrum.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <random>

namespace xgauge {

namespace {

// Random-stream purposes (lab/random.h); the detector uses its own.
constexpr uint64_t kFocalSpotStream = 0xf0ca1;

// The acquisition settings of the recipe's "detector" section besides noise.
struct Acquisition {
  int area_samples = 3;
  // m x m samples on the pixels where the n x n image bends (an edge, a
  // silhouette), 0 for none: a detector integrates its pixel's area, and n x n
  // points see an edge-on wall move in steps of 1 / n pixel. Finer than the
  // measurement's own refinement (8) so that the replica is not rendered with
  // the model's approximation.
  int edge_samples = 24;
  double focal_spot_fwhm_mm = 0.0;
  int focal_spot_samples = 1;
  bool scatter = false;
  double scatter_weight = 0.0;
  double scatter_sigma_px = 0.0;
  int flat_frames = 16;
  double heel_gradient = 0.0;
  bool cos3_falloff = false;
  double column_darkening = 0.0;
  DetectorNoiseModel noise;

  static Acquisition fromConfig(const ConfigNode& node) {
    Acquisition a;
    a.area_samples = static_cast<int>(node.get<double>("area_samples", 3.0));
    if (a.area_samples < 1 || a.area_samples > 8) node.at("area_samples").fail("expected 1 to 8");
    if (auto edge = node.find("edge_samples")) {
      a.edge_samples = static_cast<int>(edge->integer(0, 32));
      if (a.edge_samples != 0 && a.edge_samples <= a.area_samples)
        edge->fail(fmt::format("expected 0 or more than area_samples ({})", a.area_samples));
    }
    if (auto spot = node.find("focal_spot")) {
      a.focal_spot_fwhm_mm = spot->at("fwhm_mm").number(0.0, 5.0);
      a.focal_spot_samples = static_cast<int>(spot->at("samples").integer(1, 64));
    }
    if (auto scatter = node.find("scatter")) {
      a.scatter = true;
      a.scatter_weight = scatter->at("weight").number(0.0, 1.0);
      a.scatter_sigma_px = scatter->at("sigma_px").number(0.1, 1e5);
    }
    a.flat_frames = static_cast<int>(node.get<double>("flat_frames", 16.0));
    if (a.flat_frames < 1 || a.flat_frames > 1024)
      node.at("flat_frames").fail("expected 1 to 1024");
    if (auto heel = node.find("heel_gradient")) a.heel_gradient = heel->number(-0.5, 0.5);
    a.cos3_falloff = node.get<bool>("cos3_falloff", false);
    if (auto dark = node.find("column_darkening")) a.column_darkening = dark->number(0.0, 0.1);
    if (auto noise = node.find("noise")) a.noise = DetectorNoiseModel::fromConfig(*noise);
    a.noise.validate();
    return a;
  }
};

// Noise-free intensity of one shot: area sampling, and the focal spot as
// jittered source points (the source moved by s is the part moved by -s with
// the principal point moved by s). Voids move with the part.
Image renderShot(const Machine& machine, const TriangleMesh& mesh, std::span<const Defect> defects,
                 const Pose& pose, const TransmissionTable& table, const Acquisition& acquisition,
                 uint64_t seed, uint64_t shot_index) {
  RenderOptions options;
  options.samples_per_axis = acquisition.area_samples;
  options.edge_samples_per_axis = acquisition.edge_samples;
  std::vector<Vec3> world;
  std::vector<WorldSphere> voids(defects.size());
  const int spots = acquisition.focal_spot_fwhm_mm > 0 ? acquisition.focal_spot_samples : 1;
  const double sigma_mm = acquisition.focal_spot_fwhm_mm / (2.0 * std::sqrt(2.0 * std::log(2.0)));
  SplitMix64 rng = SplitMix64::stream(seed, kFocalSpotStream, shot_index);
  std::normal_distribution<double> gauss(0.0, sigma_mm);
  Image sum, one;
  for (int k = 0; k < spots; ++k) {
    const double sx = spots > 1 ? gauss(rng) : 0.0, sy = spots > 1 ? gauss(rng) : 0.0;
    Machine shifted = machine;
    shifted.cx_px += sx / machine.pitch_u_mm;
    shifted.cy_px -= sy / machine.pitch_v_mm;
    Pose moved = pose;
    moved.translation_mm -= Vec3(sx, sy, 0.0);
    poseVertices(moved, mesh.vertices, world);
    const WorldMesh posed{world, mesh.triangles, mesh.csg.get()};
    Image& target = k == 0 ? sum : one;
    renderIntensity(shifted, posed, table, options, target);
    if (!voids.empty()) {
      for (size_t d = 0; d < defects.size(); ++d)
        voids[d] = {moved.apply(defects[d].centre_part_mm), defects[d].radiusMm()};
      carveVoids(shifted, posed, voids, table, acquisition.area_samples, target);
    }
    if (k > 0) {
      auto s = sum.pixels();
      auto o = one.pixels();
      for (size_t i = 0; i < s.size(); ++i) s[i] += o[i];
    }
  }
  if (spots > 1)
    for (float& p : sum.pixels()) p /= static_cast<float>(spots);
  return sum;
}

// A square of open beam in every shot, away from the part's shadow: the first
// of the corners and edge midpoints that no shot's footprint comes near.
PixelRect findWhiteRegion(const ImageT<uint8_t>& shadowed, const Machine& machine) {
  const int side = std::max(16, machine.columns / 20);
  const int margin = std::max(2, machine.columns / 50);
  const int w = machine.columns, h = machine.rows;
  // A detector of few rows (a line scanner: one) gets a strip of its height.
  const int side_y = std::min(side, h);
  const int margin_y = h >= side + 2 * margin ? margin : 0;
  const int xs[] = {margin, w - margin - side, (w - side) / 2};
  const int ys[] = {margin_y, h - margin_y - side_y, (h - side_y) / 2};
  for (int y : ys)
    for (int x : xs) {
      const PixelRect r{x, y, side, side_y};
      if (x == xs[2] && y == ys[2] && h > side_y) continue;  // not the centre
      // Clear of any shadow by a further `margin` all around.
      const PixelRect guard =
          PixelRect{x - margin, y - margin_y, side + 2 * margin, side_y + 2 * margin_y}.intersect(
              machine.detectorRect());
      bool clear = true;
      for (int v = guard.y; v < guard.bottom() && clear; ++v)
        for (int u = guard.x; u < guard.right() && clear; ++u) clear = shadowed(u, v) == 0;
      if (clear) return r;
    }
  fail(
      "no open-beam region found for normalization: the part's shadow covers every corner; "
      "give white_region in the recipe");
}

nlohmann::json transmissionJson(const PolychromaticMaterial& material, double max_path_mm) {
  nlohmann::json path = nlohmann::json::array(), value = nlohmann::json::array();
  const double step = 0.05;
  for (int i = 0; i * step <= max_path_mm + 1e-9; ++i) {
    path.push_back(i * step);
    value.push_back(material.transmission(i * step));
  }
  return {{"path_mm", path},
          {"transmission", value},
          {"note", "polychromatic transmission of the part material for this beam and detector"}};
}

// truth.json's `defects`: each as the recipe gives it, in the part frame.
nlohmann::json defectsJson(std::span<const Defect> defects) {
  nlohmann::json out = nlohmann::json::array();
  for (const Defect& d : defects) {
    const Vec3& c = d.centre_part_mm;
    out.push_back(
        {{"type", d.type}, {"centre_mm", {c.x(), c.y(), c.z()}}, {"diameter_mm", d.diameter_mm}});
  }
  return out;
}

// A shot's `defects`, in the order of truth.json's `defects`: where each one
// is in the world and where its centre projects from the focal spot's centre
// (continuous pixel coordinates), with the diameter of its shadow to first
// order (the diameter magnified at the centre's depth).
nlohmann::json defectsInShotJson(const Machine& machine, std::span<const Defect> defects,
                                 const Pose& pose) {
  nlohmann::json out = nlohmann::json::array();
  for (const Defect& d : defects) {
    const Vec3 c = pose.apply(d.centre_part_mm);
    const Vec2 px = machine.project(c);
    const double magnification =
        machine.source_detector_distance_mm / (machine.source_detector_distance_mm - c.z());
    out.push_back({{"centre_world_mm", {c.x(), c.y(), c.z()}},
                   {"centre_px", {px.x(), px.y()}},
                   {"diameter_px",
                    {d.diameter_mm * magnification / machine.pitch_u_mm,
                     d.diameter_mm * magnification / machine.pitch_v_mm}}});
  }
  return out;
}

// truth.json's shots: name, file, pattern, pose, and each pattern's and
// defect's own keys.
nlohmann::json shotsJson(const Recipe& recipe, const Machine& machine) {
  nlohmann::json shots = nlohmann::json::array();
  for (const ShotPlan& shot : recipe.shots) {
    nlohmann::json s = {{"name", shot.name},
                        {"file", shot.name + ".tif"},
                        {"pattern", shot.pattern},
                        {"pose", poseToJson(shot.pose)}};
    if (shot.pattern == "translated") {
      s["reference"] = shot.reference;
      s["distance_mm"] = shot.distance_mm;
      s["axis"] = {shot.axis.x(), shot.axis.y(), shot.axis.z()};
    }
    if (shot.pattern == "rotated") s["nominal_angle_deg"] = shot.nominal_angle_deg;
    if (!recipe.defects.empty())
      s["defects"] = defectsInShotJson(machine, recipe.defects, shot.pose);
    shots.push_back(s);
  }
  return shots;
}

// The dataset's machine: the recipe's, with the turntable its rotations
// name.
nlohmann::json machineOf(const Machine& machine, const Recipe& recipe) {
  Machine out = machine;
  if (recipe.turntable) out.turntable = recipe.turntable;
  return out.toJson();
}

// The dead pixels of the detector pattern, [[u, v], ...].
nlohmann::json deadPixelsJson(const DetectorPattern& pattern) {
  nlohmann::json dead = nlohmann::json::array();
  for (int v = 0; v < pattern.height(); ++v)
    for (int u = 0; u < pattern.width(); ++u)
      if (pattern.dead(u, v)) dead.push_back({u, v});
  return dead;
}

// truth.json's "part": the model, its true dimensions and, where the shots
// showed another solid, that solid's file.
nlohmann::json partJson(const Recipe& recipe, const nlohmann::json& dimensions) {
  nlohmann::json part = {{"model", std::filesystem::weakly_canonical(recipe.part_file).string()},
                         {"dimensions", dimensions}};
  if (recipe.physical_file)
    part["physical"] = std::filesystem::weakly_canonical(*recipe.physical_file).string();
  return part;
}

}  // namespace

DatasetReport simulateDataset(const Recipe& recipe, const std::filesystem::path& folder) {
  const auto start = std::chrono::steady_clock::now();
  const ConfigNode& root = *recipe.root;

  // Inputs: machine, beam, material, detector, part.
  const Machine machine = Machine::load(recipe.machine_file);
  const BeamModel beam = BeamModel::fromConfig(root.at("beam"));
  const Layer material_layer = Layer::fromConfig(root.at("material"), /*with_thickness=*/false);
  const Acquisition acquisition = Acquisition::fromConfig(root.at("detector"));
  root.finish();

  const PartModel model = PartModel::load(recipe.part_file);
  const std::vector<double> values = model.values(recipe.true_dimensions);
  // What the shots show: the model at its true dimensions, or the physical
  // solid the recipe names.
  const TriangleMesh mesh = [&] {
    if (!recipe.physical_file) return model.mesh(values);
    const PartModel physical = PartModel::fromFile(*recipe.physical_file);
    return physical.mesh(physical.nominalValues());
  }();
  const double max_path_mm = boundingBox(mesh).diagonal() * 1.01 + 1.0;
  const PolychromaticMaterial material(beam, material_layer);
  const TransmissionTable table = material.table(max_path_mm);
  // Every shot must see the part, before anything is written.
  for (const ShotPlan& shot : recipe.shots) {
    std::vector<Vec3> world;
    poseVertices(shot.pose, mesh.vertices, world);
    auto why = outsideBeam(machine, world);
    if (!why) why = shadowMissesDetector(machine, world);
    if (why) fail("{}: shot {}: {}", recipe.file.string(), shot.name, *why);
  }

  createOutputFolder(folder);
  const int shot_count = static_cast<int>(recipe.shots.size());
  ProgressBar progress("simulate", shot_count + 2);

  // The detector: fixed patterns, then dark and flat frames.
  // The open beam's heel effect and fall-off multiply the gain: exposures and
  // flats alike see them, as on a real panel.
  DetectorPattern pattern =
      DetectorPattern::generate(acquisition.noise, machine.columns, machine.rows, recipe.seed);
  if (acquisition.heel_gradient != 0.0 || acquisition.cos3_falloff) {
    const Image profile =
        beamProfile(machine.columns, machine.rows, machine.pitch_u_mm, machine.pitch_v_mm,
                    machine.cx_px, machine.cy_px, machine.source_detector_distance_mm,
                    acquisition.heel_gradient, acquisition.cos3_falloff);
    auto g = pattern.gain.pixels();
    auto p = profile.pixels();
    for (size_t k = 0; k < g.size(); ++k) g[k] *= p[k];
  }
  writeTiff(folder / "dark.tif",
            darkFrame(pattern, acquisition.noise, recipe.seed, 0, acquisition.flat_frames),
            TiffFormat::kFloat32);
  progress.advance();
  writeTiff(folder / "flat.tif",
            flatFrame(pattern, acquisition.noise, recipe.seed, 0, acquisition.flat_frames),
            TiffFormat::kFloat32);
  progress.advance();

  // The shots, in order (ghosting carries each one's signal to the next).
  ImageT<uint8_t> shadowed(machine.columns, machine.rows, 0);
  std::optional<Image> previous_signal;
  double shot_seconds = 0.0;
  for (int i = 0; i < shot_count; ++i) {
    const auto shot_start = std::chrono::steady_clock::now();
    const ShotPlan& shot = recipe.shots[static_cast<size_t>(i)];
    const uint64_t index = static_cast<uint64_t>(i) + 1;
    Image intensity = renderShot(machine, mesh, recipe.defects, shot.pose, table, acquisition,
                                 recipe.seed, index);
    {
      auto p = intensity.pixels();
      auto s = shadowed.pixels();
      for (size_t k = 0; k < p.size(); ++k) s[k] |= p[k] < 1.0f ? 1 : 0;
    }
    if (acquisition.scatter)
      intensity = scatterBlur(std::move(intensity), acquisition.scatter_weight,
                              acquisition.scatter_sigma_px);
    darkenColumns(intensity, acquisition.column_darkening);
    Exposure exposure = exposeRaw(intensity, pattern, acquisition.noise, recipe.seed, index,
                                  previous_signal ? &*previous_signal : nullptr);
    writeTiff(folder / (shot.name + ".tif"), exposure.raw_adu,
              acquisition.noise.quantize_16bit ? TiffFormat::kUInt16 : TiffFormat::kFloat32);
    previous_signal = std::move(exposure.signal);
    shot_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - shot_start).count();
    progress.advance();
  }
  progress.finish();
  std::optional<nlohmann::json> characterization;
  if (recipe.characterization)
    characterization = simulateCharacterization(
        *recipe.characterization, machine, recipe.machine_file, pattern, acquisition.noise,
        {acquisition.scatter, acquisition.scatter_weight, acquisition.scatter_sigma_px,
         acquisition.column_darkening, acquisition.noise.quantize_16bit},
        recipe.seed, folder / "characterization");

  // Ground truth, last: its presence marks a complete dataset.
  const PixelRect white =
      recipe.white_region ? *recipe.white_region : findWhiteRegion(shadowed, machine);
  if (!machine.detectorRect().contains(white))
    fail("white_region {} lies outside the {}x{} detector", toString(white), machine.columns,
         machine.rows);
  nlohmann::json dims = nlohmann::json::object();
  for (size_t k = 0; k < model.dimensions().size(); ++k)
    dims[model.dimensions()[k].name] = values[k];
  nlohmann::json truth = {
      {"recipe", recipe.file.string()},
      {"description", recipe.description},
      {"seed", recipe.seed},
      {"machine", machineOf(machine, recipe)},
      {"beam", beam.toJson()},
      {"material",
       {{"compound", material_layer.compound}, {"density_g_cm3", material_layer.density_g_cm3}}},
      {"detector", acquisition.noise.toJson()},
      {"effects",
       {{"scatter", acquisition.scatter ? nlohmann::json{{"weight", acquisition.scatter_weight},
                                                         {"sigma_px", acquisition.scatter_sigma_px},
                                                         {"sigma_mm", acquisition.scatter_sigma_px *
                                                                          machine.pitch_u_mm}}
                                        : nlohmann::json(nullptr)},
        {"heel_gradient", acquisition.heel_gradient},
        {"cos3_falloff", acquisition.cos3_falloff},
        {"column_darkening", acquisition.column_darkening}}},
      {"part", partJson(recipe, dims)},
      {"white_region", {white.x, white.y, white.width, white.height}},
      {"dark", "dark.tif"},
      {"flat", "flat.tif"},
      {"dead_pixels", deadPixelsJson(pattern)},
      {"transmission", transmissionJson(material, max_path_mm)},
      {"shots", shotsJson(recipe, machine)}};
  if (!recipe.defects.empty()) truth["defects"] = defectsJson(recipe.defects);
  if (characterization) truth["characterization"] = *characterization;
  writeFileAtomically(folder / "truth.json", truth.dump(2) + "\n");

  DatasetReport report;
  report.shots = shot_count;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report.seconds_per_shot = shot_count > 0 ? shot_seconds / shot_count : 0.0;
  report.white_region = white;
  return report;
}

}  // namespace xgauge
