// The loaded inputs of a measurement: one loader reads the job and every file
// it names exactly once (part model, machine, material, each radiograph and
// each dark and flat frame) and prepares the radiographs; the fit and the
// output writers share what it returns. Every file's SHA-256 is taken from
// the bytes that were parsed, so a result names exactly what it used.
#pragma once

#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/image/radiograph.h"
#include "xgauge/image/scatter.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/scatter_curves.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/verification.h"
#include "xgauge/xray/machine.h"

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

// The levels of a pyramid, each shared by the copies of a radiograph: a
// budget's moved radiograph (its open beam's heel, its lag, its white
// region) replaces the levels it changes and shares the others. A deep copy
// per move held three 3072^2 pyramids at once in a triple's budget, its
// process's peak.
class SharedLevels {
 public:
  SharedLevels() = default;
  explicit SharedLevels(std::vector<Image> levels) {
    for (Image& level : levels) levels_.push_back(std::make_shared<const Image>(std::move(level)));
  }
  const Image& operator[](size_t level) const { return *levels_[level]; }
  const Image& front() const { return *levels_.front(); }
  size_t size() const { return levels_.size(); }
  bool empty() const { return levels_.empty(); }
  // Level `level` of this copy replaced; the other copies keep theirs.
  void replace(size_t level, Image image) {
    levels_[level] = std::make_shared<const Image>(std::move(image));
  }

 private:
  std::vector<std::shared_ptr<const Image>> levels_;
};

// A radiograph prepared for fitting: normalized without the clamp (dark/flat
// and the white region, image/radiograph.h), its pyramid and its roi.
struct PreparedRadiograph {
  SharedLevels levels;          // 0 = full size, halving down to about 64 px
  std::vector<PixelRect> rois;  // the region compared, per level
  int64_t repaired_pixels = 0;  // bad pixels repaired by the flat-field correction
  std::optional<LagEstimate> lag;  // the previous frame's lag subtracted, if any
  // With an estimated lag: per level, the lag signal subtracted per unit
  // fraction (normalized like `levels`), kept only on levels narrower than
  // kLagSignalWidthPx (the budget propagates the lag there); empty elsewhere.
  SharedLevels lag_signal_levels;
  double lag_signal_white = 0.0;  // its mean over the white region (about 1)
  // The white region mean's relative standard uncertainty (NormalizedRadiograph).
  double white_mean_uncertainty = 0.0;
  // The open beam's field fitted to the flat frame (uniform without one):
  // the field the scatter's halo is simulated in (decision 0041).
  OpenBeamField open_beam;
  static constexpr int kLagSignalWidthPx = 2048;
};

// Normalizes `raw` (named `spec.image` in errors) and builds its pyramid and
// roi (spec.roi, or the part's shadow: job.h). Throws Error naming the image
// when its size is not the machine's detector or a region lies outside it.
// `open_beam`: the field fitted to the frames' flat (openBeamOf), which
// radiographs sharing their dark and flat share; fitted here when null.
PreparedRadiograph prepareRadiograph(Image raw, const RadiographFrames& frames,
                                     const RadiographSpec& spec, const Machine& machine,
                                     const OpenBeamField* open_beam = nullptr);

// Logs what the preparation did that a reader of measure.log should know
// (the lag subtracted), apart from prepareRadiograph so that radiographs
// prepared together log in the job's order.
void logPrepared(const RadiographSpec& spec, const PreparedRadiograph& prepared);

// The open beam's field the frames' flat (less their dark) gives on this
// machine's panel; a uniform one without frames.
OpenBeamField openBeamOf(const RadiographFrames& frames, const Machine& machine);

// The detector scatter a wedge calibration found, as its material.json
// carries it under "scatter", with how the curve moves with it when given.
struct MaterialScatter {
  ScatterModel model;
  std::optional<ScatterCurves> curves;
};
MaterialScatter materialScatterFromConfig(const ConfigNode& node);

struct MeasurementInputs {
  MeasurementJob job;
  std::shared_ptr<const PartModel> part;
  Machine machine;
  std::optional<ExponentialSum> material;  // absent when the job names none (a calibration)
  // How the material's curve moves with the scatter, when the job takes its
  // scatter from the material's calibration (no "scatter" of its own) and
  // the material file says: the budget then moves both together.
  std::optional<ScatterCurves> scatter_curves;
  // The job's verification, when it names one.
  std::optional<Verification> verification;
  // One per job.radiographs entry, in its order.
  std::vector<std::shared_ptr<const PreparedRadiograph>> radiographs;
  // Every file read, as given in the job (or its folder), with its SHA-256.
  std::map<std::string, std::string> sha256;
};

// Reads the job file and everything it names. Throws Error naming the file
// and key of the first problem.
MeasurementInputs loadMeasurementInputs(const std::filesystem::path& job_file);

// The same from a job file the caller has parsed (a calibration job with keys
// of its own, which the caller reads before calling root.finish()). Without
// `needs_material` the "material" key is optional.
MeasurementInputs loadMeasurementInputs(const ConfigNode& root,
                                        const std::filesystem::path& job_file,
                                        bool needs_material);

// Every input of a job but its radiographs (`radiographs` left empty): the
// part, machine, detector file, material and verification, each read and
// checked. An inspection plan checks its job with it before any part.
MeasurementInputs loadJobInputs(const ConfigNode& root, const std::filesystem::path& job_file,
                                bool needs_material);

// Reads a radiograph file of any format (image/radiograph_file.h; the mean
// of its frames when it holds several) once, recording its SHA-256 in
// `sha256` (keyed by the path as given, NXtomo selector included). Refuses,
// before decoding, an image whose size is not the machine's.
Image readInputRadiograph(const std::filesystem::path& path, const Machine& machine,
                          std::map<std::string, std::string>& sha256);

// Reads and prepares every radiograph of `job` from their files, each file
// (dark and flat frames shared between radiographs too) read once.
std::vector<std::shared_ptr<const PreparedRadiograph>> loadRadiographs(
    const MeasurementJob& job, const Machine& machine, std::map<std::string, std::string>& sha256);

}  // namespace xgauge
