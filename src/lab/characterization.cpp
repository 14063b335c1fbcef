#include "xgauge/lab/characterization.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/tiff.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

namespace xgauge {

namespace {

// Exposure indices of the session's frames: far above any dataset's shot
// index, so that their noise is drawn independently of the shots'.
constexpr uint64_t kFirstIndex = 1'000'000;
constexpr double kEdgeShare = 0.4;  // of the panel's width behind the edge plate
constexpr double kEdgeSlantDeg = 3.0;

// Transmission 0 behind the plate, 1 elsewhere: the edge plate (left of a
// line slanted by kEdgeSlantDeg through (kEdgeShare * width, height / 2)).
Image edgeScene(int width, int height) {
  Image t(width, height, 1.0f);
  const double slope = std::tan(kEdgeSlantDeg * std::numbers::pi / 180.0);
  for (int v = 0; v < height; ++v) {
    const double edge = kEdgeShare * width + slope * (v + 0.5 - 0.5 * height);
    for (int u = 0; u < width; ++u)
      if (u + 0.5 < edge) t(u, v) = 0.0f;
  }
  return t;
}

Image quadrantScene(int width, int height) {
  Image t(width, height, 1.0f);
  for (int v = 0; v < height / 2; ++v)
    for (int u = 0; u < width / 2; ++u) t(u, v) = 0.0f;
  return t;
}

}  // namespace

nlohmann::json simulateCharacterization(const CharacterizationPlan& plan, const Machine& machine,
                                        const std::filesystem::path& machine_file,
                                        const DetectorPattern& pattern,
                                        const DetectorNoiseModel& noise,
                                        const CharacterizationPhysics& physics, uint64_t seed,
                                        const std::filesystem::path& folder) {
  const TiffFormat format = physics.quantize_16bit ? TiffFormat::kUInt16 : TiffFormat::kFloat32;
  std::filesystem::create_directories(folder / "darks");
  std::filesystem::create_directories(folder / "flats");
  // Dark and flat series: single frames of their own streams (index
  // kFirstIndex + k), each rounded like a raw frame.
  for (int k = 0; k < plan.frames; ++k) {
    const auto index = kFirstIndex + static_cast<uint64_t>(k);
    writeTiff(folder / "darks" / fmt::format("dark_{:03d}.tif", k),
              darkFrame(pattern, noise, seed, index, 1), format);
    writeTiff(folder / "flats" / fmt::format("flat_{:03d}.tif", k),
              flatFrame(pattern, noise, seed, index, 1), format);
  }
  // A scene through the panel's physics, after a rest unless `previous`.
  uint64_t index = kFirstIndex;
  auto expose = [&](Image scene, const Image* previous) {
    if (physics.scatter)
      scene = scatterBlur(std::move(scene), physics.scatter_weight, physics.scatter_sigma_px);
    darkenColumns(scene, physics.column_darkening);
    return exposeRaw(scene, pattern, noise, seed, index++, previous);
  };
  const int width = machine.columns, height = machine.rows;
  writeTiff(folder / "edge.tif", expose(edgeScene(width, height), nullptr).raw_adu, format);
  writeTiff(folder / "crosstalk.tif", expose(quadrantScene(width, height), nullptr).raw_adu,
            format);
  const Exposure bright = expose(Image(width, height, 1.0f), nullptr);
  writeTiff(folder / "lag_bright.tif", bright.raw_adu, format);
  writeTiff(folder / "lag_dark_after_bright.tif",
            expose(Image(width, height, 0.0f), &bright.signal).raw_adu, format);

  const nlohmann::json job = {
      {"description",
       "Characterise the replica detector from the shots xgauge simulate wrote beside this file"},
      {"machine", std::filesystem::absolute(machine_file).lexically_normal().string()},
      {"darks", "darks/dark_*.tif"},
      {"flats", "flats/flat_*.tif"},
      {"shots",
       {{"edge", "edge.tif"},
        {"crosstalk", "crosstalk.tif"},
        {"lag", {{"bright", "lag_bright.tif"}, {"after", "lag_dark_after_bright.tif"}}}}}};
  writeFileAtomically(folder / "characterize.json", job.dump(2) + "\n");
  return {{"folder", folder.filename().string()},
          {"job", (folder.filename() / "characterize.json").string()},
          {"frames", plan.frames},
          {"halo", physics.scatter
                       ? nlohmann::json{{"shape", "gaussian"},
                                        {"weight", physics.scatter_weight},
                                        {"sigma_mm", physics.scatter_sigma_px * machine.pitch_u_mm}}
                       : nlohmann::json(nullptr)},
          {"lag_fraction", noise.ghost_fraction},
          {"column_darkening", physics.column_darkening},
          {"edge", {{"share_of_width", kEdgeShare}, {"slant_deg", kEdgeSlantDeg}}}};
}

}  // namespace xgauge
