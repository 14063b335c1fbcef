// The forward model of a measurement: parameters -> simulated, normalized
// radiographs -> loss against the measured ones (thesis eq. 3.13).
//
// Parameter vector theta: every dimension of the part model (model order),
// then each radiograph's pose parameters by its acquisition pattern:
//   free, rotated  6: rx, ry, rz (deg; R = Rz Ry Rx) and the world position
//                  (mm) of the part's reference centre c (its nominal bounding-box
//                  centre): x_world = R (x_part - c) + centre
//   translated     2: azimuth and elevation (deg) of the unit axis
//                  d = (cos el cos az, sin el, cos el sin az); the pose is the
//                  reference's moved by distance_mm * d, so the known distance
//                  holds exactly
//   known          0
// Fixed dimensions simply keep their value; stages choose what to vary.
#pragma once

#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/measure/job.h"
#include "xgauge/xray/machine.h"

#include <functional>
#include <span>
#include <vector>

namespace xgauge {

// A measured radiograph prepared for fitting.
struct PreparedRadiograph {
  RadiographSpec spec;
  std::vector<Image> levels;     // normalized (open beam = 1, not clamped); 0 = full size
  std::vector<PixelRect> rois;   // region compared, per level
  int64_t repaired_pixels = 0;   // bad pixels repaired by the flat-field correction
};

class ForwardModel {
 public:
  explicit ForwardModel(const MeasurementJob& job);

  const MeasurementJob& job() const { return job_; }
  const PartModel& part() const { return part_; }
  const Machine& machine() const { return machine_; }
  const std::vector<PreparedRadiograph>& radiographs() const { return radiographs_; }
  int levels() const { return static_cast<int>(radiographs_.front().levels.size()); }
  // The coarsest level whose width is at least `min_width` pixels.
  int levelForWidth(int min_width) const;

  // Parameter layout.
  int size() const { return static_cast<int>(lower_.size()); }
  const std::vector<double>& lower() const { return lower_; }
  const std::vector<double>& upper() const { return upper_; }
  const std::vector<double>& start() const { return start_; }
  std::vector<int> freeDimensionIndices() const { return free_dims_; }
  std::vector<int> poseIndices(int radiograph) const;  // empty for known
  enum class Kind { kDimension, kRotation, kPosition, kAxis };
  Kind kind(int index) const { return kinds_[static_cast<size_t>(index)]; }
  Pose pose(std::span<const double> theta, int radiograph) const;
  const Vec3& referenceCentre() const { return centre_part_; }
  // Diagonal of the part's nominal bounding box (mm).
  double partSizeMm() const { return part_size_mm_; }

  // Sum over `radiographs` of the loss at pyramid `level` with n x n samples.
  double loss(std::span<const double> theta, int level, int samples,
              std::span<const int> radiographs);
  // The residuals (simulated - measured) over every roi of `radiographs`, each
  // scaled by 1 / sqrt(its pixel count) so that their squared sum is the L2
  // loss. Returns false for parameters the part or the beam cannot take.
  bool residuals(std::span<const double> theta, int level, int samples,
                 std::span<const int> radiographs, std::vector<double>& out);
  // The simulated normalized image of one radiograph over `region` (pixels of
  // `level`), as compared in the loss.
  Image simulate(std::span<const double> theta, int radiograph, int level, int samples,
                 const PixelRect& region);

 private:
  Machine machineAt(int level) const;
  // Validates the dimensions, then calls use(radiograph, roi, simulated roi)
  // for each of `radiographs`; false (and no further calls) for parameters
  // the part or the beam cannot take.
  bool forEachSimulated(
      std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
      const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use);

  MeasurementJob job_;
  PartModel part_;
  Machine machine_;
  TransmissionTable transmission_;
  std::vector<PreparedRadiograph> radiographs_;
  std::vector<double> lower_, upper_, start_;
  std::vector<int> free_dims_;
  std::vector<int> pose_offset_;  // first pose parameter of each radiograph
  std::vector<Kind> kinds_;
  Vec3 centre_part_;
  double part_size_mm_ = 0.0;
  // Scratch reused between evaluations.
  std::vector<Vec3> part_vertices_, world_vertices_;
  Image rendered_, coarse_;
};

}  // namespace xgauge
