// Dataset recipes for the virtual lab: what a real X-ray session would
// record, with its ground truth. A recipe names the machine, the beam, the
// detector, the part with its true dimensions, and the shot pattern.
//
// Recipe JSON keys (paths are relative to the recipe file):
//   description       free text
//   seed              unsigned integer; the same seed gives the same files
//   machine           path to a machine JSON (xray/machine.h)
//   beam              tube, filters, detector window, scintillator (lab/spectrum.h)
//   material          {"compound": "Al", "density_g_cm3": 2.699}: the part's material
//   detector          noise and artefacts (lab/detector.h), plus
//     area_samples    n: n x n samples per pixel (1..8)
//     focal_spot      {"fwhm_mm": f, "samples": k}: Gaussian spot, k jittered source points
//     scatter         {"weight": w, "sigma_px": s}: I' = w G(I, s) + (1 - w) I; omit to disable
//     flat_frames     frames averaged into the flat and dark frames (default 16)
//     heel_gradient   the open beam's relative change from the top row to the
//                     bottom row (heel effect), -0.5..0.5, default 0
//     cos3_falloff    true: the open beam falls off as cos^3 of the ray's angle
//                     (lab/detector.h beamProfile), default false
//     column_darkening  each column reads lower by this times the mean
//                     attenuation along it (lab/detector.h darkenColumns),
//                     0..0.1, default 0
//   part              {"model": path, "dimensions": {name: value, ...}} (unnamed = nominal),
//                     optional "physical": path (the solid shown, see below)
//   shots             the acquisition:
//     base_pose       pose of the first translated shot (xray/machine.h pose keys)
//     pivot_mm        part point the rotations turn about (default: bounding-box centre)
//     translations    {"count": N, "distance_mm": d, "axis": [x, y, z]}: shot i at the base
//                     pose moved by i * d along the (normalized) axis; exact by construction
//     rotations       {"angles_deg": [...], "axis": [x, y, z], "angle_jitter_deg": j,
//                      "wobble_deg": w, "base_pose": {...}}: the base pose (default: the
//                     shots' base_pose) turned about the axis through the
//                     pivot by each angle plus N(0, j), then tilted by N(0, w) about a random
//                     axis perpendicular to it (an uncalibrated rotary stage)
//     extra           [{"name": n, "pose": {...}}]: shots with poses of their own
//   white_region      optional [x, y, width, height]; default: found automatically
//   defects           optional [{"type": "void", "centre_mm": [x, y, z], "diameter_mm": d}]:
//                     spherical voids in the part frame, in every shot (lab/defect.h)
#pragma once

#include "xgauge/xray/machine.h"

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"
#include "xgauge/lab/characterization.h"
#include "xgauge/lab/defect.h"

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

// One radiograph to simulate, with its exact pose.
struct ShotPlan {
  std::string name;          // file stem, e.g. "t03", "r05", "calibration"
  std::string pattern;       // "translated" | "rotated" | "free" (docs/conventions.md patterns)
  std::string reference;     // for "translated": the shot it is translated from
  double distance_mm = 0.0;  // for "translated": the exact distance from `reference`
  Vec3 axis = Vec3::Zero();  // for "translated": the unit axis (truth; unknown to a fit)
  double nominal_angle_deg = 0.0;  // for "rotated": the angle the stage was asked for
  Pose pose;                       // world_from_part, exact
};

struct Recipe {
  std::filesystem::path file;  // where it was read from
  std::string description;
  uint64_t seed = 0;
  std::optional<ConfigNode> root;  // the whole document, for the modules' own sections
  std::filesystem::path machine_file;
  std::filesystem::path part_file;
  std::map<std::string, double> true_dimensions;  // by name; others take their nominal
  // "physical": the solid the shots show, when it is not the model at its
  // true dimensions (a CAD solid made at those dimensions by other means, a
  // part with features the model lacks): any part file (PartModel::fromFile:
  // a STEP or STL solid, or a part model at its nominal values). The
  // truth's dimensions stay the model's.
  std::optional<std::filesystem::path> physical_file;
  std::vector<ShotPlan> shots;
  // "rotations": {"turntable": true}: the rotary stage is the machine's
  // calibrated turntable, whose axis (through the pivot, along the
  // rotations' axis) the dataset's machine states.
  std::optional<Turntable> turntable;
  std::optional<PixelRect> white_region;
  std::vector<Defect> defects;  // checked: each entirely inside the part at its true dimensions
  // "characterization": {"frames": N}: the detector's characterisation
  // session as well (lab/characterization.h), into the dataset's
  // characterization/ folder.
  std::optional<CharacterizationPlan> characterization;

  // Reads the recipe and plans the shots (random stage errors drawn from the
  // seed). Sections read by other modules are checked there.
  static Recipe load(const std::filesystem::path& path);
};

// Plans the shots of a `shots` section for a part whose rotations turn about
// `pivot_part_mm`; `seed` drives the stage's angle jitter and wobble.
// With `turntable` given, a calibrated stage's axis ("turntable": true) is
// written there.
std::vector<ShotPlan> planShots(const ConfigNode& shots, const Vec3& pivot_part_mm, uint64_t seed,
                                std::optional<Turntable>* turntable = nullptr);

}  // namespace xgauge
