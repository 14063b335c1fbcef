#include "xgauge/study/study.h"

#include "xgauge/report/html.h"
#include "xgauge/report/measurement.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/file.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"
#include "xgauge/version.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <fstream>
#include <map>
#include <mutex>
#include <optional>

namespace xgauge {

namespace {

namespace fs = std::filesystem;

// SHA-256 of whole files, each computed once (the part and the radiographs
// every run names).
class FileDigests {
 public:
  std::string of(const fs::path& path) {
    {
      const std::lock_guard lock(mutex_);
      const auto it = known_.find(path.string());
      if (it != known_.end()) return it->second;
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot open file", SourceLocation::inFile(path.string()));
    Sha256 hash;
    std::vector<char> buffer(size_t{1} << 20);
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      hash.update(buffer.data(), static_cast<size_t>(in.gcount()));
    }
    if (in.bad()) throw Error("cannot read file", SourceLocation::inFile(path.string()));
    std::string digest = hash.hex();
    const std::lock_guard lock(mutex_);
    known_.emplace(path.string(), digest);
    return digest;
  }

 private:
  std::mutex mutex_;
  std::map<std::string, std::string> known_;
};

// What a run's result depends on: the software, its job (settings, start
// values, bounds, seed, shots), the machine, the material, whether images
// were asked for, and the bytes of the part model and of every radiograph
// and frame the job names. A run whose fingerprint differs is measured again.
std::string runFingerprint(const nlohmann::json& job, const DatasetTruth& truth,
                           const StudyInputs& inputs, bool images, FileDigests& digests) {
  std::string text = "xgauge " XGAUGE_VERSION_STRING "\n";
  text += "job " + job.dump() + "\n";
  text += "machine " + truth.machine.dump() + "\n";
  text += "material " + materialRecord(inputs).dump() + "\n";
  text += fmt::format("images {}\n", images);
  text += "part " + digests.of(inputs.part_file) + "\n";
  for (const auto& [file, digest] : inputs.part->shapeFileDigests()) text += "shape " + digest + "\n";
  for (const auto& radiograph : job.at("radiographs"))
    for (const char* key : {"image", "dark", "flat", "previous"})
      if (radiograph.contains(key))
        text += fmt::format("{} {}\n", key, digests.of(radiograph.at(key).get<std::string>()));
  return sha256Hex(text);
}

// The first line of a small text file; empty when it is missing.
std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

// A run's result.json (written by this study, with or without --images),
// read through ConfigNode so that a damaged file is named.
StudyRun readRunResult(const fs::path& file, const std::string& id, const DatasetTruth& truth,
                       const std::vector<std::string>& free_dimensions) {
  const ConfigNode root = ConfigNode::loadFile(file);
  StudyRun run;
  run.id = id;
  run.seconds = root.at("seconds").number();
  if (const auto status = root.find("status"); status && status->string() == "not measured") {
    const ConfigNode failures = root.at("failures");
    for (size_t k = 0; k < failures.size(); ++k) run.failures.push_back(failures[k].string());
    if (run.failures.empty()) failures.fail("a run not measured names no failure");
    return run;
  }
  const ConfigNode dims = root.at("dimensions");
  for (size_t k = 0; k < dims.size(); ++k) {
    const ConfigNode d = dims[k];
    if (!d.at("free").as<bool>()) continue;
    const std::string name = d.get<std::string>("name");
    const auto true_value = truth.dimensions.find(name);
    if (true_value == truth.dimensions.end()) d.at("name").fail("not a dimension of the dataset");
    run.error_mm[name] = d.at("value_mm").number() - true_value->second;
    if (const auto u = d.find("expanded_uncertainty"); u && u->isNumber())
      run.expanded_mm[name] = u->number();
  }
  if (const auto budget = root.find("uncertainty"))
    if (const auto combos = budget->find("combinations"))
      for (size_t k = 0; k < combos->size(); ++k) {
        const ConfigNode c = (*combos)[k];
        const ConfigNode terms = c.at("terms");
        double truth_value = 0.0;
        for (size_t t = 0; t < terms.size(); ++t) {
          const std::string name = terms[t].get<std::string>("dimension");
          const auto true_value = truth.dimensions.find(name);
          if (true_value == truth.dimensions.end()) terms[t].fail("not a dimension of the dataset");
          truth_value += terms[t].at("coefficient").number() * true_value->second;
        }
        run.combinations[c.get<std::string>("expression")] = {
            c.at("value").number() - truth_value, c.at("expanded_uncertainty").number()};
      }
  if (const auto refined = root.find("material_refinement"); refined && refined->isObject())
    run.rate_scale = {refined->at("rate_scale").number(),
                      refined->at("standard_uncertainty").number(0.0, 1e6)};
  for (const auto& name : free_dimensions)
    if (!run.error_mm.count(name)) dims.fail(fmt::format("no free dimension '{}'", name));
  return run;
}

struct Combination {
  std::string id;
  std::vector<std::string> shots;  // first is the free one
  bool turned = false;             // the others turned on the turntable
};

// The translated series of the dataset's own description: a shot that
// translated shots refer to, then those shots, in file order.
std::vector<const TruthShot*> translatedSeries(const DatasetTruth& truth) {
  std::vector<const TruthShot*> series;
  for (const auto& s : truth.shots) {
    if (s.pattern != "translated") continue;
    if (series.empty()) series.push_back(&truth.shot(s.reference));
    if (s.reference != series.front()->name)
      fail(
          "{}: shot {} is translated from {}, but the study's series starts at {}; a study takes "
          "one translated series",
          (truth.folder / "truth.json").string(), s.name, s.reference, series.front()->name);
    series.push_back(&s);
  }
  return series;
}

// Every pair of the dataset's rotations on its calibrated turntable, the
// first free and the second turned.
std::vector<Combination> turnedPairs(const DatasetTruth& truth,
                                     const std::vector<const TruthShot*>& rotated) {
  if (!truth.machine.contains("turntable"))
    fail(
        "{}: turned pairs need the dataset's rotations on a calibrated turntable (the recipe's "
        "shots.rotations.turntable), whose axis its machine states",
        (truth.folder / "truth.json").string());
  std::vector<Combination> out;
  for (size_t a = 0; a < rotated.size(); ++a)
    for (size_t b = a + 1; b < rotated.size(); ++b)
      out.push_back(
          {rotated[a]->name + "-" + rotated[b]->name, {rotated[a]->name, rotated[b]->name}, true});
  return out;
}

std::vector<Combination> combinations(const DatasetTruth& truth, const std::string& kind) {
  std::vector<const TruthShot*> rotated;
  for (const auto& s : truth.shots)
    if (s.pattern == "rotated") rotated.push_back(&s);
  if (kind != "pairs" && kind != "pairs+rotated" && kind != "turned-pairs")
    fail("unknown combinations '{}' (known: pairs, pairs+rotated, turned-pairs)", kind);
  if (kind == "turned-pairs") {
    std::vector<Combination> out = turnedPairs(truth, rotated);
    if (out.empty()) fail("the dataset has no two rotations to make turned pairs of");
    return out;
  }
  const std::vector<const TruthShot*> translated = translatedSeries(truth);
  std::vector<Combination> out;
  for (size_t a = 0; a < translated.size(); ++a)
    for (size_t b = a + 1; b < translated.size(); ++b) {
      const std::string pair = translated[a]->name + "-" + translated[b]->name;
      if (kind == "pairs") {
        out.push_back({pair, {translated[a]->name, translated[b]->name}});
      } else {
        for (size_t r = 1; r < rotated.size(); ++r)
          out.push_back({pair + "+" + rotated[r]->name,
                         {translated[a]->name, translated[b]->name, rotated[r]->name}});
      }
    }
  if (out.empty()) fail("the dataset has no {} of shots", kind);
  return out;
}

}  // namespace

nlohmann::json studyJob(const nlohmann::json& settings, const DatasetTruth& truth,
                        const fs::path& part_file, const std::vector<std::string>& shots,
                        const std::string& id,
                        const fs::path& machine_file, const fs::path& material_file, bool turned) {
  nlohmann::json job = settings;
  job.erase("material");
  // With "previous_frames", each shot's lag is subtracted with the shot the
  // dataset lists before it as its previous frame (the dataset lists its
  // shots in the order they were exposed; the first has none).
  bool previous_frames = false;
  if (const auto it = settings.find("previous_frames"); it != settings.end()) {
    if (!it->is_boolean()) fail("study settings: /previous_frames: expected true or false");
    previous_frames = it->get<bool>();
    job.erase("previous_frames");
  }
  auto previousOf = [&](const std::string& name) -> const TruthShot* {
    for (size_t k = 1; k < truth.shots.size(); ++k)
      if (truth.shots[k].name == name) return &truth.shots[k - 1];
    return nullptr;
  };
  job["description"] = "study run " + id;
  job["part"] = fs::absolute(part_file).string();
  job["machine"] = fs::absolute(machine_file).string();
  job["material"] = fs::absolute(material_file).string();
  const auto& w = truth.white_region;
  nlohmann::json radiographs = nlohmann::json::array();
  const TruthShot& first = truth.shot(shots[0]);
  for (size_t i = 0; i < shots.size(); ++i) {
    const TruthShot& s = truth.shot(shots[i]);
    nlohmann::json r = {{"name", s.name},
                        {"image", fs::absolute(s.file).string()},
                        {"dark", fs::absolute(truth.dark).string()},
                        {"flat", fs::absolute(truth.flat).string()},
                        {"white_region", {w.x, w.y, w.width, w.height}}};
    if (const TruthShot* previous = previous_frames ? previousOf(s.name) : nullptr)
      r["previous"] = fs::absolute(previous->file).string();
    if (i == 0) {
      r["pattern"] = "free";
    } else if (turned) {
      r["pattern"] = "turned";
      r["reference"] = first.name;
      r["angle_deg"] = s.nominal_angle_deg - first.nominal_angle_deg;
    } else if (s.pattern == "rotated") {
      r["pattern"] = "rotated";
      r["reference"] = first.name;
    } else {
      r["pattern"] = "translated";
      r["reference"] = first.name;
      r["distance_mm"] = std::abs(s.distance_mm - first.distance_mm);
    }
    radiographs.push_back(r);
  }
  job["radiographs"] = radiographs;
  return job;
}

nlohmann::json materialRecord(const StudyInputs& inputs) {
  nlohmann::json record = inputs.material.toJson();
  if (inputs.material_scatter) {
    record["scatter"] = inputs.material_scatter->model.toJson();
    if (inputs.material_scatter->curves)
      record["scatter"]["curve_moves"] = inputs.material_scatter->curves->toJson();
  }
  return record;
}

StudyInputs prepareStudyInputs(const DatasetTruth& truth, const nlohmann::json& settings,
                               const fs::path& settings_file) {
  StudyInputs inputs;
  inputs.part_file = truth.part_file;
  if (const auto it = settings.find("part"); it != settings.end()) {
    if (!it->is_string()) fail("{}: /part: expected a file name", settings_file.string());
    inputs.part_file = settings_file.parent_path() / it->get<std::string>();
  }
  inputs.part = std::make_shared<const PartModel>(PartModel::load(inputs.part_file));
  // The truth is compared by name: every dimension of the model must be one
  // of the dataset's.
  for (const Dimension& d : inputs.part->dimensions())
    if (!truth.dimensions.count(d.name))
      fail("{}: the part model {} has a dimension '{}' that the dataset's truth does not give",
           settings_file.string(), inputs.part_file.string(), d.name);
  const ConfigNode machine =
      ConfigNode::fromJson(truth.machine, (truth.folder / "truth.json").string() + " (machine)");
  inputs.machine = Machine::fromConfig(machine);
  machine.finish();
  std::string material = "fit";
  if (const auto it = settings.find("material"); it != settings.end()) {
    if (!it->is_string())
      fail("{}: /material: expected \"fit\" or a file name", settings_file.string());
    material = it->get<std::string>();
  }
  if (material == "fit") {
    // Over the paths the shots show, with a margin for the binned render.
    const double longest = longestTruePathMm(truth, *inputs.part, inputs.machine);
    inputs.material = fitTrueCurve(truth, 1.05 * longest + 0.5);
    spdlog::info("material: {}", inputs.material.description());
  } else {
    const ConfigNode node = ConfigNode::loadFile(settings_file.parent_path() / material);
    inputs.material = ExponentialSum::fromConfig(node);
    if (auto scatter = node.find("scatter"))
      inputs.material_scatter = materialScatterFromConfig(*scatter);
    node.finish();
  }
  return inputs;
}

MeasurementInputs studyRunInputs(const nlohmann::json& job, const StudyInputs& inputs,
                                 const fs::path& settings_file, PreparedShots& shots) {
  MeasurementInputs in;
  const ConfigNode root = ConfigNode::fromJson(job, settings_file.string());
  // Each run evaluates a part model of its own: evaluating one (muparser's
  // variables and stack) is not thread-safe, and the runs go in parallel.
  // Sharing one made runs fail at random ("the start values do not make a
  // valid part") or fit a garbled part.
  auto part = std::make_shared<const PartModel>(*inputs.part);
  in.job = MeasurementJob::fromConfig(root, settings_file, *part, true);
  root.finish();
  if (!job.contains("scatter") && inputs.material_scatter) {
    in.job.scatter = inputs.material_scatter->model;
    in.scatter_curves = inputs.material_scatter->curves;
  }
  in.part = std::move(part);
  in.machine = inputs.machine;
  in.material = inputs.material;
  for (const RadiographSpec& spec : in.job.radiographs) in.radiographs.push_back(shots.get(spec));
  in.sha256 = shots.sha256();
  for (const auto& [file, digest] : inputs.file_sha256) in.sha256[file] = digest;
  if (!in.job.verification_file.empty()) {
    const ConfigNode verification = ConfigNode::loadFile(in.job.verification_file);
    in.sha256[in.job.verification_file.string()] = verification.sha256();
    in.verification = Verification::fromConfig(verification, in.job.verification_file);
    verification.finish();
  }
  return in;
}

std::shared_ptr<const PreparedRadiograph> PreparedShots::get(const RadiographSpec& spec) {
  const std::lock_guard lock(mutex_);
  auto it = prepared_.find(spec.image.string());
  if (it == prepared_.end()) {
    RadiographFrames frames;
    if (!spec.dark.empty()) {
      if (!dark_)
        dark_ = readInputRadiograph(spec.dark, machine_, sha256_),
        flat_ = readInputRadiograph(spec.flat, machine_, sha256_);
      frames.dark = &*dark_;
      frames.flat = &*flat_;
      frames.column_crosstalk = machine_.column_crosstalk;
      frames.bad_pixels = machine_.bad_pixels.get();
      if (!open_beam_) open_beam_ = openBeamOf(frames, machine_);
    }
    // A shot's previous frame (the one before it in the dataset's listing),
    // read raw for its lag.
    std::optional<Image> previous;
    if (!spec.previous.empty()) {
      previous = readInputRadiograph(spec.previous, machine_, sha256_);
      frames.previous = &*previous;
      frames.previous_name = spec.previous.string();
      frames.lag_fraction = machine_.lag_fraction;
      frames.lag_fraction_uncertainty = machine_.lagFractionUncertainty();
    }
    it = prepared_
             .emplace(spec.image.string(),
                      std::make_shared<const PreparedRadiograph>(prepareRadiograph(
                          readInputRadiograph(spec.image, machine_, sha256_), frames, spec,
                          machine_, open_beam_ ? &*open_beam_ : nullptr)))
             .first;
    logPrepared(spec, *it->second);
  }
  return it->second;
}

std::map<std::string, std::string> PreparedShots::sha256() const {
  const std::lock_guard lock(mutex_);
  return sha256_;
}

std::string StudySummary::table() const {
  auto figures = [](const CoverageFigures& c) {
    return c.runs == 0 ? fmt::format(" {:>9} {:>9} {:>7}", "n/a", "n/a", "n/a")
                       : fmt::format(" {:>9.4f} {:>8.1f}% {:>7.2f}", c.mean_u, 100.0 * c.coverage,
                                     c.mean_normalised);
  };
  std::string out = fmt::format("{:<18} {:>14} {:>14} {:>9} {:>9} {:>7}\n", "dimension",
                                "mean |err| mm", "max |err| mm", "mean U", "coverage", "|e|/U");
  for (const auto& d : dimensions)
    out += fmt::format("{:<18} {:>14.4f} {:>14.4f}", d, mean_abs_mm.at(d), max_abs_mm.at(d)) +
           figures(coverage.at(d)) + "\n";
  out += fmt::format("{:<18} {:>14.4f} {:>14.4f}", "all", mean_abs_mm_all, max_abs_mm_all) +
         figures(pooled) + "\n";
  for (const auto& [expression, c] : combination_coverage)
    out += fmt::format("{:<18} {:>14.4f} {:>14}", expression, c.mean_abs, "") + figures(c) +
           fmt::format("  (measurable combination, {} runs)\n", c.runs);
  out += fmt::format("{} runs, median {:.1f} s per run", runs.size(), median_seconds);
  if (measured_runs < static_cast<int>(runs.size()))
    out += fmt::format("; {} measured, {} not (the figures above are the measured runs'):",
                       measured_runs, runs.size() - static_cast<size_t>(measured_runs));
  out += "\n";
  for (const StudyRun& run : runs)
    if (!run.measured())
      out += fmt::format("  {} not measured: {}\n", run.id, run.failures.front());
  return out;
}

namespace {

// A study's "lag_fraction": the detector's lag as the lab knows it (from
// earlier pairs, or its panel's data sheet), written into the study's
// machine so that every run subtracts it instead of estimating it from each
// shot and its previous frame (which cannot be told where the previous
// frame's edges all fall in this shot's shadow, as with small rotations).
// The settings' "machine", when they name one, in place of the dataset's:
// a lab that measures with what it believes its machine to be (an ideal
// panel where the dataset's is tilted, say). Its detector file, named
// relative to it, is named absolutely, as the study's record sits elsewhere.
void useSettingsMachine(nlohmann::json& settings, nlohmann::json& machine,
                        const fs::path& settings_file) {
  const auto it = settings.find("machine");
  if (it == settings.end()) return;
  if (!it->is_string()) fail("{}: /machine: expected a file name", settings_file.string());
  const fs::path file = settings_file.parent_path() / it->get<std::string>();
  const ConfigNode node = ConfigNode::loadFile(file);
  Machine::fromConfig(node);  // checked as any machine file
  node.finish();
  machine = node.json();
  if (auto c = machine["detector"].find("characterization");
      c != machine["detector"].end() && c->is_string())
    *c = fs::absolute(file.parent_path() / c->get<std::string>()).string();
  settings.erase("machine");
}

void applyStudyLag(nlohmann::json& settings, nlohmann::json& machine,
                   const fs::path& settings_file) {
  const auto it = settings.find("lag_fraction");
  if (it == settings.end()) {
    if (settings.contains("lag_fraction_uncertainty"))
      fail("{}: /lag_fraction_uncertainty: needs a \"lag_fraction\"", settings_file.string());
    return;
  }
  const std::string where = settings_file.string() + ": /lag_fraction";
  if (!it->is_number()) fail("{}: expected a number from 0 to 0.5", where);
  const double lag = it->get<double>();
  if (!(lag >= 0.0 && lag <= 0.5)) fail("{}: expected a number from 0 to 0.5, got {}", where, lag);
  if (!settings.value("previous_frames", false))
    fail("{}: a lag is only subtracted with \"previous_frames\": true", where);
  machine["detector"]["lag_fraction"] = lag;
  settings.erase("lag_fraction");
  // Its standard uncertainty, when the lab knows it (else the machine's
  // default, a tenth of the fraction).
  if (const auto u = settings.find("lag_fraction_uncertainty"); u != settings.end()) {
    const std::string at = settings_file.string() + ": /lag_fraction_uncertainty";
    if (!u->is_number() || !(u->get<double>() >= 0.0 && u->get<double>() <= 0.5))
      fail("{}: expected a number from 0 to 0.5", at);
    machine["uncertainty"]["lag_fraction"] = u->get<double>();
    settings.erase("lag_fraction_uncertainty");
  }
}

// Records, so that every run's job.json can be measured again by hand: the
// study's machine and material, beside the runs, with their digests (and
// the part's) among the inputs'.
struct StudyRecords {
  fs::path machine_file, material_file;
};

StudyRecords writeStudyRecords(const StudyOptions& options, const DatasetTruth& truth,
                               StudyInputs& inputs) {
  const StudyRecords records{options.output / "machine.json", options.output / "material.json"};
  const std::string machine_text = truth.machine.dump(2) + "\n";
  const std::string material_text = materialRecord(inputs).dump(2) + "\n";
  writeFileAtomically(records.machine_file, machine_text);
  writeFileAtomically(records.material_file, material_text);
  inputs.file_sha256[fs::absolute(inputs.part_file).string()] =
      sha256Hex(readFileContents(inputs.part_file, uint64_t{64} << 20, "a part model"));
  for (const auto& [file, digest] : inputs.part->shapeFileDigests())
    inputs.file_sha256[fs::absolute(file).string()] = digest;
  inputs.file_sha256[fs::absolute(records.machine_file).string()] = sha256Hex(machine_text);
  inputs.file_sha256[fs::absolute(records.material_file).string()] = sha256Hex(material_text);
  return records;
}

// The study's runs, the first `limit` of them; of a shard, every N-th.
std::vector<Combination> selectRuns(const DatasetTruth& truth, const StudyOptions& options) {
  std::vector<Combination> runs = combinations(truth, options.combinations);
  if (options.limit > 0 && static_cast<size_t>(options.limit) < runs.size())
    runs.resize(static_cast<size_t>(options.limit));
  // A shard takes every N-th run; each run's folder is its own, so shards
  // share one output folder, and a run without --shard gathers them all.
  if (options.shard_count > 1) {
    std::vector<Combination> mine;
    for (size_t i = 0; i < runs.size(); ++i)
      if (static_cast<int>(i % static_cast<size_t>(options.shard_count)) == options.shard_index - 1)
        mine.push_back(runs[i]);
    runs = std::move(mine);
  }
  return runs;
}

// Every job first, checked against the part model (so a bad setting fails
// before any work); each is also written as a record of the run. Sets
// `free_dimensions` to the jobs' free dimensions.
std::vector<nlohmann::json> studyJobs(const StudyOptions& options, const nlohmann::json& settings,
                                      const DatasetTruth& truth, const StudyInputs& inputs,
                                      const StudyRecords& records,
                                      const std::vector<Combination>& runs,
                                      std::vector<std::string>& free_dimensions) {
  std::vector<nlohmann::json> jobs;
  for (const auto& c : runs) {
    jobs.push_back(studyJob(settings, truth, inputs.part_file, c.shots, c.id, records.machine_file,
                            records.material_file, c.turned));
    // A verification named relative to the settings file, as every run's
    // job.json records it: absolutely.
    if (const auto v = settings.find("verification"); v != settings.end() && v->is_string())
      jobs.back()["verification"] =
          fs::absolute(options.settings.parent_path() / v->get<std::string>()).string();
    const ConfigNode root = ConfigNode::fromJson(jobs.back(), options.settings.string());
    const MeasurementJob job =
        MeasurementJob::fromConfig(root, options.settings, *inputs.part, true);
    root.finish();
    free_dimensions = job.free_dimensions;
  }
  return jobs;
}

// Everything one run needs but its own combination and job.
struct RunContext {
  const StudyOptions& options;
  const DatasetTruth& truth;
  const StudyInputs& inputs;
  const std::vector<std::string>& free_dimensions;
  PreparedShots& shots;
  FileDigests& digests;
};

// One run: its earlier result where its fingerprint says that is still
// what it would measure, else measured (again) into its folder.
StudyRun studyRun(const RunContext& context, const Combination& combination,
                  const nlohmann::json& job) {
  const StudyOptions& options = context.options;
  const fs::path folder = options.output / "runs" / combination.id;
  const fs::path result_file = folder / "result.json";
  const fs::path fingerprint_file = folder / "fingerprint.sha256";
  const std::string fingerprint =
      runFingerprint(job, context.truth, context.inputs, options.images, context.digests);
  if (fs::exists(result_file)) {
    if (readText(fingerprint_file) != fingerprint) {
      spdlog::warn("run {}: measured with other settings or inputs; measuring again",
                   combination.id);
    } else {
      try {
        return readRunResult(result_file, combination.id, context.truth, context.free_dimensions);
      } catch (const Error& e) {
        spdlog::warn("run {}: cannot use the earlier result ({}); measuring again", combination.id,
                     e.what());
      }
    }
  }
  createOutputFolder(folder);
  // The fingerprint goes last: a run cut short is never taken as done.
  std::error_code ignored;
  fs::remove(fingerprint_file, ignored);
  writeFileAtomically(folder / "job.json", job.dump(2) + "\n");
  const MeasurementInputs run_inputs =
      studyRunInputs(job, context.inputs, options.settings, context.shots);
  ForwardModel model(run_inputs);
  const MeasurementResult result = measure(model, model.start());
  if (options.images) {
    writeMeasurementOutputs(model, result, folder, true, nlohmann::json(context.truth.dimensions));
  } else {
    writeFileAtomically(result_file, measurementJson(model, result).dump(2) + "\n");
  }
  writeFileAtomically(fingerprint_file, fingerprint + "\n");
  return readRunResult(result_file, combination.id, context.truth, context.free_dimensions);
}

// Every run, in parallel, with one progress bar for them all.
void studyRuns(const RunContext& context, const std::vector<Combination>& runs,
               const std::vector<nlohmann::json>& jobs, StudySummary& summary) {
  summary.runs.resize(runs.size());
  ProgressBar progress("study", static_cast<int64_t>(runs.size()));
  const bool progress_was = progressEnabled();
  setProgressEnabled(false);  // no bars from the runs themselves
  const auto level = spdlog::get_level();
  spdlog::set_level(spdlog::level::warn);
  tbb::parallel_for(size_t{0}, runs.size(), [&](size_t i) {
    summary.runs[i] = studyRun(context, runs[i], jobs[i]);
    progress.advance();
  });
  spdlog::set_level(level);
  setProgressEnabled(progress_was);
  progress.finish();
}

// The errors' statistics per dimension and overall; returns them per run
// as CSV.
std::string tabulateErrors(StudySummary& summary) {
  double sum_all = 0.0;
  size_t count_all = 0;
  std::string csv = "run,seconds";
  for (const auto& d : summary.dimensions) csv += "," + d + "_error_mm";
  csv += "\n";
  for (const auto& d : summary.dimensions)
    summary.mean_abs_mm[d] = 0.0, summary.max_abs_mm[d] = 0.0;
  std::vector<double> seconds;
  for (const auto& run : summary.runs) summary.measured_runs += run.measured();
  for (const auto& run : summary.runs) {
    csv += fmt::format("{},{:.3f}", run.id, run.seconds);
    seconds.push_back(run.seconds);
    if (!run.measured()) {
      for (size_t d = 0; d < summary.dimensions.size(); ++d) csv += ",not measured";
      csv += "\n";
      continue;
    }
    for (const auto& d : summary.dimensions) {
      const double e = std::abs(run.error_mm.at(d));
      summary.mean_abs_mm[d] += e / static_cast<double>(summary.measured_runs);
      summary.max_abs_mm[d] = std::max(summary.max_abs_mm[d], e);
      summary.max_abs_mm_all = std::max(summary.max_abs_mm_all, e);
      sum_all += e, ++count_all;
      csv += fmt::format(",{:.6f}", run.error_mm.at(d));
    }
    csv += "\n";
  }
  summary.mean_abs_mm_all = sum_all / static_cast<double>(std::max<size_t>(1, count_all));
  std::sort(seconds.begin(), seconds.end());
  summary.median_seconds = seconds[seconds.size() / 2];
  return csv;
}

// Coverage of the reported uncertainties: per dimension, pooled, and per
// measurable combination.
void tabulateCoverage(StudySummary& summary) {
  auto add = [](CoverageFigures& c, double error, double u) {
    ++c.runs;
    c.mean_u += u, c.mean_abs += std::abs(error);
    c.coverage += std::abs(error) <= u ? 1.0 : 0.0;
    c.mean_normalised += u > 0.0 ? std::abs(error) / u : 0.0;
  };
  auto finish = [](CoverageFigures& c) {
    if (c.runs == 0) return;
    const auto n = static_cast<double>(c.runs);
    c.mean_u /= n, c.mean_abs /= n, c.coverage /= n, c.mean_normalised /= n;
  };
  for (const auto& d : summary.dimensions) summary.coverage[d] = {};
  for (const auto& run : summary.runs) {
    for (const auto& [name, u] : run.expanded_mm) {
      add(summary.coverage[name], run.error_mm.at(name), u);
      add(summary.pooled, run.error_mm.at(name), u);
    }
    for (const auto& [expression, eu] : run.combinations)
      add(summary.combination_coverage[expression], eu.first, eu.second);
  }
  for (auto& [name, c] : summary.coverage) finish(c);
  for (auto& [name, c] : summary.combination_coverage) finish(c);
  finish(summary.pooled);
}

nlohmann::json coverageJson(const CoverageFigures& c) {
  return nlohmann::json{{"runs_with_u", c.runs},
                        {"mean_u_mm", c.mean_u},
                        {"coverage", c.coverage},
                        {"mean_normalised_error", c.mean_normalised},
                        {"mean_abs_mm", c.mean_abs}};
}

nlohmann::json runJson(const StudyRun& run) {
  nlohmann::json combination_errors = nlohmann::json::object();
  for (const auto& [expression, eu] : run.combinations)
    combination_errors[expression] = {{"error_mm", eu.first}, {"expanded_uncertainty", eu.second}};
  nlohmann::json out = {{"id", run.id},
                        {"status", run.measured() ? "measured" : "not measured"},
                        {"failures", run.failures},
                        {"seconds", run.seconds},
                        {"error_mm", run.error_mm},
                        {"expanded_uncertainty_mm", run.expanded_mm},
                        {"combinations", combination_errors}};
  if (run.rate_scale)
    out["material_refinement"] = {{"rate_scale", run.rate_scale->first},
                                  {"standard_uncertainty", run.rate_scale->second}};
  return out;
}

// study.json: the figures per dimension and overall, and every run's.
nlohmann::json studyJson(const StudyOptions& options, StudySummary& summary) {
  nlohmann::json per_dim = nlohmann::json::object();
  for (const auto& d : summary.dimensions) {
    per_dim[d] = {{"mean_abs_mm", summary.mean_abs_mm[d]}, {"max_abs_mm", summary.max_abs_mm[d]}};
    per_dim[d].update(coverageJson(summary.coverage[d]));
  }
  nlohmann::json combos = nlohmann::json::object();
  for (const auto& [expression, c] : summary.combination_coverage)
    combos[expression] = coverageJson(c);
  nlohmann::json all_runs = nlohmann::json::array();
  for (const auto& run : summary.runs) all_runs.push_back(runJson(run));
  return {{"dataset", options.dataset.string()},
          {"combinations", options.combinations},
          {"dimensions", per_dim},
          {"mean_abs_mm", summary.mean_abs_mm_all},
          {"max_abs_mm", summary.max_abs_mm_all},
          {"pooled_coverage", coverageJson(summary.pooled)},
          {"combinations_coverage", combos},
          {"median_seconds", summary.median_seconds},
          {"measured_runs", summary.measured_runs},
          {"runs", all_runs}};
}

}  // namespace

StudySummary runStudy(const StudyOptions& options) {
  DatasetTruth truth = DatasetTruth::load(options.dataset / "truth.json");
  const ConfigNode settings_node = ConfigNode::loadFile(options.settings);
  nlohmann::json settings = settings_node.json();
  useSettingsMachine(settings, truth.machine, options.settings);
  applyStudyLag(settings, truth.machine, options.settings);
  createOutputFolder(options.output / "runs");

  // The part and the machine from the dataset, the material from the
  // settings or fitted, each radiograph prepared once for every run.
  StudyInputs inputs = prepareStudyInputs(truth, settings, options.settings);
  // Without a scatter of their own, the runs take the one the material's
  // calibration found, as a measurement job does (measure/inputs.cpp).
  if (!settings.contains("scatter") && inputs.material_scatter)
    spdlog::info(
        "{}: the scatter its material's calibration found: weight {:.4f}, sigma {:.1f} mm{}",
        options.settings.string(), inputs.material_scatter->model.weight,
        inputs.material_scatter->model.sigma_mm,
        inputs.material_scatter->curves ? ", moved together with the curve in the budget" : "");
  PreparedShots shots(inputs.machine);
  const StudyRecords records = writeStudyRecords(options, truth, inputs);
  const std::vector<Combination> runs = selectRuns(truth, options);
  if (options.shard_count > 1 && runs.empty()) return {};
  StudySummary summary;
  const std::vector<nlohmann::json> jobs =
      studyJobs(options, settings, truth, inputs, records, runs, summary.dimensions);
  FileDigests digests;
  studyRuns({options, truth, inputs, summary.dimensions, shots, digests}, runs, jobs, summary);

  // Statistics, CSV and JSON.
  const std::string csv = tabulateErrors(summary);
  tabulateCoverage(summary);
  // A shard's figures are a part of the study's: its files come from the
  // run that gathers every shard.
  if (options.shard_count == 1) writeFileAtomically(options.output / "study.csv", csv);
  const nlohmann::json study_json = studyJson(options, summary);
  if (options.shard_count > 1) return summary;
  writeFileAtomically(options.output / "study.json", study_json.dump(2) + "\n");
  if (options.report)
    writeReport(options.output / "report.html", ReportKind::kStudy,
                "xgauge study: " + options.dataset.filename().string(),
                {{"study", study_json},
                 {"settings", {{"file", options.settings.string()}, {"json", settings}}},
                 {"truth", truth.dimensions},
                 {"generated", utcTimestamp()}});
  return summary;
}

}  // namespace xgauge
