#include "xgauge/measure/study.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/progress.h"
#include "xgauge/material/exponential_fit.h"
#include "xgauge/measure/job.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/truth.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <fstream>
#include <mutex>

namespace xgauge {

namespace {

namespace fs = std::filesystem;

struct Combination {
  std::string id;
  std::vector<std::string> shots;  // first is the free one
};

std::vector<Combination> combinations(const DatasetTruth& truth, const std::string& kind) {
  std::vector<const TruthShot*> translated, rotated;
  for (const auto& s : truth.shots) {
    if (s.name.rfind("t", 0) == 0) translated.push_back(&s);
    if (s.pattern == "rotated") rotated.push_back(&s);
  }
  if (kind != "pairs" && kind != "pairs+rotated")
    fail("unknown combinations '{}' (known: pairs, pairs+rotated)", kind);
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
                        const std::vector<std::string>& shots, const StudyInputs& inputs,
                        const std::string& id) {
  nlohmann::json job = settings;
  job.erase("material");
  job["description"] = "study run " + id;
  job["part"] = fs::absolute(truth.part_file).string();
  job["machine"] = fs::absolute(inputs.machine).string();
  job["material"] = fs::absolute(inputs.material).string();
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
    if (i == 0) {
      r["pattern"] = "free";
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

StudyInputs prepareStudyInputs(const DatasetTruth& truth, const nlohmann::json& settings,
                               const fs::path& settings_file, const fs::path& folder) {
  fs::create_directories(folder);
  StudyInputs inputs{folder / "machine.json", folder / "material.json"};
  writeFileAtomically(inputs.machine, truth.machine.dump(2) + "\n");
  std::string material = "fit";
  if (const auto it = settings.find("material"); it != settings.end()) {
    if (!it->is_string()) fail("{}: /material: expected \"fit\" or a file name", settings_file.string());
    material = it->get<std::string>();
  }
  if (material == "fit") {
    ExponentialFitReport report;
    const ExponentialSum fitted = fitExponentialSum(truth.path_mm, truth.transmission, 3, {}, &report);
    nlohmann::json m = fitted.toJson();
    m["description"] = fmt::format("3 exponentials fitted to {} (max residual {:.2e})",
                                   (truth.folder / "truth.json").string(), report.max_abs_residual);
    writeFileAtomically(inputs.material, m.dump(2) + "\n");
  } else {
    inputs.material = settings_file.parent_path() / material;
  }
  return inputs;
}

std::string StudySummary::table() const {
  std::string out = fmt::format("{:<18} {:>14} {:>14}\n", "dimension", "mean |err| mm", "max |err| mm");
  for (const auto& d : dimensions)
    out += fmt::format("{:<18} {:>14.4f} {:>14.4f}\n", d, mean_abs_mm.at(d), max_abs_mm.at(d));
  out += fmt::format("{:<18} {:>14.4f} {:>14.4f}\n", "all", mean_abs_mm_all, max_abs_mm_all);
  out += fmt::format("{} runs, median {:.1f} s per run\n", runs.size(), median_seconds);
  return out;
}

StudySummary runStudy(const StudyOptions& options) {
  const DatasetTruth truth = DatasetTruth::load(options.dataset / "truth.json");
  const ConfigNode settings_node = ConfigNode::loadFile(options.settings);
  nlohmann::json settings = settings_node.json();
  fs::create_directories(options.output / "runs");

  // The machine from the dataset; the material from the settings or fitted.
  const StudyInputs inputs = prepareStudyInputs(truth, settings, options.settings, options.output);

  std::vector<Combination> runs = combinations(truth, options.combinations);
  if (options.limit > 0 && static_cast<size_t>(options.limit) < runs.size())
    runs.resize(static_cast<size_t>(options.limit));

  // Write every job first (so a bad setting fails before any work).
  std::vector<MeasurementJob> jobs;
  for (const auto& c : runs) {
    const fs::path folder = options.output / "runs" / c.id;
    fs::create_directories(folder);
    writeFileAtomically(folder / "job.json", studyJob(settings, truth, c.shots, inputs, c.id).dump(2) + "\n");
    jobs.push_back(MeasurementJob::load(folder / "job.json"));
  }

  StudySummary summary;
  for (const auto& name : jobs.front().free_dimensions) summary.dimensions.push_back(name);
  summary.runs.resize(runs.size());
  ProgressBar progress("study", static_cast<int64_t>(runs.size()));
  const bool progress_was = progressEnabled();
  setProgressEnabled(false);  // no bars from the runs themselves
  const auto level = spdlog::get_level();
  spdlog::set_level(spdlog::level::warn);
  tbb::parallel_for(size_t{0}, runs.size(), [&](size_t i) {
    const fs::path folder = options.output / "runs" / runs[i].id;
    const fs::path result_file = folder / "result.json";
    if (!fs::exists(result_file)) {
      const MeasurementResult result = measure(jobs[i]);
      if (options.images) {
        writeMeasurementOutputs(jobs[i], result, folder);
      } else {
        nlohmann::json dims = nlohmann::json::array();
        for (const auto& d : result.dimensions)
          dims.push_back({{"name", d.name}, {"value_mm", d.value}, {"free", d.free}});
        writeFileAtomically(result_file, nlohmann::json({{"dimensions", dims},
                                                         {"seconds", result.seconds},
                                                         {"evaluations", result.evaluations},
                                                         {"total_loss", result.total_loss}})
                                                 .dump(2) + "\n");
      }
    }
    std::ifstream in(result_file);
    const auto result = nlohmann::json::parse(in);
    StudyRun run{runs[i].id, {}, result.value("seconds", 0.0)};
    for (const auto& d : result["dimensions"])
      if (d["free"].get<bool>())
        run.error_mm[d["name"]] = d["value_mm"].get<double>() - truth.dimensions.at(d["name"]);
    summary.runs[i] = run;
    progress.advance();
  });
  spdlog::set_level(level);
  setProgressEnabled(progress_was);
  progress.finish();

  // Statistics, CSV and JSON.
  double sum_all = 0.0;
  size_t count_all = 0;
  std::string csv = "run,seconds";
  for (const auto& d : summary.dimensions) csv += "," + d + "_error_mm";
  csv += "\n";
  for (const auto& d : summary.dimensions) summary.mean_abs_mm[d] = 0.0, summary.max_abs_mm[d] = 0.0;
  std::vector<double> seconds;
  for (const auto& run : summary.runs) {
    csv += fmt::format("{},{:.3f}", run.id, run.seconds);
    seconds.push_back(run.seconds);
    for (const auto& d : summary.dimensions) {
      const double e = std::abs(run.error_mm.at(d));
      summary.mean_abs_mm[d] += e / static_cast<double>(summary.runs.size());
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
  writeFileAtomically(options.output / "study.csv", csv);
  nlohmann::json per_dim = nlohmann::json::object();
  for (const auto& d : summary.dimensions)
    per_dim[d] = {{"mean_abs_mm", summary.mean_abs_mm[d]}, {"max_abs_mm", summary.max_abs_mm[d]}};
  nlohmann::json all_runs = nlohmann::json::array();
  for (const auto& run : summary.runs) all_runs.push_back({{"id", run.id}, {"seconds", run.seconds}, {"error_mm", run.error_mm}});
  writeFileAtomically(options.output / "study.json",
                      nlohmann::json({{"dataset", options.dataset.string()},
                                      {"combinations", options.combinations},
                                      {"dimensions", per_dim},
                                      {"mean_abs_mm", summary.mean_abs_mm_all},
                                      {"max_abs_mm", summary.max_abs_mm_all},
                                      {"median_seconds", summary.median_seconds},
                                      {"runs", all_runs}})
                              .dump(2) + "\n");
  return summary;
}

}  // namespace xgauge
