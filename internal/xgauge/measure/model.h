// The forward model of a measurement: named parameters -> simulated,
// normalized radiographs -> loss against the measured ones (thesis eq. 3.13,
// docs/method.md).
//
// Parameters (measure/parameters.h): "dim/<name>" for every dimension of the
// part model (model order), then each radiograph's pose by its acquisition
// pattern:
//   free, rotated  "<name>/rotation" rx, ry, rz (deg; R = Rz Ry Rx) and
//                  "<name>/position" x, y, z: the world position (mm) of the
//                  part's reference centre c (its nominal bounding-box centre):
//                  x_world = R (x_part - c) + position
//   translated     "<name>/axis" azimuth and elevation (deg) of the unit axis
//                  d = (cos el cos az, sin el, cos el sin az); the pose is the
//                  reference's moved by distance_mm * d, so the known distance
//                  holds exactly
//   known          none
// then, when the job refines the material in situ (job "refine_material":
// "rate_scale"), "material_refinement/rate_scale": the relative change e of
// every rate (the curve used is the material's withScaledRates(e)), free
// only in the least-squares stages, which weigh it by a prior of standard
// uncertainty rateScalePrior() about 0;
// and, for a calibration that frees the material (freeMaterial), last, the
// material of M terms: "material/fraction<k>", M - 1 stick-breaking fractions
// u_k in [0, 1] (a_1 = u_1, a_k = u_k (1 - a_1 - ... - a_{k-1}), the last
// term takes the rest, so the weights are >= 0 and sum to 1 for any u in the
// box) and "material/rate<k>", the M rates mu_k in [0, 10] /mm;
// and, for a geometry calibration (freeDetectorPose), "detector/tilt_u",
// "detector/tilt_v" and "detector/rotation": the panel's pose (deg,
// xray/machine.h), from then on read from theta at every evaluation.
//
// Infeasible parameters (dimensions the part model cannot take, a surface
// that folds, a vertex outside the beam) are a status: loss() returns nullopt
// and infeasibility() says why. What an optimiser sees for them is decided by
// the caller. Broken preconditions (a theta of the wrong size) abort.
//
// Defined by concept: model.cpp (construction, material, posing, simulated
// radiographs, residuals, loss), model_parameters.cpp (the parameter
// layout), model_scatter.cpp (the scatter), model_derivatives.cpp (the
// Jacobian).
#pragma once

#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/image/scatter.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/parameters.h"
#include "xgauge/xray/contour.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// The modelled scintillator scatter of one simulated radiograph (job
// "scatter"): G(I) from a coarse render of the whole detector, and the
// open-beam level the white-region normalization divides by.
struct ScatterEstimate {
  // G(I) at the coarse level: in the open beam's field K * (I O) / O
  // (image/scatter.h, ScatterModel::spreadIn; decision 0041).
  Image blurred;
  // The flat frame's own halo mix(1, K * O / O) at the coarse level, by
  // which the flat-field divides; empty in a uniform field (1).
  Image flat;
  double ratio = 1.0;  // coarse pixels per pixel of the level asked for
  // The white region's mean of (1 - w) + w G(I), each over the flat's own
  // halo there.
  double open = 1.0;
  // G(I) at a continuous pixel coordinate of the level asked for (bilinear).
  double at(double x, double y) const { return at(tap(x, y)); }
  // The bilinear interpolation's four coarse pixels and weights at (x, y),
  // the same for every estimate on the same coarse level (the derivatives'
  // spreads share them with the image's).
  struct Tap {
    int x0, y0, x1, y1;
    double fx, fy;
  };
  Tap tap(double x, double y) const;
  double at(const Tap& t) const {
    auto value = [&](int i, int j) { return static_cast<double>(blurred(i, j)); };
    return (1 - t.fy) * ((1 - t.fx) * value(t.x0, t.y0) + t.fx * value(t.x1, t.y0)) +
           t.fy * ((1 - t.fx) * value(t.x0, t.y1) + t.fx * value(t.x1, t.y1));
  }
  // The flat's own halo at a tap (1 in a uniform field).
  double flatAt(const Tap& t) const {
    if (flat.empty()) return 1.0;
    auto value = [&](int i, int j) { return static_cast<double>(flat(i, j)); };
    return (1 - t.fy) * ((1 - t.fx) * value(t.x0, t.y0) + t.fx * value(t.x1, t.y0)) +
           t.fy * ((1 - t.fx) * value(t.x0, t.y1) + t.fx * value(t.x1, t.y1));
  }
  // What a normalized value is divided by at a tap: open times the flat's
  // own halo.
  double openAt(const Tap& t) const { return open * flatAt(t); }
  // The simulated, normalized value of the pixel centred at (x, y) whose
  // scatter-free intensity is `intensity`: mix(I, G) / openAt.
  float simulated(const ScatterModel& scatter, double intensity, double x, double y) const {
    return simulated(scatter, intensity, tap(x, y));
  }
  float simulated(const ScatterModel& scatter, double intensity, const Tap& t) const {
    return static_cast<float>(scatter.mix(intensity, at(t)) / openAt(t));
  }
};

class ForwardModel {
 public:
  // Shares the inputs (which must outlive the model); the material is the
  // inputs' unless given (a calibration's current estimate).
  explicit ForwardModel(const MeasurementInputs& inputs);
  ForwardModel(const MeasurementInputs& inputs, const ExponentialSum& material);
  // The model keeps a reference to its inputs: a temporary would dangle.
  explicit ForwardModel(MeasurementInputs&&) = delete;
  ForwardModel(MeasurementInputs&&, const ExponentialSum&) = delete;

  // The material the radiographs are simulated with (before a refinement's
  // rate scale); a calibration changes it.
  const ExponentialSum& material() const { return base_material_; }
  void setMaterial(const ExponentialSum& material);

  const MeasurementInputs& inputs() const { return inputs_; }
  const MeasurementJob& job() const { return inputs_.job; }
  const PartModel& part() const { return part_; }
  // The machine as rendered now: the inputs', with theta's detector pose
  // when it is free.
  const Machine& machine() const { return machine_; }
  int radiographCount() const { return static_cast<int>(inputs_.radiographs.size()); }
  const PreparedRadiograph& radiograph(int index) const {
    return *inputs_.radiographs[static_cast<size_t>(index)];
  }
  const RadiographSpec& spec(int index) const {
    return inputs_.job.radiographs[static_cast<size_t>(index)];
  }
  int levels() const { return static_cast<int>(radiograph(0).levels.size()); }
  // The coarsest level whose width is at least `min_width` pixels (0: full size).
  int levelForWidth(int min_width) const;
  // The machine as seen at pyramid `level` (pixels 2^level times larger).
  Machine machineAt(int level) const;

  // The parameters.
  const ParameterLayout& parameters() const { return layout_; }
  int size() const { return layout_.size(); }
  const std::vector<double>& lower() const { return layout_.lower(); }
  const std::vector<double>& upper() const { return layout_.upper(); }
  const std::vector<double>& start() const { return layout_.start(); }
  ParameterKind kind(int index) const { return layout_[index].kind; }
  // The dimensions the job measures, in model order.
  const std::vector<int>& freeDimensionIndices() const { return free_dims_; }
  // The pose parameters of a radiograph (empty for a known pose).
  std::vector<int> poseIndices(int radiograph) const;
  // Every parameter a joint fit varies: free dimensions, every pose, the
  // material when free.
  std::vector<int> jointIndices() const;
  // Appends the material's parameters to the layout and to `theta`; from
  // then on the material is read from theta at every evaluation.
  void freeMaterial(const ExponentialSum& material, std::vector<double>& theta,
                    double rate_floor_per_mm = 0.0);
  std::vector<int> materialIndices() const { return layout_.block("material"); }
  // Appends the detector's pose (tilt_u, tilt_v, rotation, deg) to the
  // layout and to `theta`, each within +-reach_deg of the machine's; the
  // rotation held where it is unless `with_rotation`.
  void freeDetectorPose(std::vector<double>& theta, double reach_deg, bool with_rotation);
  std::vector<int> detectorIndices() const { return layout_.block("detector"); }
  // The refinement's rate scale, -1 when the job does not refine the
  // material; its prior's standard uncertainty (relative), the scale that
  // moves the curve by the material's stated transmission uncertainty at
  // the path where a scale moves it most (ExponentialSum::rateScaleFor).
  int rateScaleIndex() const { return rate_scale_index_; }
  double rateScalePrior() const { return rate_scale_prior_; }
  // The parameters of a least-squares stage: jointIndices() and the rate
  // scale when the material is refined.
  std::vector<int> leastSquaresIndices() const;
  // The material a parameter vector stands for (the fixed one when the
  // material is not free).
  ExponentialSum materialOf(std::span<const double> theta) const;
  Pose pose(std::span<const double> theta, int radiograph) const;
  const Vec3& referenceCentre() const { return centre_part_; }
  // Diagonal of the part's nominal bounding box (mm).
  double partSizeMm() const { return part_size_mm_; }

  // From now on every render also samples the pixels on the projection of
  // an edge or a silhouette with m x m points (RenderOptions::
  // edge_samples_per_axis; where m is not above a render's own samples, that
  // render does not refine); 0: never (the default).
  void setEdgeSamples(int m) { edge_samples_ = m; }
  int edgeSamples() const { return edge_samples_; }

  // Why theta cannot be simulated, or nullopt when it can.
  std::optional<std::string> infeasibility(std::span<const double> theta);
  // Sum over `radiographs` of the loss at pyramid `level` with n x n
  // samples; nullopt where theta is infeasible.
  std::optional<double> loss(std::span<const double> theta, int level, int samples,
                             std::span<const int> radiographs);
  // The residuals (simulated - measured) over every roi of `radiographs`, each
  // scaled by 1 / sqrt(its pixel count) so that their squared sum is the L2
  // loss. False (and `out` empty) where theta is infeasible.
  bool residuals(std::span<const double> theta, int level, int samples,
                 std::span<const int> radiographs, std::vector<double>& out);
  // residuals() and their Jacobian d r_m / d theta[indices[k]] at
  // jacobian[m * indices.size() + k], from the render with derivatives
  // (xray/derivatives.h) chained through the part model, the poses and the
  // scatter; material parameters by central differences of renders. False
  // (both empty) where theta is infeasible.
  bool residualsAndJacobian(std::span<const double> theta, std::span<const int> indices,
                            int level, int samples, std::span<const int> radiographs,
                            std::vector<double>& out, std::vector<double>& jacobian);
  // The simulated normalized image of one radiograph over `region` (pixels of
  // `level`), as compared in the loss. Requires a feasible theta.
  Image simulate(std::span<const double> theta, int radiograph, int level, int samples,
                 const PixelRect& region);
  // The path length (mm) through the part at the centre of each pixel of
  // `region` (pixels of `level`). Requires a feasible theta.
  Image pathLengths(std::span<const double> theta, int radiograph, int level,
                    const PixelRect& region);
  // The posed part's outline on the detector (xray/contour.h), in full-size
  // continuous pixel coordinates. Requires a feasible theta.
  std::vector<Segment2> outline(std::span<const double> theta, int radiograph);
  // The scatter as simulate() adds it (requires job().scatter.enabled()).
  ScatterEstimate scatter(std::span<const double> theta, int radiograph, int level);
  // d(world vertices)/d theta[indices[k]] of `radiograph`, for the vertex
  // parameters among `indices` (not the material's); `moving` gets the
  // positions in `indices` of those that move some vertex.
  bool poseVelocities(std::span<const double> theta, std::span<const int> indices,
                      int radiograph, std::vector<int>& moving, std::vector<Vec3>& velocities);

 private:
  // The parameter layout (model_parameters.cpp): "dim/<name>" for every
  // dimension of the part, each radiograph's pose by its pattern, the
  // refinement's rate scale.
  void addDimensionParameters();
  void addPoseParameters();
  void addRateScale();
  // The rate scale's bounds, in prior standard uncertainties (at most +-0.5).
  static constexpr double kRateScaleReach = 6.0;

  // Posing and simulating (model.cpp).
  // Poses the part for `radiograph` into world_vertices_; the reason when
  // the surface cannot be built or leaves the beam.
  std::optional<std::string> tryPose(std::span<const double> theta, int radiograph);
  WorldMesh posedMesh(std::span<const double> theta, int radiograph);
  WorldMesh worldMesh() const;
  // n x n samples over `region`, the edges refined as setEdgeSamples says:
  // the same for the image and for the render with derivatives.
  RenderOptions renderOptions(int samples, const PixelRect& region) const;
  Image simulatePosed(const WorldMesh& mesh, int radiograph, int level, int samples,
                      const PixelRect& region);
  // Calls use(radiograph, roi, simulated roi) for each of `radiographs`;
  // false (and no calls) where theta is infeasible.
  bool forEachSimulated(
      std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
      const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use);
  // Rebuilds the table when theta's material differs from the current one,
  // and sets the detector's pose when it is free.
  void useMaterialOf(std::span<const double> theta);
  void useMaterial(const ExponentialSum& material);  // keeps base_material_

  // The scatter (model_scatter.cpp).
  ScatterEstimate scatterOf(const WorldMesh& mesh, int radiograph, int level);
  // The scatter estimate of a coarse render (a derivative image when
  // `derivative`: its open level holds only the scatter's part).
  ScatterEstimate spreadOf(const Image& coarse, int coarse_level, int radiograph, int level,
                           bool derivative) const;
  // Adds the scatter to `image`, the scatter-free render of `region`.
  void addScatter(const WorldMesh& mesh, int radiograph, int level, const PixelRect& region,
                  Image& image);
  // scatterOf() and, into `rates`, the scatter of each of the `count`
  // derivative images of a coarse render with these vertex velocities, on
  // the same grid.
  ScatterEstimate scatterWithRates(const WorldMesh& mesh, int radiograph, int level,
                                   std::span<const Vec3> velocities, int count,
                                   std::vector<ScatterEstimate>& rates);
  int scatterLevel(int level) const { return std::max(level, levelForWidth(128)); }
  // The coarse render's samples (why these: model_scatter.cpp).
  RenderOptions scatterRenderOptions() const;

  // The derivatives (model_derivatives.cpp): one radiograph's residuals and
  // Jacobian rows appended (false where it cannot be posed), then the
  // material's columns by central differences.
  bool appendRadiographJacobian(std::span<const double> theta, std::span<const int> indices, int r,
                                int level, int samples, std::vector<double>& out,
                                std::vector<double>& jacobian);
  bool addMaterialColumns(std::span<const double> theta, std::span<const int> indices, int level,
                          int samples, std::span<const int> radiographs,
                          std::span<const double> out, std::vector<double>& jacobian);

  // The halo's field of one radiograph at one coarse level (image/scatter.h):
  // fixed by the inputs, made once per model (it blurs the open beam over
  // the plane) rather than on every render and derivative column.
  struct HaloFields {
    struct Made {
      int width = 0, height = 0;  // the coarse image's
      double pitch_mm = 0.0;
      std::shared_ptr<const HaloField> field;
    };
    std::mutex mutex;
    std::map<std::pair<int, int>, Made> fields;  // by (radiograph, coarse level)
  };
  std::shared_ptr<const HaloField> haloFieldOf(int radiograph, int coarse_level, int width,
                                               int height, double pitch_mm) const;

  const MeasurementInputs& inputs_;
  std::shared_ptr<HaloFields> halo_fields_ = std::make_shared<HaloFields>();
  Machine machine_;  // the inputs', with theta's detector pose when free
  PartModel part_;  // this model's own copy: evaluating one is not thread-safe
  ExponentialSum base_material_;  // as given (setMaterial)
  ExponentialSum material_;       // as rendered now: the base, or theta's
  int material_terms_ = 0;  // > 0 when the material is free
  int rate_scale_index_ = -1;
  double rate_scale_prior_ = 0.0;
  double max_path_mm_ = 0.0;
  TransmissionTable transmission_;
  ParameterLayout layout_;
  std::vector<int> free_dims_;
  std::vector<int> pose_first_;  // first pose parameter of each radiograph
  Vec3 centre_part_;
  double part_size_mm_ = 0.0;
  int edge_samples_ = 0;
  // Scratch reused between evaluations.
  std::vector<Vec3> part_vertices_, world_vertices_;
  Image rendered_, coarse_;
};

}  // namespace xgauge
