#include "xgauge/measure/model.h"

#include "xgauge/image/blur.h"
#include "xgauge/loss/loss.h"
#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/renderer.h"

#include <tbb/parallel_for.h>

#include <cmath>

namespace xgauge {

namespace {

Vec3 axisFromAngles(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kDegToRad, el = elevation_deg * kDegToRad;
  return {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
}

}  // namespace

ScatterEstimate::Tap ScatterEstimate::tap(double u_level, double v_level) const {
  // Bilinear in coarse pixel-centre units.
  const double u = u_level * ratio - 0.5, v = v_level * ratio - 0.5;
  const double x = std::clamp(u, 0.0, blurred.width() - 1.0);
  const double y = std::clamp(v, 0.0, blurred.height() - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  return {x0, y0, std::min(x0 + 1, blurred.width() - 1), std::min(y0 + 1, blurred.height() - 1),
          x - x0, y - y0};
}

namespace {

// Refuses pose bounds under which the part can never be inside the beam or
// cast a shadow on the detector; `reach_mm` bounds the distance from the
// part's centre to any of its points.
void checkPoseBounds(const MeasurementJob& job, const Machine& machine, double reach_mm) {
  const auto& c = job.centre_bounds_mm;
  const double d = machine.source_detector_distance_mm;
  const SourceLocation where = SourceLocation::at(job.file.string(), "/pose_bounds/centre_mm");
  const double z0 = std::max(c[2][0] - reach_mm, 1e-6), z1 = std::min(c[2][1] + reach_mm, d - 1e-6);
  if (c[2][1] - reach_mm <= 0.0 || c[2][0] + reach_mm >= d || z0 >= z1)
    failAt(where,
           "centre z in [{}, {}] mm keeps the part (reaching {:.1f} mm from its centre) out of "
           "the beam: it must lie between the detector (z = 0) and the source (z = {} mm)",
           c[2][0], c[2][1], reach_mm, d);
  // The shadows of every allowed position lie within the shadow of this box.
  std::vector<Vec3> corners;
  for (int k = 0; k < 8; ++k)
    corners.emplace_back(k & 1 ? c[0][1] + reach_mm : c[0][0] - reach_mm,
                         k & 2 ? c[1][1] + reach_mm : c[1][0] - reach_mm, k & 4 ? z1 : z0);
  if (auto why = shadowMissesDetector(machine, corners))
    failAt(where, "no centre within these bounds puts the part in view: {}", *why);
}

}  // namespace

ForwardModel::ForwardModel(const MeasurementInputs& inputs)
    : ForwardModel(inputs, [&]() -> const ExponentialSum& {
        if (!inputs.material) fail("{}: the job names no material", inputs.job.file.string());
        return *inputs.material;
      }()) {}

ForwardModel::ForwardModel(const MeasurementInputs& inputs, const ExponentialSum& material)
    : inputs_(inputs), part_(*inputs.part), base_material_(material), material_(material) {
  XG_CHECK(
      inputs.radiographs.size() == inputs.job.radiographs.size() && !inputs.radiographs.empty(),
      "the inputs hold {} prepared radiographs for {} in the job", inputs.radiographs.size(),
      inputs.job.radiographs.size());
  const MeasurementJob& job = inputs.job;

  // The part: its reference centre and the dimension parameters.
  const std::vector<double> nominal = part_.nominalValues();
  const BoundingBox box = boundingBox(part_.mesh(nominal));
  centre_part_ = 0.5 * (box.min_mm + box.max_mm);
  part_size_mm_ = box.diagonal();
  const auto& dims = part_.dimensions();
  std::vector<std::string> names;
  std::vector<double> lower, upper, start;
  for (size_t i = 0; i < dims.size(); ++i) {
    const Dimension& d = dims[i];
    const bool free = std::find(job.free_dimensions.begin(), job.free_dimensions.end(), d.name) !=
                      job.free_dimensions.end();
    double value = d.nominal;
    if (auto f = job.fixed_dimensions.find(d.name); f != job.fixed_dimensions.end())
      value = f->second;
    if (auto s = job.start.find(d.name); s != job.start.end()) value = s->second;
    double lo = value, hi = value;
    if (free) {
      free_dims_.push_back(static_cast<int>(i));
      if (auto b = job.bounds.find(d.name); b != job.bounds.end()) {
        lo = b->second[0], hi = b->second[1];
      } else {
        lo = std::max(d.min, d.nominal - 0.1 * std::abs(d.nominal));
        hi = std::min(d.max, d.nominal + 0.1 * std::abs(d.nominal));
      }
      value = std::clamp(value, lo, hi);
    }
    names.push_back(d.name), lower.push_back(lo), upper.push_back(hi), start.push_back(value);
  }
  layout_.add("dim", ParameterKind::kDimension, names, lower, upper, start);
  if (const auto why = part_.invalidity(layout_.start()))
    failAt(SourceLocation::at(job.file.string(), "/dimensions"),
           "the values the fit starts from do not make a valid part: {}", *why);
  checkPoseBounds(job, machine(), 0.5 * part_size_mm_);

  // The material: tabulated over the longest chord the part can have.
  double longest = 0.0;
  for (const Dimension& d : dims) longest = std::max(longest, d.max);
  max_path_mm_ = 4.0 * box.diagonal() + 2.0 * longest;
  setMaterial(material);

  // Each radiograph's pose parameters.
  const size_t levels = radiograph(0).levels.size();
  for (int r = 0; r < radiographCount(); ++r) {
    const RadiographSpec& s = spec(r);
    if (radiograph(r).levels.size() != levels)
      fail("radiographs {} and {} differ in size", spec(0).name, s.name);
    pose_first_.push_back(layout_.size());
    switch (s.pattern) {
      case Acquisition::kFree:
      case Acquisition::kRotated: {
        std::vector<double> lo, hi, mid;
        for (const auto& range : job.rotation_bounds_deg)
          lo.push_back(range[0]), hi.push_back(range[1]),
              mid.push_back(0.5 * (range[0] + range[1]));
        layout_.add(s.name + "/rotation", ParameterKind::kRotation, {"rx", "ry", "rz"}, lo, hi,
                    mid);
        lo.clear(), hi.clear(), mid.clear();
        for (const auto& range : job.centre_bounds_mm)
          lo.push_back(range[0]), hi.push_back(range[1]),
              mid.push_back(0.5 * (range[0] + range[1]));
        layout_.add(s.name + "/position", ParameterKind::kPosition, {"x", "y", "z"}, lo, hi, mid);
        break;
      }
      case Acquisition::kTranslated:
        layout_.add(
            s.name + "/axis", ParameterKind::kAxis, {"azimuth", "elevation"},
            {-180.0, s.axis_elevation_bounds_deg[0]}, {180.0, s.axis_elevation_bounds_deg[1]},
            {0.0, std::clamp(0.0, s.axis_elevation_bounds_deg[0], s.axis_elevation_bounds_deg[1])});
        break;
      case Acquisition::kKnown:
        break;
    }
  }
  if (job.refine_material == MaterialRefinement::kRateScale) addRateScale();
}

void ForwardModel::setMaterial(const ExponentialSum& material) {
  base_material_ = material;
  useMaterial(material);
}

void ForwardModel::useMaterial(const ExponentialSum& material) {
  material_ = material;
  transmission_ = TransmissionTable::forMaterial(material, max_path_mm_);
}

void ForwardModel::addRateScale() {
  // The prior is the job's material's, the same for a model built on one of
  // its moved curves (the budget's), so that every model of one measurement
  // weighs the refinement alike. Checked here, where every path to a
  // measurement (a job, a study's run, the budget's moved models) passes.
  const MeasurementJob& job = inputs_.job;
  if (!inputs_.material)
    fail("{}: /refine_material: the job names no material to refine", job.file.string());
  const ExponentialSum& stated = *inputs_.material;
  rate_scale_prior_ = stated.rateScaleFor(stated.transmissionUncertainty(), part_size_mm_);
  if (!(rate_scale_prior_ > 0.0))
    fail("{}: /refine_material: the refinement is weighed by the material's stated uncertainty, "
         "and {} states none (uncertainty.transmission is 0)",
         job.file.string(), job.material_file.string());
  const double reach = std::min(kRateScaleReach * rate_scale_prior_, 0.5);
  rate_scale_index_ = layout_.add("material_refinement", ParameterKind::kMaterial, {"rate_scale"},
                                  {-reach}, {reach}, {0.0});
}

void ForwardModel::freeMaterial(const ExponentialSum& material, std::vector<double>& theta,
                                double rate_floor_per_mm) {
  XG_CHECK(material_terms_ == 0, "the material is free already");
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  const auto& terms = material.terms();
  const size_t m = terms.size();
  std::vector<std::string> names;
  std::vector<double> lower, upper, start;
  double rest = 1.0;
  for (size_t k = 0; k + 1 < m; ++k) {
    const double u = rest > 0.0 ? std::clamp(terms[k].weight / rest, 0.0, 1.0) : 0.0;
    rest -= terms[k].weight;
    names.push_back(fmt::format("fraction{}", k + 1));
    lower.push_back(0.0), upper.push_back(1.0), start.push_back(u);
  }
  for (size_t k = 0; k < m; ++k) {
    names.push_back(fmt::format("rate{}", k + 1));
    const double low = std::min(rate_floor_per_mm, 10.0);
    lower.push_back(low), upper.push_back(10.0);
    start.push_back(std::clamp(terms[k].mu_per_mm, low, 10.0));
  }
  layout_.add("material", ParameterKind::kMaterial, names, lower, upper, start);
  theta.insert(theta.end(), start.begin(), start.end());
  material_terms_ = static_cast<int>(m);
  setMaterial(materialOf(theta));
}

ExponentialSum ForwardModel::materialOf(std::span<const double> theta) const {
  if (rate_scale_index_ >= 0)
    return base_material_.withScaledRates(theta[static_cast<size_t>(rate_scale_index_)]);
  if (material_terms_ == 0) return material_;
  const int m = material_terms_;
  const double* u = theta.data() + layout_.block("material").front();
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
  if (material_terms_ == 0 && rate_scale_index_ < 0) return;
  const ExponentialSum wanted = materialOf(theta);
  const auto& now = material_.terms();
  bool same = now.size() == wanted.terms().size();
  for (size_t k = 0; same && k < now.size(); ++k)
    same = now[k].weight == wanted.terms()[k].weight &&
           now[k].mu_per_mm == wanted.terms()[k].mu_per_mm;
  if (!same) useMaterial(wanted);
}

int ForwardModel::levelForWidth(int min_width) const {
  if (min_width <= 0) return 0;
  int level = levels() - 1;
  while (level > 0 && radiograph(0).levels[static_cast<size_t>(level)].width() < min_width) --level;
  return level;
}

std::vector<int> ForwardModel::poseIndices(int r) const {
  switch (spec(r).pattern) {
    case Acquisition::kFree:
    case Acquisition::kRotated: {
      std::vector<int> out = layout_.block(spec(r).name + "/rotation");
      for (int i : layout_.block(spec(r).name + "/position")) out.push_back(i);
      return out;
    }
    case Acquisition::kTranslated:
      return layout_.block(spec(r).name + "/axis");
    case Acquisition::kKnown:
      break;
  }
  return {};
}

std::vector<int> ForwardModel::jointIndices() const {
  std::vector<int> all = free_dims_;
  for (int r = 0; r < radiographCount(); ++r)
    for (int i : poseIndices(r)) all.push_back(i);
  for (int i : materialIndices()) all.push_back(i);
  return all;
}

std::vector<int> ForwardModel::leastSquaresIndices() const {
  std::vector<int> all = jointIndices();
  if (rate_scale_index_ >= 0) all.push_back(rate_scale_index_);
  return all;
}

Pose ForwardModel::pose(std::span<const double> theta, int radiograph) const {
  const RadiographSpec& s = spec(radiograph);
  // The hot path: the pose block's first index was found once, at construction
  // (rotation then position, or the axis: model.h).
  const double* p = theta.data() + pose_first_[static_cast<size_t>(radiograph)];
  switch (s.pattern) {
    case Acquisition::kFree:
    case Acquisition::kRotated: {
      Pose out = Pose::fromEulerDeg(Vec3(p[0], p[1], p[2]), Vec3::Zero());
      out.translation_mm = Vec3(p[3], p[4], p[5]) - out.rotation * centre_part_;
      return out;
    }
    case Acquisition::kTranslated: {
      Pose out = pose(theta, s.reference);
      out.translation_mm += s.distance_mm * axisFromAngles(p[0], p[1]);
      return out;
    }
    case Acquisition::kKnown:
      return s.known_pose;
  }
  return {};
}

Machine ForwardModel::machineAt(int level) const {
  Machine m = machine();
  const double s = static_cast<double>(1 << level);
  const Image& image = radiograph(0).levels[static_cast<size_t>(level)];
  m.columns = image.width();
  m.rows = image.height();
  m.pitch_u_mm *= s;
  m.pitch_v_mm *= s;
  m.cx_px /= s;
  m.cy_px /= s;
  return m;
}

std::optional<std::string> ForwardModel::tryPose(std::span<const double> theta, int radiograph) {
  if (auto why = part_.tryEvaluate(theta.first(part_.dimensions().size()), part_vertices_))
    return why;
  poseVertices(pose(theta, radiograph), part_vertices_, world_vertices_);
  if (auto why = outsideBeam(machine(), world_vertices_))
    return fmt::format("{} in radiograph {}", *why, spec(radiograph).name);
  return std::nullopt;
}

WorldMesh ForwardModel::worldMesh() const {
  return WorldMesh{world_vertices_, part_.triangles(), part_.csg().get()};
}

WorldMesh ForwardModel::posedMesh(std::span<const double> theta, int radiograph) {
  if (auto why = tryPose(theta, radiograph)) fail("cannot simulate these parameters: {}", *why);
  return worldMesh();
}

std::optional<std::string> ForwardModel::infeasibility(std::span<const double> theta) {
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (auto why = part_.invalidity(theta.first(part_.dimensions().size()))) return why;
  for (int r = 0; r < radiographCount(); ++r)
    if (auto why = tryPose(theta, r)) return why;
  return std::nullopt;
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

std::vector<Segment2> ForwardModel::outline(std::span<const double> theta, int radiograph) {
  return projectedContour(machine(), posedMesh(theta, radiograph));
}

ScatterEstimate ForwardModel::scatter(std::span<const double> theta, int radiograph, int level) {
  XG_CHECK(job().scatter.enabled(), "the job models no scatter");
  useMaterialOf(theta);
  return scatterOf(posedMesh(theta, radiograph), radiograph, level);
}

ScatterEstimate ForwardModel::scatterOf(const WorldMesh& mesh, int radiograph, int level) {
  // The kernel is hundreds of pixels wide: a coarse render of the whole
  // detector carries all of G(I).
  const int coarse_level = scatterLevel(level);
  renderIntensity(machineAt(coarse_level), mesh, transmission_, scatterRenderOptions(), coarse_);
  return spreadOf(coarse_, coarse_level, radiograph, level, false);
}

ScatterEstimate ForwardModel::spreadOf(const Image& coarse, int coarse_level, int radiograph,
                                       int level, bool derivative) const {
  ScatterEstimate out;
  // The coarse pixels' area (a box of 1/12 coarse pixel^2 of variance) and
  // the bilinear interpolation back (1/6) widen the kernel: taken off here,
  // as blur.cpp's reduced blur does.
  // Outside the part's shadow the render is the open beam (1) and a
  // derivative image 0: only the shadow's rows and columns are summed. With
  // an open border the world beyond the panel is that level too.
  out.blurred = job().scatter.spreadAround(coarse, machineAt(coarse_level).pitch_u_mm,
                                           derivative ? 0.0f : 1.0f, 0.25);
  // The model's open-beam level in the white region (full-size coordinates).
  const PixelRect white = spec(radiograph).white_region;
  const double full_to_coarse = 1.0 / static_cast<double>(1 << coarse_level);
  // at() maps pixels of a level to the coarse one: first full-size pixels,
  // for the white region, then the level asked for.
  out.ratio = full_to_coarse;
  double white_sum = 0.0;
  constexpr int kGrid = 8;
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i)
      white_sum += out.at(white.x + (i + 0.5) * white.width / kGrid,
                          white.y + (j + 0.5) * white.height / kGrid);
  const double w = job().scatter.weight;
  out.open = (derivative ? 0.0 : 1.0 - w) + w * white_sum / (kGrid * kGrid);
  out.ratio = static_cast<double>(1 << level) / static_cast<double>(1 << coarse_level);
  return out;
}

bool ForwardModel::poseVelocities(std::span<const double> theta, std::span<const int> indices,
                                  int radiograph, std::vector<int>& moving,
                                  std::vector<Vec3>& velocities) {
  std::vector<int> vertex_indices;
  std::vector<double> steps;
  std::vector<int> position;
  for (size_t k = 0; k < indices.size(); ++k) {
    if (kind(indices[k]) == ParameterKind::kMaterial) continue;
    vertex_indices.push_back(indices[k]);
    position.push_back(static_cast<int>(k));
    // Small against any feature, large against rounding; most vertex
    // expressions are linear in the dimensions, where any step is exact.
    steps.push_back(1e-4 * std::max(1.0, std::abs(theta[static_cast<size_t>(indices[k])])));
  }
  const size_t dims = part_.dimensions().size();
  const VertexMap map = [&](std::span<const double> t, std::vector<Vec3>& world) {
    if (part_.tryEvaluate(t.first(dims), part_vertices_)) return false;
    poseVertices(pose(t, radiograph), part_vertices_, world);
    return true;
  };
  std::vector<Vec3> all;
  if (!vertexVelocities(map, theta, vertex_indices, steps, all)) return false;
  // Keep the parameters that move this radiograph's part (another
  // radiograph's pose does not).
  const size_t vertices = part_.vertexCount();
  moving.clear();
  velocities.clear();
  for (size_t k = 0; k < vertex_indices.size(); ++k) {
    const auto first = all.begin() + static_cast<ptrdiff_t>(k * vertices);
    if (std::all_of(first, first + static_cast<ptrdiff_t>(vertices),
                    [](const Vec3& v) { return v.isZero(0.0); }))
      continue;
    moving.push_back(position[k]);
    velocities.insert(velocities.end(), first, first + static_cast<ptrdiff_t>(vertices));
  }
  return true;
}

bool ForwardModel::residualsAndJacobian(std::span<const double> theta, std::span<const int> indices,
                                        int level, int samples, std::span<const int> radiographs,
                                        std::vector<double>& out, std::vector<double>& jacobian) {
  out.clear();
  jacobian.clear();
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (part_.invalidity(theta.first(part_.dimensions().size()))) return false;
  useMaterialOf(theta);
  const size_t p = indices.size();
  const ScatterModel& scatter = job().scatter;
  std::vector<int> moving;
  std::vector<Vec3> velocities;
  for (int r : radiographs) {
    if (tryPose(theta, r)) {
      out.clear(), jacobian.clear();
      return false;
    }
    const WorldMesh mesh = worldMesh();
    const PreparedRadiograph& rad = radiograph(r);
    const PixelRect roi = rad.rois[static_cast<size_t>(level)];
    if (!poseVelocities(theta, indices, r, moving, velocities)) {
      out.clear(), jacobian.clear();
      return false;
    }
    const int count = static_cast<int>(moving.size());
    IntensityDerivatives d;
    renderIntensityDerivatives(machineAt(level), mesh, transmission_, renderOptions(samples, roi),
                               velocities, count,
                               d);
    // The scatter and its derivatives, from coarse renders of the whole detector.
    std::optional<ScatterEstimate> spread;
    std::vector<ScatterEstimate> spread_rates;
    if (scatter.enabled()) {
      const int coarse_level = scatterLevel(level);
      IntensityDerivatives coarse;
      // Point samples alone: refined, these rates made the 512 px joint stage
      // of a 4096^2 Prism A pair take 16 iterations instead of 5 for the same
      // loss, at a higher cost each.
      RenderOptions coarse_options = scatterRenderOptions();
      coarse_options.edge_samples_per_axis = 0;
      renderIntensityDerivatives(machineAt(coarse_level), mesh, transmission_, coarse_options,
                                 velocities, count, coarse);
      // The value from the render whose edges are refined (scatterOf), as
      // residuals() has it: the render with derivatives samples each pixel
      // once, which is the per-shot error scatterRenderOptions() removes.
      spread = scatterOf(mesh, r, level);
      for (const Image& rate : coarse.per_parameter) {
        spread_rates.push_back(spreadOf(rate, coarse_level, r, level, true));
        // The image's interpolation taps serve every rate's below.
        XG_CHECK(spread_rates.back().blurred.width() == spread->blurred.width() &&
                     spread_rates.back().blurred.height() == spread->blurred.height() &&
                     spread_rates.back().ratio == spread->ratio,
                 "a derivative's scatter estimate on another grid than the image's");
      }
    }
    const Image& measured = rad.levels[static_cast<size_t>(level)];
    const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
    const size_t first = out.size();
    out.resize(first + static_cast<size_t>(roi.area()));
    jacobian.resize(out.size() * p, 0.0);
    const double w = scatter.weight;
    // Rows in parallel: every pixel writes only its own residual and row.
    tbb::parallel_for(0, roi.height, [&](int y) {
      for (int x = 0; x < roi.width; ++x) {
        const size_t m = first + static_cast<size_t>(y) * static_cast<size_t>(roi.width) +
                         static_cast<size_t>(x);
        const auto intensity = static_cast<double>(d.intensity(x, y));
        double* row = jacobian.data() + m * p;
        double simulated = intensity;
        if (!spread) {
          for (int k = 0; k < count; ++k)
            row[moving[static_cast<size_t>(k)]] =
                scale * static_cast<double>(d.per_parameter[static_cast<size_t>(k)](x, y));
        } else {
          // out = mix(I, G) / open, as simulatePosed.
          const ScatterEstimate::Tap tap = spread->tap(roi.x + x + 0.5, roi.y + y + 0.5);
          simulated = static_cast<double>(spread->simulated(scatter, intensity, tap));
          for (int k = 0; k < count; ++k) {
            const ScatterEstimate& rate = spread_rates[static_cast<size_t>(k)];
            const double mixed =
                (1.0 - w) * static_cast<double>(d.per_parameter[static_cast<size_t>(k)](x, y)) +
                w * rate.at(tap);
            row[moving[static_cast<size_t>(k)]] =
                scale * (mixed - simulated * rate.open) / spread->open;
          }
        }
        out[m] = scale * (simulated - static_cast<double>(measured(roi.x + x, roi.y + y)));
      }
    });
  }
  // Material parameters: central differences of whole renders.
  std::vector<double> at(theta.begin(), theta.end()), plus, minus;
  for (size_t k = 0; k < p; ++k) {
    const auto i = static_cast<size_t>(indices[k]);
    if (kind(indices[k]) != ParameterKind::kMaterial) continue;
    const double h = 1e-4 * std::max(1.0, std::abs(theta[i]));
    at[i] = std::min(theta[i] + h, upper()[i]);
    const double hi = at[i];
    const bool ok_plus = residuals(at, level, samples, radiographs, plus);
    at[i] = std::max(theta[i] - h, lower()[i]);
    const double lo = at[i];
    const bool ok_minus = residuals(at, level, samples, radiographs, minus);
    at[i] = theta[i];
    if (!ok_plus || !ok_minus || plus.size() != out.size() || !(hi > lo)) {
      out.clear(), jacobian.clear();
      return false;
    }
    for (size_t m = 0; m < out.size(); ++m) jacobian[m * p + k] = (plus[m] - minus[m]) / (hi - lo);
  }
  useMaterialOf(theta);
  return true;
}

Image ForwardModel::simulate(std::span<const double> theta, int radiograph, int level, int samples,
                             const PixelRect& region) {
  useMaterialOf(theta);
  return simulatePosed(posedMesh(theta, radiograph), radiograph, level, samples, region);
}

RenderOptions ForwardModel::renderOptions(int samples, const PixelRect& region) const {
  RenderOptions options;
  options.samples_per_axis = samples;
  options.edge_samples_per_axis = edge_samples_ > samples ? std::min(edge_samples_, 32) : 0;
  options.region = region;
  return options;
}

Image ForwardModel::simulatePosed(const WorldMesh& mesh, int radiograph, int level, int samples,
                                  const PixelRect& region) {
  Image out;
  renderIntensity(machineAt(level), mesh, transmission_, renderOptions(samples, region), out);
  const ScatterModel& scatter = job().scatter;
  if (!scatter.enabled()) return out;

  // The scintillator scatter, with the same white-region normalization as the
  // measured image.
  const ScatterEstimate spread = scatterOf(mesh, radiograph, level);
  for (int y = 0; y < out.height(); ++y)
    for (int x = 0; x < out.width(); ++x)
      out(x, y) = spread.simulated(scatter, static_cast<double>(out(x, y)), region.x + x + 0.5,
                                   region.y + y + 0.5);
  return out;
}

bool ForwardModel::forEachSimulated(
    std::span<const double> theta, int level, int samples, std::span<const int> radiographs,
    const std::function<void(const PreparedRadiograph&, const PixelRect&, const Image&)>& use) {
  XG_CHECK(theta.size() == static_cast<size_t>(size()), "theta has the wrong size");
  if (part_.invalidity(theta.first(part_.dimensions().size()))) return false;
  useMaterialOf(theta);
  for (int r : radiographs) {
    if (tryPose(theta, r)) return false;
    const PreparedRadiograph& rad = radiograph(r);
    const PixelRect roi = rad.rois[static_cast<size_t>(level)];
    rendered_ = simulatePosed(worldMesh(), r, level, samples, roi);
    use(rad, roi, rendered_);
  }
  return true;
}

bool ForwardModel::residuals(std::span<const double> theta, int level, int samples,
                             std::span<const int> radiographs, std::vector<double>& out) {
  out.clear();
  const bool feasible = forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        const Image& measured = rad.levels[static_cast<size_t>(level)];
        const double scale = 1.0 / std::sqrt(static_cast<double>(roi.area()));
        for (int y = 0; y < roi.height; ++y)
          for (int x = 0; x < roi.width; ++x)
            out.push_back(scale * (static_cast<double>(simulated(x, y)) -
                                   static_cast<double>(measured(roi.x + x, roi.y + y))));
      });
  if (!feasible) out.clear();
  return feasible;
}

std::optional<double> ForwardModel::loss(std::span<const double> theta, int level, int samples,
                                         std::span<const int> radiographs) {
  double total = 0.0;
  const bool feasible = forEachSimulated(
      theta, level, samples, radiographs,
      [&](const PreparedRadiograph& rad, const PixelRect& roi, const Image& simulated) {
        total += imageLoss(simulated, rad.levels[static_cast<size_t>(level)], roi, job().loss);
      });
  if (!feasible) return std::nullopt;
  return total;
}

}  // namespace xgauge
