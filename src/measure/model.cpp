#include "xgauge/measure/model.h"

#include "xgauge/image/bad_pixels.h"
#include "xgauge/image/blur.h"
#include "xgauge/image/pyramid.h"
#include "xgauge/image/stats.h"
#include "xgauge/image/tiff.h"
#include "xgauge/loss/loss.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/renderer.h"

#include <spdlog/spdlog.h>

#include <cmath>

namespace xgauge {

namespace {

constexpr double kInvalidLoss = 1e6;  // parameters the part or the beam cannot take

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

}  // namespace

PreparedRadiograph prepareRadiograph(const RadiographSpec& spec, const Machine& machine) {
  PreparedRadiograph out;
  out.spec = spec;
  Image image = readTiff(spec.image);
  if (image.width() != machine.columns || image.height() != machine.rows)
    fail("{} is {}x{} pixels but the machine's detector is {}x{}", spec.image.string(),
         image.width(), image.height(), machine.columns, machine.rows);
  if (!spec.dark.empty()) {
    const Image dark = readTiff(spec.dark), flat = readTiff(spec.flat);
    try {
      image = flatFieldCorrectRepairing(image, dark, flat, &out.repaired_pixels);
    } catch (const Error& e) {
      fail("{} with {} and {}: {}", spec.image.string(), spec.dark.string(), spec.flat.string(),
           e.message());
    }
  }
  if (!image.rect().contains(spec.white_region))
    fail("{}: white region {} lies outside the {}x{} image", spec.image.string(),
         toString(spec.white_region), image.width(), image.height());
  const double white = meanOf(image, spec.white_region);
  if (!(white > 0.0))
    fail("{}: the white region's mean is {} (must be positive)", spec.image.string(), white);
  const float scale = static_cast<float>(1.0 / white);
  for (float& p : image.pixels()) p *= scale;

  int count = 1;
  while ((image.width() >> count) >= 64 && (image.height() >> count) >= 64) ++count;
  out.levels = buildPyramid(image, count);
  PixelRect roi;
  if (spec.roi) {
    if (!image.rect().contains(*spec.roi))
      fail("{}: roi {} lies outside the {}x{} image", spec.image.string(), toString(*spec.roi),
           image.width(), image.height());
    roi = *spec.roi;
  } else {
    roi = automaticRoi(out.levels, spec);
  }
  for (int level = 0; level < count; ++level)
    out.rois.push_back(rectAtLevelOutward(roi, level, out.levels[static_cast<size_t>(level)]));
  return out;
}

namespace {

Vec3 axisFromAngles(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kDegToRad, el = elevation_deg * kDegToRad;
  return {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
}

}  // namespace

double ScatterEstimate::at(double u_level, double v_level) const {
  // Bilinear in coarse pixel-centre units.
  const double u = u_level * ratio - 0.5, v = v_level * ratio - 0.5;
  const double x = std::clamp(u, 0.0, blurred.width() - 1.0);
  const double y = std::clamp(v, 0.0, blurred.height() - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, blurred.width() - 1), y1 = std::min(y0 + 1, blurred.height() - 1);
  const double fx = x - x0, fy = y - y0;
  auto value = [&](int i, int j) { return static_cast<double>(blurred(i, j)); };
  return (1 - fy) * ((1 - fx) * value(x0, y0) + fx * value(x1, y0)) +
         fy * ((1 - fx) * value(x0, y1) + fx * value(x1, y1));
}

ForwardModel::ForwardModel(const MeasurementJob& job)
    : ForwardModel(job, ExponentialSum::load(job.material_file)) {}

ForwardModel::ForwardModel(const MeasurementJob& job, const ExponentialSum& material)
    : job_(job), part_(PartModel::load(job.part_file)), machine_(Machine::load(job.machine_file)) {
  // The part: its reference centre and the dimension parameters.
  const std::vector<double> nominal = part_.nominalValues();
  const BoundingBox box = boundingBox(part_.mesh(nominal));
  centre_part_ = 0.5 * (box.min_mm + box.max_mm);
  part_size_mm_ = box.diagonal();
  const auto& dims = part_.dimensions();
  for (size_t i = 0; i < dims.size(); ++i) {
    const Dimension& d = dims[i];
    const bool free = std::find(job.free_dimensions.begin(), job.free_dimensions.end(), d.name) !=
                      job.free_dimensions.end();
    double start = d.nominal;
    if (auto f = job.fixed_dimensions.find(d.name); f != job.fixed_dimensions.end())
      start = f->second;
    if (auto s = job.start.find(d.name); s != job.start.end()) start = s->second;
    double lo = start, hi = start;
    if (free) {
      free_dims_.push_back(static_cast<int>(i));
      if (auto b = job.bounds.find(d.name); b != job.bounds.end()) {
        lo = b->second[0], hi = b->second[1];
      } else {
        lo = std::max(d.min, d.nominal - 0.1 * std::abs(d.nominal));
        hi = std::min(d.max, d.nominal + 0.1 * std::abs(d.nominal));
      }
      start = std::clamp(start, lo, hi);
    }
    lower_.push_back(lo), upper_.push_back(hi), start_.push_back(start);
    kinds_.push_back(Kind::kDimension);
  }
  part_.validate(start_);

  // The material: tabulated over the longest chord the part can have.
  double longest = 0.0;
  for (size_t i = 0; i < dims.size(); ++i) longest = std::max(longest, dims[i].max);
  max_path_mm_ = 4.0 * box.diagonal() + 2.0 * longest;
  setMaterial(material);

  // The radiographs and their pose parameters.
  for (const RadiographSpec& spec : job.radiographs) {
    radiographs_.push_back(prepareRadiograph(spec, machine_));
    pose_offset_.push_back(size());
    switch (spec.pattern) {
      case Acquisition::kFree:
      case Acquisition::kRotated:
        for (int k = 0; k < 3; ++k) {
          lower_.push_back(job.rotation_bounds_deg[static_cast<size_t>(k)][0]);
          upper_.push_back(job.rotation_bounds_deg[static_cast<size_t>(k)][1]);
          start_.push_back(0.5 * (lower_.back() + upper_.back()));
          kinds_.push_back(Kind::kRotation);
        }
        for (int k = 0; k < 3; ++k) {
          lower_.push_back(job.centre_bounds_mm[static_cast<size_t>(k)][0]);
          upper_.push_back(job.centre_bounds_mm[static_cast<size_t>(k)][1]);
          start_.push_back(0.5 * (lower_.back() + upper_.back()));
          kinds_.push_back(Kind::kPosition);
        }
        break;
      case Acquisition::kTranslated:
        lower_.insert(lower_.end(), {-180.0, -90.0});
        upper_.insert(upper_.end(), {180.0, 90.0});
        start_.insert(start_.end(), {0.0, 0.0});
        kinds_.insert(kinds_.end(), {Kind::kAxis, Kind::kAxis});
        break;
      case Acquisition::kKnown:
        break;
    }
  }
  for (size_t i = 1; i < radiographs_.size(); ++i)
    if (radiographs_[i].levels.size() != radiographs_[0].levels.size())
      fail("radiographs {} and {} differ in size", radiographs_[0].spec.name,
           radiographs_[i].spec.name);
}

void ForwardModel::setMaterial(const ExponentialSum& material) {
  material_ = std::make_shared<ExponentialSum>(material);
  transmission_ = TransmissionTable::forMaterial(material, max_path_mm_);
}

void ForwardModel::freeMaterial(const ExponentialSum& material, std::vector<double>& theta) {
  XG_CHECK(material_offset_ < 0, "the material is free already");
  XG_CHECK(theta.size() == lower_.size(), "theta has the wrong size");
  const auto& terms = material.terms();
  material_offset_ = size();
  material_terms_ = static_cast<int>(terms.size());
  double rest = 1.0;
  for (size_t k = 0; k + 1 < terms.size(); ++k) {
    const double u = rest > 0.0 ? std::clamp(terms[k].weight / rest, 0.0, 1.0) : 0.0;
    rest -= terms[k].weight;
    lower_.push_back(0.0), upper_.push_back(1.0), start_.push_back(u), theta.push_back(u);
    kinds_.push_back(Kind::kMaterial);
  }
  for (const ExponentialTerm& term : terms) {
    const double mu = std::clamp(term.mu_per_mm, 0.0, 10.0);
    lower_.push_back(0.0), upper_.push_back(10.0), start_.push_back(mu), theta.push_back(mu);
    kinds_.push_back(Kind::kMaterial);
  }
  setMaterial(materialOf(theta));
}

std::vector<int> ForwardModel::materialIndices() const {
  std::vector<int> out;
  for (int i = std::max(0, material_offset_); material_offset_ >= 0 && i < size(); ++i)
    out.push_back(i);
  return out;
}

ExponentialSum ForwardModel::materialOf(std::span<const double> theta) const {
  if (material_offset_ < 0) return *material_;
  const int m = material_terms_;
  const double* u = theta.data() + material_offset_;
  const double* mu = u + (m - 1);
  std::vector<ExponentialTerm> terms;
  double rest = 1.0;
  for (int k = 0; k < m; ++k) {
    const double a = k + 1 < m ? rest * std::clamp(u[k], 0.0, 1.0) : rest;
    rest -= a;
    if (a > 0.0) terms.push_back({a, std::max(0.0, mu[k])});
  }
  double sum = 0.0;
  for (const auto& t : terms) sum += t.weight;
  for (auto& t : terms) t.weight /= sum;
  return ExponentialSum(std::move(terms), "free in the fit");
}

void ForwardModel::useMaterialOf(std::span<const double> theta) {
  if (material_offset_ < 0) return;
  const ExponentialSum wanted = materialOf(theta);
  const auto& now = material_->terms();
  bool same = now.size() == wanted.terms().size();
  for (size_t k = 0; same && k < now.size(); ++k)
    same = now[k].weight == wanted.terms()[k].weight &&
           now[k].mu_per_mm == wanted.terms()[k].mu_per_mm;
  if (!same) setMaterial(wanted);
}

int ForwardModel::levelForWidth(int min_width) const {
  int level = levels() - 1;
  while (level > 0 && radiographs_.front().levels[static_cast<size_t>(level)].width() < min_width)
    --level;
  return level;
}

std::vector<int> ForwardModel::poseIndices(int radiograph) const {
  const int first = pose_offset_[static_cast<size_t>(radiograph)];
  const int end = static_cast<size_t>(radiograph) + 1 < pose_offset_.size()
                      ? pose_offset_[static_cast<size_t>(radiograph) + 1]
                      : size();
  std::vector<int> out;
  for (int i = first; i < end; ++i) out.push_back(i);
  return out;
}

Pose ForwardModel::pose(std::span<const double> theta, int radiograph) const {
  const RadiographSpec& spec = radiographs_[static_cast<size_t>(radiograph)].spec;
  const double* p = theta.data() + pose_offset_[static_cast<size_t>(radiograph)];
  switch (spec.pattern) {
    case Acquisition::kFree:
    case Acquisition::kRotated: {
      Pose out = Pose::fromEulerDeg(Vec3(p[0], p[1], p[2]), Vec3::Zero());
      out.translation_mm = Vec3(p[3], p[4], p[5]) - out.rotation * centre_part_;
      return out;
    }
    case Acquisition::kTranslated: {
      Pose out = pose(theta, spec.reference);
      out.translation_mm += spec.distance_mm * axisFromAngles(p[0], p[1]);
      return out;
    }
    case Acquisition::kKnown:
      return spec.known_pose;
  }
  return {};
}

Machine ForwardModel::machineAt(int level) const {
  Machine m = machine_;
  const double s = static_cast<double>(1 << level);
  const Image& image = radiographs_.front().levels[static_cast<size_t>(level)];
  m.columns = image.width();
  m.rows = image.height();
  m.pitch_u_mm *= s;
  m.pitch_v_mm *= s;
  m.cx_px /= s;
  m.cy_px /= s;
  return m;
}

WorldMesh ForwardModel::posedMesh(std::span<const double> theta, int radiograph) {
  part_.evaluate(theta.first(part_.dimensions().size()), part_vertices_);
  poseVertices(pose(theta, radiograph), part_vertices_, world_vertices_);
  return WorldMesh{world_vertices_, part_.triangles()};
}

Image ForwardModel::pathLengths(std::span<const double> theta, int radiograph, int level,
                                const PixelRect& region) {
  useMaterialOf(theta);
  const WorldMesh mesh = posedMesh(theta, radiograph);
  RenderOptions options;
  options.region = region;
  Image out;
  renderPathLength(machineAt(level), mesh, options, out);
  return out;
}

ScatterEstimate ForwardModel::scatter(std::span<const double> theta, int radiograph, int level) {
  XG_CHECK(job_.scatter.enabled(), "the job models no scatter");
  useMaterialOf(theta);
  return scatterOf(posedMesh(theta, radiograph), radiograph, level);
}

ScatterEstimate ForwardModel::scatterOf(const WorldMesh& mesh, int radiograph, int level) {
  // The kernel is hundreds of pixels wide: a coarse render of the whole
  // detector carries all of G(I).
  const int coarse_level = std::max(level, levelForWidth(128));
  const Machine mc = machineAt(coarse_level);
  RenderOptions coarse_options;
  renderIntensity(mc, mesh, transmission_, coarse_options, coarse_);
  ScatterEstimate out;
  out.blurred = gaussianBlur(coarse_, job_.scatter.sigma_mm / mc.pitch_u_mm);
  // The model's open-beam level in the white region (full-size coordinates).
  const PixelRect white = radiographs_[static_cast<size_t>(radiograph)].spec.white_region;
  const double full_to_coarse = 1.0 / static_cast<double>(1 << coarse_level);
  out.ratio = full_to_coarse;
  double white_sum = 0.0;
  constexpr int kGrid = 8;
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i)
      white_sum += out.at(white.x + (i + 0.5) * white.width / kGrid,
                          white.y + (j + 0.5) * white.height / kGrid);
  const double w = job_.scatter.weight;
  out.open = (1.0 - w) + w * white_sum / (kGrid * kGrid);
  out.ratio = static_cast<double>(1 << level) / static_cast<double>(1 << coarse_level);
  return out;
}

Image ForwardModel::simulate(std::span<const double> theta, int radiograph, int level, int samples,
                             const PixelRect& region) {
  useMaterialOf(theta);
  const WorldMesh mesh = posedMesh(theta, radiograph);
  RenderOptions options;
  options.samples_per_axis = samples;
  options.region = region;
  Image out;
  renderIntensity(machineAt(level), mesh, transmission_, options, out);
  if (!job_.scatter.enabled()) return out;

  // Scintillator scatter, I' = (1 - w) I + w G(I), with the same
  // white-region normalization as the measured image.
  const ScatterEstimate spread = scatterOf(mesh, radiograph, level);
  const double w = job_.scatter.weight;
  for (int y = 0; y < out.height(); ++y)
    for (int x = 0; x < out.width(); ++x) {
      const double g = spread.at(region.x + x + 0.5, region.y + y + 0.5);
      out(x, y) =
          static_cast<float>(((1.0 - w) * static_cast<double>(out(x, y)) + w * g) / spread.open);
    }
  return out;
}

bool ForwardModel::forEachSimulated(
    std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
    const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use) {
  try {
    part_.validate(theta.first(part_.dimensions().size()));
    useMaterialOf(theta);
    for (int r : radiographs) {
      const PreparedRadiograph& rad = radiographs_[static_cast<size_t>(r)];
      const PixelRect roi = rad.rois[static_cast<size_t>(level)];
      rendered_ = simulate(theta, r, level, samples, roi);
      use(rad, roi, rendered_);
    }
  } catch (const Error& e) {
    // Dimensions the part cannot take, or a pose outside the beam: a bad
    // point for the optimiser, not a failure of the measurement.
    spdlog::debug("invalid parameters: {}", e.message());
    return false;
  }
  return true;
}

bool ForwardModel::residuals(std::span<const double> theta, int level, int samples,
                             std::span<const int> radiographs, std::vector<double>& out) {
  out.clear();
  return forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        const Image& measured = rad.levels[static_cast<size_t>(level)];
        const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
        for (int y = 0; y < roi.height; ++y)
          for (int x = 0; x < roi.width; ++x)
            out.push_back(scale * (static_cast<double>(simulated(x, y)) -
                                   static_cast<double>(measured(roi.x + x, roi.y + y))));
      });
}

double ForwardModel::loss(std::span<const double> theta, int level, int samples,
                          std::span<const int> radiographs) {
  const LossKind kind = lossKindFromName(job_.loss);
  double total = 0.0;
  const bool valid = forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        total += imageLoss(simulated, rad.levels[static_cast<size_t>(level)], roi, kind);
      });
  return valid ? total : kInvalidLoss;
}

}  // namespace xgauge
