#include "xgauge/measure/inputs.h"

#include "xgauge/xray/detector_file.h"

#include "xgauge/core/config.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/image/stats.h"

#include <spdlog/spdlog.h>

#include <tbb/parallel_for.h>

#include <chrono>
#include <exception>

namespace xgauge {

namespace {

// `rect` (full-size pixels) at pyramid `level`, rounded outwards and clipped.
PixelRect rectAtLevelOutward(const PixelRect& rect, int level, const Image& image) {
  const int s = 1 << level;
  const int x0 = rect.x / s, y0 = rect.y / s;
  const int x1 = (rect.right() + s - 1) / s, y1 = (rect.bottom() + s - 1) / s;
  return PixelRect{x0, y0, x1 - x0, y1 - y0}.intersect(image.rect());
}

// The part's shadow: where a coarse copy of the normalized image is below
// 0.9, as a bounding box grown by 10 % of its size plus 8 pixels.
PixelRect automaticRoi(const std::vector<Image>& levels, const RadiographSpec& spec) {
  int level = 0;
  while (level + 1 < static_cast<int>(levels.size()) &&
         levels[static_cast<size_t>(level)].width() > 256)
    ++level;
  const Image& coarse = levels[static_cast<size_t>(level)];
  int x0 = coarse.width(), y0 = coarse.height(), x1 = -1, y1 = -1;
  for (int y = 0; y < coarse.height(); ++y)
    for (int x = 0; x < coarse.width(); ++x)
      if (coarse(x, y) < 0.9f)
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  if (x1 < 0)
    fail("{}: no part shadow found (no pixel below 0.9 of the open beam); give its roi",
         spec.image.string());
  const int s = 1 << level;
  PixelRect r{x0 * s, y0 * s, (x1 - x0 + 1) * s, (y1 - y0 + 1) * s};
  const int grow_x = r.width / 10 + 8, grow_y = r.height / 10 + 8;
  return PixelRect{r.x - grow_x, r.y - grow_y, r.width + 2 * grow_x, r.height + 2 * grow_y}
      .intersect(levels.front().rect());
}

// Parses a JSON input file once, recording its digest.
ConfigNode loadInputConfig(const std::filesystem::path& path,
                           std::map<std::string, std::string>& sha256) {
  ConfigNode node = ConfigNode::loadFile(path);
  sha256[path.string()] = node.sha256();
  return node;
}

// What a file of several frames was made into.
void logFrames(const std::filesystem::path& path, const RadiographFile& file) {
  if (file.frames > 1)
    spdlog::info("{}: the mean of {} frames ({})", path.string(), file.frames,
                 toString(file.format));
}

}  // namespace

void logPrepared(const RadiographSpec& spec, const PreparedRadiograph& prepared) {
  if (prepared.lag)
    spdlog::info("{}: lag of {} subtracted, {}", spec.image.string(), spec.previous.string(),
                 describeLag(*prepared.lag));
}

OpenBeamField openBeamOf(const RadiographFrames& frames, const Machine& machine) {
  return OpenBeamField::fromFrames(machine.openBeamGeometry(), frames.dark, frames.flat);
}

PreparedRadiograph prepareRadiograph(Image raw, const RadiographFrames& frames,
                                     const RadiographSpec& spec, const Machine& machine,
                                     const OpenBeamField* open_beam) {
  if (raw.width() != machine.columns || raw.height() != machine.rows)
    fail("{} is {}x{} pixels but the machine's detector is {}x{}", spec.image.string(),
         raw.width(), raw.height(), machine.columns, machine.rows);
  const std::string name = spec.image.string();
  NormalizedRadiograph normalized =
      normalizeRadiograph(std::move(raw), frames, spec.white_region, ClampPolicy::kNone, name);
  PreparedRadiograph out;
  out.open_beam = open_beam ? *open_beam : openBeamOf(frames, machine);
  out.repaired_pixels = normalized.repaired_pixels;
  out.lag = normalized.lag;
  out.white_mean_uncertainty = normalized.white_mean_uncertainty;
  int count = 1;
  while ((normalized.image.width() >> count) >= 64 && (normalized.image.height() >> count) >= 64)
    ++count;
  std::vector<Image> levels = buildPyramid(std::move(normalized.image), count);
  const Image& image = levels.front();
  if (!normalized.lag_signal.empty()) {
    out.lag_signal_white = meanOf(normalized.lag_signal, spec.white_region);
    std::vector<Image> lag_levels = buildPyramid(std::move(normalized.lag_signal), count);
    for (Image& level : lag_levels)
      if (level.width() >= PreparedRadiograph::kLagSignalWidthPx) level = Image();
    out.lag_signal_levels = SharedLevels(std::move(lag_levels));
  }
  PixelRect roi;
  if (spec.roi) {
    if (!image.rect().contains(*spec.roi))
      fail("{}: roi {} lies outside the {}x{} image", name, toString(*spec.roi), image.width(),
           image.height());
    roi = *spec.roi;
  } else {
    roi = automaticRoi(levels, spec);
  }
  for (int level = 0; level < count; ++level)
    out.rois.push_back(rectAtLevelOutward(roi, level, levels[static_cast<size_t>(level)]));
  out.levels = SharedLevels(std::move(levels));
  return out;
}

Image readInputRadiograph(const std::filesystem::path& path, const Machine& machine,
                          std::map<std::string, std::string>& sha256) {
  std::string digest;
  const ExpectedImageSize detector{machine.columns, machine.rows, "the machine's detector"};
  RadiographFile file = readRadiograph(path, &digest, &detector);
  logFrames(path, file);
  sha256[path.string()] = digest;
  return std::move(file.image);
}

std::vector<std::shared_ptr<const PreparedRadiograph>> loadRadiographs(
    const MeasurementJob& job, const Machine& machine, std::map<std::string, std::string>& sha256) {
  // Dark and flat frames are usually shared by every radiograph, and a
  // radiograph may be another's previous frame: each file is read once, in
  // the order the job names them (dark, flat, previous, image), all of them
  // at once (decoding a 3072^2 TIFF is a core's work for a tenth of a
  // second); the first that fails in that order is the error.
  std::vector<std::filesystem::path> files;
  std::map<std::filesystem::path, size_t> index, uses;
  for (const RadiographSpec& spec : job.radiographs)
    for (const std::filesystem::path* path : {&spec.dark, &spec.flat, &spec.previous, &spec.image})
      if (!path->empty()) {
        ++uses[*path];
        if (index.emplace(*path, files.size()).second) files.push_back(*path);
      }
  struct Read {
    RadiographFile file;
    std::string digest;
    std::exception_ptr error;
  };
  const auto start = std::chrono::steady_clock::now();
  const auto secondsSince = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  std::vector<Read> read(files.size());
  const ExpectedImageSize detector{machine.columns, machine.rows, "the machine's detector"};
  tbb::parallel_for(size_t{0}, files.size(), [&](size_t i) {
    try {
      read[i].file = readRadiograph(files[i], &read[i].digest, &detector);
    } catch (...) {
      read[i].error = std::current_exception();
    }
  });
  for (size_t i = 0; i < files.size(); ++i) {
    if (read[i].error) std::rethrow_exception(read[i].error);
    logFrames(files[i], read[i].file);
    sha256[files[i].string()] = read[i].digest;
  }
  spdlog::info("{} radiograph files read in {:.2f} s", files.size(), secondsSince(start));
  const auto prepare_start = std::chrono::steady_clock::now();
  auto frame = [&](const std::filesystem::path& path) -> const Image& {
    return read[index.at(path)].file.image;
  };
  if (machine.column_crosstalk > 0.0)
    spdlog::info("the detector's column crosstalk, {:.5f} +- {:.2g}, is undone on the raw frames",
                 machine.column_crosstalk, machine.column_crosstalk_uncertainty);
  std::vector<RadiographFrames> given(job.radiographs.size());
  // The dark and flat made ready and the open beam's field, once per pair.
  using Pair = std::pair<std::filesystem::path, std::filesystem::path>;
  std::map<Pair, FlatField> flat_fields;
  std::map<Pair, OpenBeamField> open_beams;
  for (size_t r = 0; r < job.radiographs.size(); ++r) {
    const RadiographSpec& spec = job.radiographs[r];
    if (!spec.dark.empty()) {
      given[r].dark = &frame(spec.dark);
      given[r].flat = &frame(spec.flat);
      given[r].column_crosstalk = machine.column_crosstalk;
      given[r].bad_pixels = machine.bad_pixels.get();
    }
    if (!spec.previous.empty()) {
      given[r].previous = &frame(spec.previous);
      given[r].previous_name = spec.previous.string();
      given[r].lag_fraction = machine.lag_fraction;
      given[r].lag_fraction_uncertainty = machine.lagFractionUncertainty();
    }
    const Pair pair{spec.dark, spec.flat};
    if (!spec.dark.empty() && !flat_fields.count(pair)) {
      try {
        flat_fields.emplace(pair, flatFieldOf(given[r]));
      } catch (const Error& e) {
        fail("{} with its dark and flat frames: {}", spec.image.string(), e.message());
      }
    }
    if (!spec.dark.empty()) given[r].flat_field = &flat_fields.at(pair);
    if (!open_beams.count(pair)) open_beams.emplace(pair, openBeamOf(given[r], machine));
  }
  // Each radiograph prepared on its own (they share only read-only frames),
  // the first error in the job's order thrown, the log in that order too.
  std::vector<std::shared_ptr<const PreparedRadiograph>> out(job.radiographs.size());
  std::vector<std::exception_ptr> errors(job.radiographs.size());
  tbb::parallel_for(size_t{0}, job.radiographs.size(), [&](size_t r) {
    const RadiographSpec& spec = job.radiographs[r];
    try {
      // A file only this radiograph names is moved, not copied.
      Image raw = uses.at(spec.image) > 1 ? Image(frame(spec.image))
                                          : std::move(read[index.at(spec.image)].file.image);
      out[r] = std::make_shared<const PreparedRadiograph>(prepareRadiograph(
          std::move(raw), given[r], spec, machine, &open_beams.at({spec.dark, spec.flat})));
    } catch (...) {
      errors[r] = std::current_exception();
    }
  });
  for (size_t r = 0; r < out.size(); ++r) {
    if (errors[r]) std::rethrow_exception(errors[r]);
    logPrepared(job.radiographs[r], *out[r]);
  }
  spdlog::info("{} radiograph(s) normalised in {:.2f} s", out.size(), secondsSince(prepare_start));
  return out;
}

MaterialScatter materialScatterFromConfig(const ConfigNode& node) {
  MaterialScatter out{ScatterModel::fromConfig(node), std::nullopt};
  if (auto curves = node.find("curve_moves")) out.curves = ScatterCurves::fromConfig(*curves);
  return out;
}

MeasurementInputs loadJobInputs(const ConfigNode& root, const std::filesystem::path& job_file,
                                bool needs_material) {
  MeasurementInputs in;
  in.sha256[job_file.string()] = root.sha256();
  const std::filesystem::path part_file = MeasurementJob::partFileOf(root, job_file);
  in.part = std::make_shared<const PartModel>(
      PartModel::fromConfig(loadInputConfig(part_file, in.sha256), part_file));
  for (const auto& [file, digest] : in.part->shapeFileDigests()) in.sha256[file] = digest;
  in.job = MeasurementJob::fromConfig(root, job_file, *in.part, needs_material);
  {
    const ConfigNode machine = loadInputConfig(in.job.machine_file, in.sha256);
    in.machine = Machine::fromConfig(machine);
    machine.finish();
  }
  // A characterised detector's halo, for a job without a "scatter" of its
  // own: measured on its own shot, it comes before a wedge calibration's.
  const std::optional<DetectorFile> detector = detectorFileOf(in.job.machine_file);
  const bool detector_halo = detector && detector->halo && !root.has("scatter");
  if (detector_halo) {
    in.job.scatter = *detector->halo;
    spdlog::info("{}: the characterised halo: {} kernel, {} border, weight {:.4f}, sigma {:.1f} mm",
                 detector->file.string(), toString(in.job.scatter.shape),
                 toString(in.job.scatter.border), in.job.scatter.weight, in.job.scatter.sigma_mm);
  }
  if (!in.job.material_file.empty()) {
    const ConfigNode material = loadInputConfig(in.job.material_file, in.sha256);
    in.material = ExponentialSum::fromConfig(material);
    // The detector's scatter its wedge calibration found, for a job without
    // a "scatter" of its own.
    if (auto found = material.find("scatter"); found && !root.has("scatter") && !detector_halo) {
      MaterialScatter scatter = materialScatterFromConfig(*found);
      in.job.scatter = scatter.model;
      in.scatter_curves = std::move(scatter.curves);
      spdlog::info("{}: the scatter its calibration found: weight {:.4f}, sigma {:.1f} mm",
                   in.job.material_file.string(), in.job.scatter.weight, in.job.scatter.sigma_mm);
    } else if (found && detector_halo) {
      // A material calibrated with this very halo (the same detector file's)
      // moved its curve with the halo's weight and width: the budget moves
      // both together, as for the scatter a calibration found; counted
      // apart, a halo's uncertainty entered U twice with the sign that
      // cancels dropped (docs/method.md, "The scatter from the calibration
      // shot").
      // The curve moved by the calibration's u of the weight and width and
      // to the kernel's alternatives: the same as the job's, else the moves
      // would not be the budget's.
      MaterialScatter scatter = materialScatterFromConfig(*found);
      if (scatter.model.sameKernel(in.job.scatter) &&
          scatter.model.weight_uncertainty == in.job.scatter.weight_uncertainty &&
          scatter.model.sigma_uncertainty_mm == in.job.scatter.sigma_uncertainty_mm &&
          scatter.model.equivalent_end == in.job.scatter.equivalent_end &&
          scatter.model.kernel_choice == in.job.scatter.kernel_choice)
        in.scatter_curves = std::move(scatter.curves);
    }
    material.finish();
  }
  if (!in.job.verification_file.empty()) {
    const ConfigNode verification = loadInputConfig(in.job.verification_file, in.sha256);
    in.verification = Verification::fromConfig(verification, in.job.verification_file);
    verification.finish();
  }
  return in;
}

MeasurementInputs loadMeasurementInputs(const ConfigNode& root,
                                        const std::filesystem::path& job_file,
                                        bool needs_material) {
  MeasurementInputs in = loadJobInputs(root, job_file, needs_material);
  in.radiographs = loadRadiographs(in.job, in.machine, in.sha256);
  return in;
}

MeasurementInputs loadMeasurementInputs(const std::filesystem::path& job_file) {
  const ConfigNode root = ConfigNode::loadFile(job_file);
  MeasurementInputs in = loadMeasurementInputs(root, job_file, true);
  root.finish();
  return in;
}

}  // namespace xgauge
