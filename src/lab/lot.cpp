#include "xgauge/lab/lot.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/core/manifest.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/random.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <ctime>
#include <random>

namespace xgauge {

namespace fs = std::filesystem;

namespace {

// Stream ids of the lot's random numbers (lab/random.h), apart from the
// per-part datasets' own, which are seeded by the part's seed.
constexpr uint64_t kDimensionStream = 0x107d1;
constexpr uint64_t kJitterStream = 0x107d2;
constexpr uint64_t kPartSeedStream = 0x107d3;

uint64_t nameHash(const std::string& name) {
  uint64_t h = 1469598103934665603ull;  // FNV-1a
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
  return h;
}

struct DimensionProcess {
  std::string name;
  double sigma = 0.0;
  int64_t drift_from = 0;  // 0: none
  double drift_per_part = 0.0;
  int64_t step_from = 0;  // 0: none
  double step_by = 0.0;
};

struct LotSpec {
  std::string name;
  int64_t parts = 0;
  int64_t start_unix = 0;
  double interval_s = 60.0;
  std::vector<DimensionProcess> process;
  double jitter_rotation_deg = 0.0, jitter_translation_mm = 0.0;
};

int64_t parseUtc(const ConfigNode& node) {
  std::tm tm{};
  const std::string text = node.string();
  if (!strptime(text.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm))
    node.fail("expected a UTC time as 2026-12-04T06:00:00Z");
  return static_cast<int64_t>(timegm(&tm));
}

std::string formatUtc(int64_t unix_seconds) {
  const std::time_t t = static_cast<std::time_t>(unix_seconds);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

LotSpec readLot(const ConfigNode& lot, const PartModel& model, const fs::path& folder) {
  LotSpec spec;
  lot.get<std::string>("description", "");  // free text
  spec.name =
      lot.get<std::string>("name", fs::absolute(folder).lexically_normal().filename().string());
  spec.parts = lot.at("parts").integer(1, 100000);
  spec.start_unix = 1767247200;  // 2026-01-01T06:00:00Z
  if (auto start = lot.find("start_time")) spec.start_unix = parseUtc(*start);
  if (auto interval = lot.find("interval_s")) spec.interval_s = interval->number(0.0, 1e7);
  if (auto process = lot.find("process")) {
    for (const auto& name : process->keys()) {
      const ConfigNode d = process->at(name);
      try {
        model.dimensionIndex(name);
      } catch (const Error& e) {
        d.fail(e.message());
      }
      DimensionProcess p;
      p.name = name;
      p.sigma = d.get<double>("sigma", 0.0);
      if (p.sigma < 0 || p.sigma > 100) d.at("sigma").fail("expected 0 .. 100");
      if (auto drift = d.find("drift")) {
        p.drift_from = drift->at("from_part").integer(1, spec.parts + 1);
        p.drift_per_part = drift->at("per_part").number(-100.0, 100.0);
      }
      if (auto step = d.find("step")) {
        p.step_from = step->at("from_part").integer(1, spec.parts + 1);
        p.step_by = step->at("by").number(-1000.0, 1000.0);
      }
      spec.process.push_back(p);
    }
  }
  if (auto jitter = lot.find("pose_jitter")) {
    spec.jitter_rotation_deg = jitter->get<double>("rotation_deg", 0.0);
    spec.jitter_translation_mm = jitter->get<double>("translation_mm", 0.0);
    if (spec.jitter_rotation_deg < 0 || spec.jitter_rotation_deg > 45)
      jitter->at("rotation_deg").fail("expected 0 .. 45");
    if (spec.jitter_translation_mm < 0 || spec.jitter_translation_mm > 1000)
      jitter->at("translation_mm").fail("expected 0 .. 1000");
  }
  return spec;
}

// Part k's placement on the stage: a turn about its bounding-box centre and
// a shift, in the part's frame, applied before every shot's pose.
Pose jitterFor(const LotSpec& spec, uint64_t seed, int64_t k, const Vec3& centre_part) {
  SplitMix64 rng = SplitMix64::stream(seed, kJitterStream, static_cast<uint64_t>(k));
  std::normal_distribution<double> gauss(0.0, 1.0);
  Vec3 axis(gauss(rng), gauss(rng), gauss(rng));
  if (axis.norm() < 1e-12) axis = Vec3::UnitZ();
  const double angle = spec.jitter_rotation_deg * gauss(rng) * kDegToRad;
  const Vec3 shift(spec.jitter_translation_mm * gauss(rng), spec.jitter_translation_mm * gauss(rng),
                   spec.jitter_translation_mm * gauss(rng));
  Pose j;
  j.rotation = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  j.translation_mm = centre_part - j.rotation * centre_part + shift;
  return j;
}

Pose compose(const Pose& outer, const Pose& inner) {
  Pose p;
  p.rotation = outer.rotation * inner.rotation;
  p.translation_mm = outer.rotation * inner.translation_mm + outer.translation_mm;
  return p;
}

std::map<std::string, double> partDimensions(const LotSpec& spec, const Recipe& recipe, int64_t k) {
  std::map<std::string, double> dims = recipe.true_dimensions;
  for (const auto& p : spec.process) {
    // One stream per part and dimension: part k's values do not depend on
    // how many parts the lot has or which other dimensions vary.
    SplitMix64 rng = SplitMix64::stream(recipe.seed, kDimensionStream, static_cast<uint64_t>(k),
                                        nameHash(p.name));
    std::normal_distribution<double> gauss(0.0, 1.0);
    double value = dims.at(p.name) + p.sigma * gauss(rng);
    if (p.drift_from > 0 && k >= p.drift_from)
      value += p.drift_per_part * static_cast<double>(k - p.drift_from + 1);
    if (p.step_from > 0 && k >= p.step_from) value += p.step_by;
    dims[p.name] = value;
  }
  return dims;
}

}  // namespace

bool isLotRecipe(const Recipe& recipe) { return recipe.root && recipe.root->has("lot"); }

LotReport simulateLot(const Recipe& recipe, const fs::path& folder) {
  const auto t0 = std::chrono::steady_clock::now();
  const PartModel model = PartModel::load(recipe.part_file);
  const LotSpec spec = readLot(recipe.root->at("lot"), model, folder);
  // The recipe's unnamed dimensions take their nominal values.
  Recipe base = recipe;
  for (const auto& d : model.dimensions())
    if (!base.true_dimensions.count(d.name)) base.true_dimensions[d.name] = d.nominal;
  const BoundingBox box = boundingBox(model.mesh(model.values(base.true_dimensions)));
  const Vec3 centre = 0.5 * (box.min_mm + box.max_mm);

  createOutputFolder(folder);
  createOutputFolder(folder / "parts");
  createOutputFolder(folder / "truth");
  LotReport report;
  report.parts = static_cast<int>(spec.parts);
  nlohmann::json parts = nlohmann::json::array();
  ProgressBar bar("lot", spec.parts);
  for (int64_t k = 1; k <= spec.parts; ++k) {
    const std::string id = fmt::format("p{:04d}", k);
    Recipe part = base;
    part.true_dimensions = partDimensions(spec, base, k);
    part.seed = SplitMix64::stream(recipe.seed, kPartSeedStream, static_cast<uint64_t>(k))() >> 11;
    const Pose jitter = jitterFor(spec, recipe.seed, k, centre);
    for (auto& shot : part.shots) shot.pose = compose(shot.pose, jitter);
    const std::string time =
        formatUtc(spec.start_unix +
                  static_cast<int64_t>(std::llround(spec.interval_s * static_cast<double>(k - 1))));
    parts.push_back(
        {{"part", id},
         {"index", k},
         {"time", time},
         {"seed", part.seed},
         {"dimensions", part.true_dimensions},
         {"pose_jitter",
          {{"rotation_deg", jitter.eulerDeg()}, {"translation_mm", jitter.translation_mm}}}});
    const fs::path part_folder = folder / "parts" / id;
    if (checkPartFolder(part_folder).state == PartFolderState::kReady &&
        fs::exists(folder / "truth" / (id + ".json"))) {
      bar.advance();
      continue;  // made by an earlier, interrupted run: the same bytes
    }
    // Made aside, then moved in: the part folder only ever holds whole
    // files, and its manifest comes last.
    const fs::path staging = folder / ".staging" / id;
    fs::remove_all(staging);
    const bool progress = progressEnabled();
    setProgressEnabled(false);
    try {
      simulateDataset(part, staging);
    } catch (...) {
      setProgressEnabled(progress);
      throw;
    }
    setProgressEnabled(progress);
    createOutputFolder(part_folder);
    std::vector<std::string> files = {"dark.tif", "flat.tif"};
    for (const auto& shot : part.shots) files.push_back(shot.name + ".tif");
    for (const auto& f : files) fs::rename(staging / f, part_folder / f);
    fs::rename(staging / "truth.json", folder / "truth" / (id + ".json"));
    fs::remove_all(staging);
    Manifest manifest;
    manifest.part = id;
    manifest.lot = spec.name;
    manifest.time = time;
    manifest.index = k;
    writeManifest(part_folder, manifest, files);
    ++report.simulated;
    bar.advance();
  }
  bar.finish();
  fs::remove_all(folder / ".staging");
  nlohmann::json process = nlohmann::json::object();
  for (const auto& p : spec.process) {
    nlohmann::json d = {{"nominal", base.true_dimensions.at(p.name)}, {"sigma", p.sigma}};
    if (p.drift_from > 0)
      d["drift"] = {{"from_part", p.drift_from}, {"per_part", p.drift_per_part}};
    if (p.step_from > 0) d["step"] = {{"from_part", p.step_from}, {"by", p.step_by}};
    process[p.name] = d;
  }
  const nlohmann::json truth = {{"recipe", recipe.file.string()},
                                {"description", recipe.description},
                                {"lot", spec.name},
                                {"seed", recipe.seed},
                                {"part_model", fs::weakly_canonical(recipe.part_file).string()},
                                {"process", process},
                                {"parts", parts}};
  writeFileAtomically(folder / "truth.json", truth.dump(2) + "\n");
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace xgauge
