// A measurement job: what to measure, from which radiographs, how.
//
// Job JSON keys (paths relative to the job file; unknown keys are errors):
//   description        free text
//   part               part model file (geometry/part_model.h)
//   dimensions         optional:
//     free             names to measure (default: all); the others stay fixed
//     fixed            {name: value} for dimensions held at a known value (default nominal)
//     start            {name: value} starting values of free dimensions (default nominal)
//     bounds           {name: [min, max]} search bounds of free dimensions (default: the
//                      model's bounds narrowed to nominal +- 10 %)
//   machine            machine file (xray/machine.h)
//   material           exponential-sum material file (material/exponential_sum.h)
//   scatter            optional {"weight": w, "sigma_mm": s}: the detector's scintillator
//                      scatter I' = w G(I, s) + (1 - w) I, with s in mm on the detector,
//                      modelled in the fit (METHOD.md: w = 0.139, s = 500 px of 0.1 mm)
//   radiographs        list of:
//     name             unique name
//     image            raw or normalized radiograph (TIFF)
//     dark, flat       optional dark and flat frames (TIFF); bad pixels are repaired
//     white_region     [x, y, w, h]: open beam; the image is divided by its mean (eq. 3.9)
//     roi              optional [x, y, w, h]: pixels compared; default: the part's shadow
//                      in this image (normalized < 0.98) grown by 5 % of its size + 8 px
//     pattern          "free" | "translated" | "rotated" | "known" (PARTS.md)
//     reference        translated and rotated: the radiograph it refers to
//     distance_mm      translated: the exact distance moved (mm)
//     pose             known: the pose (xray/machine.h keys)
//   pose_bounds        search bounds of every free pose (world frame, of the part's
//                      bounding-box centre; angles in degrees, R = Rz Ry Rx):
//                      {"rotation_deg": [[rx0, rx1], [ry0, ry1], [rz0, rz1]],
//                       "centre_mm": [[x0, x1], [y0, y1], [z0, z1]]}
//   schedule           "default" or "thesis" (measure/schedule.h)
//   loss               "l1" (thesis eq. 3.13, default) or "l2"
//   seed               optional, default 1
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

enum class Acquisition { kFree, kTranslated, kRotated, kKnown };

struct RadiographSpec {
  std::string name;
  std::filesystem::path image, dark, flat;  // dark/flat empty when not given
  PixelRect white_region;
  std::optional<PixelRect> roi;
  Acquisition pattern = Acquisition::kFree;
  int reference = -1;        // index of the reference radiograph
  double distance_mm = 0.0;  // translated
  Pose known_pose;           // known
};

struct ScatterModel {
  double weight = 0.0;
  double sigma_mm = 0.0;  // on the detector
  bool enabled() const { return weight > 0.0; }
};

struct MeasurementJob {
  std::filesystem::path file;
  std::string description;
  std::filesystem::path part_file, machine_file, material_file;
  std::vector<std::string> free_dimensions;             // in model order
  std::map<std::string, double> fixed_dimensions;       // overrides of nominal
  std::map<std::string, double> start;                  // starting values
  std::map<std::string, std::array<double, 2>> bounds;  // explicit bounds
  ScatterModel scatter;
  std::vector<RadiographSpec> radiographs;
  std::array<std::array<double, 2>, 3> rotation_bounds_deg{};
  std::array<std::array<double, 2>, 3> centre_bounds_mm{};
  std::string schedule = "default";
  std::string loss = "l1";
  uint64_t seed = 1;

  // Reads and validates a job file (Error naming file and key).
  static MeasurementJob load(const std::filesystem::path& path);
  // The same from a parsed file whose other keys the caller reads (a
  // calibration job adds its own); does not call finish(). Without
  // `needs_material` the material key is optional (material_file empty).
  static MeasurementJob fromConfig(const ConfigNode& root, const std::filesystem::path& path,
                                   bool needs_material);
};

// {"weight": w in [0, 0.9], "sigma_mm": s in [0.01, 1e4]} (Error at the node otherwise).
ScatterModel scatterModelFromConfig(const ConfigNode& node);

// [x, y, width, height] in whole pixels, not empty (Error at the node otherwise).
PixelRect pixelRectFromConfig(const ConfigNode& node);

std::string_view acquisitionName(Acquisition pattern);

}  // namespace xgauge
