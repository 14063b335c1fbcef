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
// and, for a calibration that frees the material (freeMaterial), last, the
// material of M terms: M - 1 stick-breaking fractions u_k in [0, 1] (a_1 =
// u_1, a_k = u_k (1 - a_1 - ... - a_{k-1}), the last term takes the rest, so
// the weights are >= 0 and sum to 1 for any u in the box) and the M rates
// mu_k in [0, 10] /mm.
// Fixed dimensions simply keep their value; stages choose what to vary.
#pragma once

#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/measure/job.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace xgauge {

// A measured radiograph prepared for fitting.
struct PreparedRadiograph {
  RadiographSpec spec;
  std::vector<Image> levels;    // normalized (open beam = 1, not clamped); 0 = full size
  std::vector<PixelRect> rois;  // region compared, per level
  int64_t repaired_pixels = 0;  // bad pixels repaired by the flat-field correction
};

// Reads, flat-field corrects (repairing bad pixels) and normalizes a
// radiograph by its white region; builds its pyramid and finds its roi.
PreparedRadiograph prepareRadiograph(const RadiographSpec& spec, const Machine& machine);

// The modelled scintillator scatter of one simulated radiograph (job
// "scatter"): w G(I) from a coarse render of the whole detector, and the
// open-beam level the white-region normalization divides by.
struct ScatterEstimate {
  Image blurred;       // G(I) at the coarse level
  double ratio = 1.0;  // coarse pixels per pixel of the level asked for
  double open = 1.0;   // (1 - w) + w mean of G(I) over the white region
  // G(I) at a continuous pixel coordinate of the level asked for (bilinear).
  double at(double x, double y) const;
};

class ForwardModel {
 public:
  // The material comes from job.material_file, or is given.
  explicit ForwardModel(const MeasurementJob& job);
  ForwardModel(const MeasurementJob& job, const ExponentialSum& material);

  // The material the radiographs are simulated with; a calibration changes it.
  const ExponentialSum& material() const { return *material_; }
  void setMaterial(const ExponentialSum& material);

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
  enum class Kind { kDimension, kRotation, kPosition, kAxis, kMaterial };
  // Appends the material's parameters to the parameter layout and to
  // `theta`, starting at `material`; from then on the material is read from
  // theta at every evaluation.
  void freeMaterial(const ExponentialSum& material, std::vector<double>& theta);
  std::vector<int> materialIndices() const;
  // The material a parameter vector stands for (the fixed one when the
  // material is not free).
  ExponentialSum materialOf(std::span<const double> theta) const;
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
  // The path length (mm) through the part at the centre of each pixel of
  // `region` (pixels of `level`).
  Image pathLengths(std::span<const double> theta, int radiograph, int level,
                    const PixelRect& region);
  // The scatter as simulate() adds it (requires job().scatter.enabled()).
  ScatterEstimate scatter(std::span<const double> theta, int radiograph, int level);

 private:
  Machine machineAt(int level) const;
  // Poses the part for `radiograph` into world_vertices_.
  WorldMesh posedMesh(std::span<const double> theta, int radiograph);
  ScatterEstimate scatterOf(const WorldMesh& mesh, int radiograph, int level);
  // Validates the dimensions, then calls use(radiograph, roi, simulated roi)
  // for each of `radiographs`; false (and no further calls) for parameters
  // the part or the beam cannot take.
  bool forEachSimulated(
      std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
      const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use);

  MeasurementJob job_;
  PartModel part_;
  Machine machine_;
  // Rebuilds the table when theta's material differs from the current one.
  void useMaterialOf(std::span<const double> theta);
  std::shared_ptr<ExponentialSum> material_;
  int material_offset_ = -1;  // first material parameter; -1 when fixed
  int material_terms_ = 0;
  double max_path_mm_ = 0.0;
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
