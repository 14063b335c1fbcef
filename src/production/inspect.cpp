#include "xgauge/production/inspect.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/core/manifest.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/production/spc_report.h"
#include "xgauge/report/html.h"
#include "xgauge/report/measurement.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <thread>

namespace xgauge {

namespace fs = std::filesystem;

namespace {

constexpr const char* kRadiographFileKeys[] = {"image", "dark", "flat", "previous"};

// The job for one part: the plan's, its radiographs' files in `folder`.
nlohmann::json jobFor(const InspectionPlan& plan, const fs::path& folder) {
  nlohmann::json job = plan.job;
  for (auto& r : job.at("radiographs"))
    for (const char* key : kRadiographFileKeys)
      if (r.contains(key) && r[key].is_string())
        r[key] = fs::absolute(folder / r[key].get<std::string>()).string();
  return job;
}

uint64_t fnv1a(const std::string& text) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
  return h;
}

}  // namespace

Shard Shard::parse(const std::string& text) {
  Shard s;
  const auto slash = text.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    size_t used = 0;
    s.index = std::stoi(text.substr(0, slash), &used);
    if (used != slash) throw std::invalid_argument("index");
    const std::string count = text.substr(slash + 1);
    s.count = std::stoi(count, &used);
    if (used != count.size()) throw std::invalid_argument("count");
  } catch (const std::exception&) {
    fail("--shard {}: expected i/N, e.g. 2/4", text);
  }
  if (s.count < 1 || s.index < 1 || s.index > s.count)
    fail("--shard {}: expected 1 <= i <= N", text);
  return s;
}

bool Shard::takes(const std::string& id) const {
  return count == 1 || static_cast<int>(fnv1a(id) % static_cast<uint64_t>(count)) == index - 1;
}

InspectionPlan InspectionPlan::load(const fs::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  InspectionPlan plan;
  plan.file = path;
  plan.sha256 = root.sha256();
  const fs::path folder = path.parent_path();
  plan.description = root.get<std::string>("description", "");
  plan.lot = root.get<std::string>("lot", "");
  plan.station = root.get<std::string>("station", "");
  if (auto store = root.find("store")) {
    plan.store = store->string();
    if (!isPostgresUrl(plan.store)) plan.store = (folder / plan.store).string();
  }
  if (auto source = root.find("source")) plan.source = folder / source->string();
  if (auto output = root.find("output")) plan.output = folder / output->string();
  if (auto lease = root.find("claim_lease_s")) plan.claim_lease_s = lease->number(1.0, 1e7);
  const ConfigNode job = root.at("job");
  if (!job.isObject()) job.fail("expected the measurement job (an object)");
  plan.job = job.json();
  root.finish();

  // Paths of the job outside the part folder, made absolute.
  for (const char* key : {"part", "machine", "material", "verification"})
    if (plan.job.contains(key) && plan.job[key].is_string())
      plan.job[key] = fs::absolute(folder / plan.job[key].get<std::string>()).string();
  // Every key of the job checked now, against a part folder of the plan's
  // own, and every file the parts share read (part model, machine, detector,
  // material, verification): a missing or bad one fails before any part.
  const ConfigNode check = job.derived(jobFor(plan, folder));
  loadJobInputs(check, path, true);
  check.finish();
  for (const auto& r : plan.job.at("radiographs"))
    for (const char* key : kRadiographFileKeys)
      if (r.contains(key) && r[key].get<std::string>().find('/') != std::string::npos)
        job.at("radiographs")
            .fail(fmt::format("'{}' of a radiograph must be a file name inside each part's folder, "
                              "not a path: {}",
                              key, r[key].get<std::string>()));
  return plan;
}

std::vector<std::string> InspectionPlan::partFiles() const {
  std::set<std::string> names;
  for (const auto& r : job.at("radiographs"))
    for (const char* key : kRadiographFileKeys)
      if (r.contains(key)) names.insert(r[key].get<std::string>());
  return {names.begin(), names.end()};
}

std::string partLine(const std::string& part, const nlohmann::json& result) {
  if (result.value("status", "") != "measured") return fmt::format("{}  not measured", part);
  std::string worst_name, verdict;
  double worst = -1.0, worst_signed = 0.0;
  int rank = -1;  // conforms < inconclusive < does not conform
  for (const auto& d : result.at("dimensions")) {
    if (!d.contains("tolerance")) continue;
    const auto& t = d.at("tolerance");
    const double lower = t.at("nominal").get<double>() + t.at("lower").get<double>();
    const double upper = t.at("nominal").get<double>() + t.at("upper").get<double>();
    const double x =
        (d.at("value_mm").get<double>() - 0.5 * (lower + upper)) / (0.5 * (upper - lower));
    if (std::abs(x) > worst) worst = std::abs(x), worst_signed = x, worst_name = d.at("name");
    const std::string v = d.value("verdict", "");
    const int r = v == "does not conform" ? 2 : v == "inconclusive" ? 1 : v == "conforms" ? 0 : -1;
    if (r > rank) rank = r, verdict = v;
  }
  if (worst < 0) return fmt::format("{}  no tolerance", part);
  if (verdict.empty()) verdict = "no verdict";  // an unverified U
  return fmt::format("{}  {}  {} {:+.3f}", part, verdict, worst_name, worst_signed);
}

namespace {

class Inspector {
 public:
  Inspector(const InspectionPlan& plan, const InspectOptions& options,
            const std::function<void(const std::string&)>& line)
      : plan_(plan), options_(options), line_(line) {
    source_ = options.source.empty() ? plan.source : options.source;
    if (source_.empty())
      fail("{}: no source of parts: give one, or --watch DIR", plan.file.string());
    output_ = options.output.empty() ? plan.output : options.output;
    if (output_.empty())
      fail("{}: no output folder for the parts' results: give \"output\" or -o",
           plan.file.string());
    const std::string location = options.store.empty() ? plan.store : options.store;
    if (location.empty())
      fail("{}: no results store: give \"store\" or --store", plan.file.string());
    store_ = ResultStore::open(location);
    claimant_ = Claimant::thisProcess(options.station.empty() ? plan.station : options.station,
                                      plan.claim_lease_s);
  }

  InspectSummary run() {
    using clock = std::chrono::steady_clock;
    auto last_new = clock::now();
    for (;;) {
      const Scan scan = look();
      if (!options_.watch) {
        // Parts another station holds: wait until it records them or dies.
        if (scan.elsewhere == 0) break;
      } else if (scan.measured > 0) {
        last_new = clock::now();
      } else if (options_.idle_exit_s > 0 &&
                 std::chrono::duration<double>(clock::now() - last_new).count() >=
                     options_.idle_exit_s) {
        break;
      }
      std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_s));
    }
    return summary_;
  }

 private:
  struct Scan {
    int measured = 0, elsewhere = 0;
  };

  std::vector<fs::path> partFolders() const {
    std::vector<fs::path> folders;
    std::error_code ec;
    if (!fs::is_directory(source_, ec)) fail("{}: not a folder of parts", source_.string());
    for (const auto& entry : fs::directory_iterator(source_))
      if (entry.is_directory() && !entry.path().filename().string().starts_with("."))
        folders.push_back(entry.path());
    std::sort(folders.begin(), folders.end());
    return folders;
  }

  Scan look() {
    Scan scan;
    std::vector<fs::path> mine;
    for (const auto& f : partFolders())
      if (options_.shard.takes(f.filename().string()) && !done_.count(f.filename().string()))
        mine.push_back(f);
    summary_.not_ready = 0;
    std::optional<ProgressBar> bar;
    if (!options_.watch && !mine.empty()) bar.emplace("inspect", static_cast<int64_t>(mine.size()));
    for (const auto& folder : mine) {
      const std::string id = folder.filename().string();
      const PartFolderCheck check = checkPartFolder(folder);
      if (check.state != PartFolderState::kReady && !options_.watch) {
        // A folder run looks once: what is not complete or not intact now
        // will not become so; the part failed.
        spdlog::error("{}: refused: {}: {}", id,
                      check.state == PartFolderState::kCorrupt ? "corrupt" : "incomplete",
                      check.why);
        done_.insert(id);
        markFailed(id);
      } else if (check.state != PartFolderState::kReady) {
        ++summary_.not_ready;
        if (!warned_.count(id + check.why)) {
          warned_.insert(id + check.why);
          spdlog::warn("{}: {}: {}", id,
                       check.state == PartFolderState::kCorrupt ? "refused" : "not complete yet",
                       check.why);
        }
      } else {
        const Outcome outcome = take(folder, check.manifest);
        if (outcome == Outcome::kMeasured) ++scan.measured;
        if (outcome == Outcome::kElsewhere) ++scan.elsewhere;
      }
      if (bar) bar->advance();
    }
    return scan;
  }

  enum class Outcome { kMeasured, kAlready, kElsewhere, kFailed };

  void markFailed(const std::string& id) {
    ++summary_.failed;
    summary_.failed_parts.push_back(id);
  }

  Outcome take(const fs::path& folder, const Manifest& manifest) {
    const std::string id = folder.filename().string();
    MeasurementRecord record;
    record.lot = !plan_.lot.empty() ? plan_.lot
                 : !manifest.lot.empty()
                     ? manifest.lot
                     : fs::absolute(source_).lexically_normal().filename().string();
    record.part = manifest.part;
    record.part_index = manifest.index;
    record.acquired_at = manifest.time;
    record.inputs_digest = manifest.digest();
    for (const auto& f : manifest.files) record.inputs_sha256[f.name] = f.sha256;
    record.plan = fs::absolute(plan_.file).string();
    record.plan_sha256 = plan_.sha256;
    record.station = claimant_.station;
    for (const auto& name : plan_.partFiles()) {
      const bool listed = std::any_of(manifest.files.begin(), manifest.files.end(),
                                      [&](const ManifestFile& f) { return f.name == name; });
      if (!listed) {
        spdlog::error("{}: refused: {} is not in its manifest, so it cannot be trusted complete",
                      id, (folder / name).string());
        done_.insert(id);
        markFailed(id);
        return Outcome::kFailed;
      }
    }
    const Claim claim = store_->claim(record, claimant_);
    if (claim.outcome == ClaimOutcome::kAlreadyMeasured) {
      done_.insert(id);
      ++summary_.already;
      return Outcome::kAlready;
    }
    if (claim.outcome == ClaimOutcome::kClaimedElsewhere) {
      ++summary_.elsewhere;
      return Outcome::kElsewhere;
    }
    nlohmann::json result;
    try {
      result = measurePart(folder, output_ / record.lot / id);
    } catch (const Error& e) {
      store_->release(record, claim.token);
      spdlog::error("{}: {}", id, e.what());
      done_.insert(id);
      markFailed(id);
      return Outcome::kFailed;
    }
    fillFromResult(result, record);
    record.measured_at = utcTimestamp();
    record.report = fs::absolute(output_ / record.lot / id).string();
    done_.insert(id);
    if (!store_->record(record, claim.token)) {
      ++summary_.already;
      return Outcome::kAlready;
    }
    ++summary_.measured;
    if (record.status != "measured") ++summary_.not_measured;
    line_(partLine(record.part, result));
    if (options_.spc_baseline > 0) watchProcess(record.lot);
    return Outcome::kMeasured;
  }

  // SPC after each part, once phase I is complete: the lot's analysis
  // replaces its alarms in the store; the alarms it did not have yet are
  // printed.
  void watchProcess(const std::string& lot) {
    SpcOptions spc;
    spc.baseline_parts = options_.spc_baseline;
    spc.skip_short_baseline = true;  // phase I not complete: no analysis yet
    const std::vector<DimensionSpc> analyses = analyseLot(*store_, lot, spc);
    if (analyses.empty()) return;
    const std::string now = utcTimestamp();
    std::vector<StoredAlarm> alarms, fresh;
    for (const auto& analysis : analyses)
      for (auto& a : alarmsOf(analysis, now)) alarms.push_back(std::move(a));
    store_->recordAnalysis({lot}, alarms, now, &fresh);
    for (const auto& a : fresh) line_(alarmLine(a));
  }

  // Measures one part as `xgauge measure` does and writes its outputs.
  nlohmann::json measurePart(const fs::path& folder, const fs::path& out) {
    checkOutputFolder(out);
    const ConfigNode root = ConfigNode::fromJson(
        jobFor(plan_, folder), fmt::format("{} (part {})", plan_.file.string(), folder.string()));
    const MeasurementInputs inputs = loadMeasurementInputs(root, plan_.file, true);
    root.finish();
    ForwardModel model(inputs);
    auto [result, simulated] = measureWithPictures(model);
    nlohmann::json json = measurementJson(model, result);
    OutputTransaction outputs;
    writeMeasurementOutputs(model, result, out, options_.report, nullptr, std::move(simulated));
    outputs.commit();
    return json;
  }

  const InspectionPlan& plan_;
  const InspectOptions& options_;
  const std::function<void(const std::string&)>& line_;
  fs::path source_, output_;
  std::unique_ptr<ResultStore> store_;
  Claimant claimant_;
  InspectSummary summary_;
  std::set<std::string> done_;    // parts this process is finished with
  std::set<std::string> warned_;  // not-ready messages already given
};

}  // namespace

InspectSummary inspect(const InspectionPlan& plan, const InspectOptions& options,
                       const std::function<void(const std::string&)>& line) {
  Inspector inspector(plan, options, line);
  return inspector.run();
}

}  // namespace xgauge
