// Projection geometry as plain data (docs/conventions.md frames; the files: docs/formats.md).
//
// World frame: detector plane z = 0, X-ray source (focal spot centre) at
// (0, 0, D). Seen from the source, world x points right and y up. Detector
// pixel (u, v): u = column from the left, v = row from the top; pixel centres
// at continuous coordinates (u + 0.5, v + 0.5). The principal point (cx, cy)
// is the continuous pixel coordinate of the foot of the perpendicular from the
// source; a continuous pixel coordinate (pu, pv) is the world point
// ((pu - cx) * pitch_u, (cy - pv) * pitch_v, 0).
//
// Machine JSON keys:
//   source_detector_distance_mm      D, > 0
//   detector.columns, detector.rows  detector size in pixels (1..65536)
//   detector.pixel_pitch_mm          [pitch_u, pitch_v] in mm, > 0
//   detector.principal_point_px      [cx, cy]; default: the detector centre
//   detector.lag_fraction            optional, 0..0.5: the fraction of a frame's
//                                    signal the next frame records (image/lag.h);
//                                    absent: estimated where a job names the
//                                    previous frame
//   uncertainty.lag_fraction         optional, 0..0.5: the standard uncertainty
//                                    of lag_fraction (default: a tenth of it)
//   turntable                        optional: the rotary stage's axis
//     .point_mm                      a point of the axis (world mm)
//     .direction                     its direction (normalised here)
//     .point_uncertainty_mm          optional, 0..100: standard uncertainty of
//                                    the point across the axis (default 0.01)
//     .direction_uncertainty_deg     optional, 0..10: of the direction's two
//                                    tilts (default 0.01)
//   detector.tilt_deg                optional [about u, about v], each -10..10:
//                                    the panel's tilt (docs/conventions.md)
//   detector.rotation_deg            optional, -10..10: its turn in its plane
//   uncertainty.detector_pose_deg    optional [u_tilt_u, u_tilt_v, u_rotation]
//   description                      optional free text
//
// Pose JSON keys (a pose maps part to world coordinates, x_w = R x_p + t):
//   rotation_deg     [rx, ry, rz], R = Rz(rz) Ry(ry) Rx(rx) (fixed axes, x first)
//   translation_mm   [tx, ty, tz]
// or
//   matrix           16 numbers, row-major 4x4 world_from_part
//   description      optional free text
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/image/image.h"
#include "xgauge/image/open_beam.h"

#include <array>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>

namespace xgauge {

// A rotary stage's axis: "turned" radiographs are their reference's pose
// turned about it by a stated angle (docs/conventions.md, stage axis).
struct Turntable {
  Vec3 point_mm = Vec3::Zero();
  Vec3 direction = Vec3::UnitY();  // unit
  double point_uncertainty_mm = kDefaultPointUncertaintyMm;
  double direction_uncertainty_deg = kDefaultDirectionUncertaintyDeg;
  // A geometry calibration states its axis to about 10 um and 0.01 deg.
  static constexpr double kDefaultPointUncertaintyMm = 0.01;
  static constexpr double kDefaultDirectionUncertaintyDeg = 0.01;
  // The pose `reference` turned about the axis by `angle_deg` (right-handed
  // about `direction`).
  Pose turn(const Pose& reference, double angle_deg) const;
};

struct Machine {
  double source_detector_distance_mm = 1000.0;
  int columns = 1024;
  int rows = 1024;
  double pitch_u_mm = 0.1;
  double pitch_v_mm = 0.1;
  double cx_px = 512.0;
  double cy_px = 512.0;
  std::string description;
  std::optional<Turntable> turntable;
  double lag_fraction = std::numeric_limits<double>::quiet_NaN();  // NaN: not stated
  // The characterised detector's column crosstalk (its detector file's
  // "crosstalk"), undone on raw radiographs (image/radiograph.h); 0: none.
  double column_crosstalk = 0.0;
  double column_crosstalk_uncertainty = 0.0;
  // The characterised detector's bad pixels (its detector file's
  // bad_pixels.json: dead, hot and noisy), repaired on every radiograph
  // besides those the dark and flat frames show (image/bad_pixels.h); null:
  // none named.
  std::shared_ptr<const ImageT<uint8_t>> bad_pixels;
  // Standard uncertainties a lab states for its machine (optional key
  // "uncertainty"; docs/formats.md): they enter every measurement's budget.
  double source_detector_distance_uncertainty_mm = kDefaultDistanceUncertaintyMm;
  double pixel_pitch_uncertainty_relative = kDefaultPitchUncertaintyRelative;
  // Of a stated lag_fraction (key "uncertainty": {"lag_fraction": u}); NaN:
  // not stated, lagFractionUncertainty() then gives the default.
  double lag_fraction_uncertainty = std::numeric_limits<double>::quiet_NaN();
  // The standard uncertainty of the stated lag fraction: the machine's, else
  // kDefaultLagUncertaintyRelative of the fraction (0 without a fraction).
  double lagFractionUncertainty() const;
  // Defaults when a machine file states none: a source-detector distance
  // taken from a drawing or a tape (0.5 mm), and a pitch as the panel's
  // data sheet gives it (1e-4 of the pitch).
  static constexpr double kDefaultDistanceUncertaintyMm = 0.5;
  static constexpr double kDefaultPitchUncertaintyRelative = 1e-4;
  // A panel's lag changes with the exposure before and the time between
  // frames; a fraction taken from a data sheet or from earlier pairs is
  // known to about a tenth of itself (the replica's six estimates from one
  // session spread by 4 %; a data sheet quotes one figure for all timings).
  static constexpr double kDefaultLagUncertaintyRelative = 0.1;

  static Machine fromConfig(const ConfigNode& node);  // validates; does not call finish()
  static Machine load(const std::filesystem::path& path);
  nlohmann::json toJson() const;
  // Throws Error if a field is out of range.
  void validate() const;

  PixelRect detectorRect() const { return {0, 0, columns, rows}; }
  // What the open beam's field needs (image/open_beam.h).
  OpenBeamGeometry openBeamGeometry() const {
    return {source_detector_distance_mm, cx_px, cy_px, pitch_u_mm, pitch_v_mm};
  }
  Vec3 sourceWorld() const { return {0.0, 0.0, source_detector_distance_mm}; }
  // World point on the detector of a continuous pixel coordinate.
  Vec3 detectorPoint(double pu, double pv) const {
    const Vec3 local{(pu - cx_px) * pitch_u_mm, (cy_px - pv) * pitch_v_mm, 0.0};
    return tilted() ? Vec3(detector_rotation * local) : local;
  }
  // Continuous pixel coordinate where the ray from the source through a world
  // point (z < D) meets the detector.
  Vec2 project(const Vec3& world) const {
    if (tilted()) return projectTilted(world);
    const double magnification = source_detector_distance_mm / (source_detector_distance_mm - world.z());
    return {world.x() * magnification / pitch_u_mm + cx_px,
            cy_px - world.y() * magnification / pitch_v_mm};
  }
  // The ray's magnification at a world point: |P - S| / |W - S| for the
  // detector point P the ray from the source S through W meets; D / (D - z)
  // on an untilted detector. Its inverse is affine over a projected plane.
  double magnificationAt(const Vec3& world) const {
    const double d = source_detector_distance_mm;
    if (!tilted()) return d / (d - world.z());
    const Vec3 n = detector_rotation.col(2);
    return n.z() * d / (n.z() * d - n.dot(world));
  }

  // The detector's pose (docs/conventions.md, "Detector pose"): the panel
  // turned about the world origin, the pixel (cx, cy), by
  // R = Rz(rotation) Ry(tilt v) Rx(tilt u), angles in degrees; identity for
  // an ideal machine. Set through setDetectorPose.
  std::array<double, 2> detector_tilt_deg{0.0, 0.0};  // about the panel's u and v axes
  double detector_rotation_deg = 0.0;                 // in the panel's plane
  Mat3 detector_rotation = Mat3::Identity();
  // Standard uncertainties of the three angles (a geometry calibration's).
  std::array<double, 3> detector_pose_uncertainty_deg{0.0, 0.0, 0.0};
  void setDetectorPose(double tilt_u_deg, double tilt_v_deg, double rotation_deg);
  // Whether the pose is other than the identity: read per sample by the
  // render's derivatives, so kept as a flag (set by setDetectorPose only).
  bool tilted() const { return tilted_; }

 private:
  Vec2 projectTilted(const Vec3& world) const;
  bool tilted_ = false;

 public:
};

Pose poseFromConfig(const ConfigNode& node);  // does not call finish()
Pose loadPose(const std::filesystem::path& path);
// Writes both the Euler angles and the 4x4 matrix, so a pose is never ambiguous.
nlohmann::json poseToJson(const Pose& pose);

}  // namespace xgauge
