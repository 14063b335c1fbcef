// The front door (xgauge/xgauge.h) over the measurement pipeline: loads the
// job once, measures, writes the outputs, and turns the library's result
// and its errors into the summary. `xgauge measure` is this and a print.
#include "xgauge/xgauge.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/core/output.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/tolerance.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/measurement.h"

#include <fmt/format.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>
#include <new>
#include <sstream>

namespace xgauge {

// Sets the summary's private parts (the report and result.json's text).
class MeasurementSummaryBuilder {
 public:
  static void set(MeasurementSummary& s, std::string full_report, std::string json) {
    s.full_report_ = std::move(full_report);
    s.json_ = std::move(json);
  }
};

namespace {

VerdictType verdictOf(const MeasuredDimension& d) {
  if (!d.decision) return VerdictType::kNone;
  switch (d.decision->verdict) {
    case Verdict::kConforms:
      return VerdictType::kConforms;
    case Verdict::kDoesNotConform:
      return VerdictType::kDoesNotConform;
    case Verdict::kInconclusive:
      return VerdictType::kInconclusive;
  }
  return VerdictType::kNone;
}

StageSummary stageSummary(const StageReport& s) {
  return {s.name,        s.method,     s.level,   s.evaluations,
          s.loss_before, s.loss_after, s.seconds, s.termination};
}

// The table `xgauge measure` prints (FullReport).
std::string reportTable(const MeasurementResult& result, const std::optional<DatasetTruth>& truth) {
  bool toleranced = false;
  for (const auto& d : result.dimensions) toleranced |= d.decision.has_value();
  const bool measured = result.status == MeasurementStatus::kMeasured;
  std::string table;
  if (!measured) {
    table += fmt::format(
        "NOT MEASURED: after {} attempt(s) the fit does not explain the radiographs; the values "
        "below are the rejected fit's, not results, and no verdict is given:\n",
        result.attempts);
    for (const auto& f : result.check.failures) table += "  - " + f + "\n";
  }
  table += fmt::format("{:<18} {:>10} {:>9} {:<10}", "dimension",
                       measured ? "measured" : "rejected", "U (k=2)", " U is");
  if (toleranced) table += fmt::format(" {:>19} {:<16}", "tolerance zone", " verdict");
  if (truth) table += fmt::format(" {:>10} {:>10}", "true", "error");
  table += "\n";
  for (const auto& d : result.dimensions) {
    table += fmt::format("{:<18} {:>10.4f} {:>9}", d.name + (d.free ? "" : " (fixed)"), d.value,
                         !d.free                  ? ""
                         : d.expanded_uncertainty ? fmt::format("{:.4f}", *d.expanded_uncertainty)
                                                  : "n/a");
    table += fmt::format(" {:<10}", !d.free ? "" : d.verified ? " verified" : " unverified");
    if (toleranced)
      table += d.tolerance && d.decision
                   ? fmt::format(" [{:>8.4f},{:>9.4f}]  {:<16}", d.tolerance->lowerLimit(),
                                 d.tolerance->upperLimit(),
                                 std::string(verdictName(d.decision->verdict)))
                   : fmt::format(" {:>19} {:<16}", "", "");
    if (truth && truth->dimensions.count(d.name))
      table += fmt::format(" {:>10.4f} {:>+10.4f}", truth->dimensions.at(d.name),
                           d.value - truth->dimensions.at(d.name));
    table += "\n";
  }
  for (const auto& c : result.uncertainty.combinations)
    table += c.name.empty()
                 ? fmt::format(
                       "{:<18} {:>10.4f} {:>9.4f}  (measurable combination of dimensions "
                       "that are not determined alone)\n",
                       c.expression, c.value, c.expanded)
                 : fmt::format("{:<18} {:>10.4f} {:>9.4f}  (the part's combination {})\n", c.name,
                               c.value, c.expanded, c.expression);
  if (const auto& refined = result.uncertainty.refinement)
    table += fmt::format(
        "material refined in situ: rates x (1 {:+.5f}), u {:.5f} (prior {:.5f}); the curve "
        "{:+.4f} at {:.1f} mm\n",
        refined->rate_scale, refined->standard_uncertainty, refined->prior_standard_uncertainty,
        refined->transmission_change, refined->at_path_mm);
  if (toleranced) table += fmt::format("Verdicts: {}.\n", kDecisionRule);
  if (!result.check.warnings.empty()) {
    table += fmt::format("{} warning(s):\n", result.check.warnings.size());
    for (const auto& w : result.check.warnings) table += "  - " + w + "\n";
  }
  return table;
}

// The exit status of `xgauge measure` for a result.
int exitStatusOf(const MeasurementResult& result) {
  if (result.status != MeasurementStatus::kMeasured) return kExitCouldNotMeasure;
  std::vector<Decision> decisions;
  bool withheld = false;
  for (const auto& d : result.dimensions) {
    if (d.decision) decisions.push_back(*d.decision);
    withheld |= d.tolerance && !d.decision;  // an unverified U: no verdict
  }
  // A tolerance whose verdict was withheld cannot be taken as conforming.
  return std::max(exitCodeFor(decisions), withheld ? kExitInconclusive : kExitConforms);
}

MeasurementSummary summarize(const MeasurementResult& result,
                             const std::optional<DatasetTruth>& truth, const std::string& table,
                             const nlohmann::json& json) {
  MeasurementSummary s;
  s.termination = result.status == MeasurementStatus::kMeasured ? TerminationType::kMeasured
                                                                : TerminationType::kNotMeasured;
  for (const auto& d : result.dimensions) {
    DimensionSummary out;
    out.name = d.name;
    out.unit = d.unit;
    out.value = d.value;
    out.free = d.free;
    out.expanded_uncertainty = d.expanded_uncertainty;
    out.verified = d.verified;
    if (d.tolerance)
      out.lower_limit = d.tolerance->lowerLimit(), out.upper_limit = d.tolerance->upperLimit();
    out.verdict = verdictOf(d);
    if (truth && truth->dimensions.count(d.name)) out.true_value = truth->dimensions.at(d.name);
    s.dimensions.push_back(out);
  }
  s.failures = result.check.failures;
  s.warnings = result.check.warnings;
  for (const auto& stage : result.stages) s.stages.push_back(stageSummary(stage));
  s.attempts = result.attempts;
  s.evaluations = result.evaluations;
  s.final_loss = result.total_loss;
  s.seconds = result.seconds;
  s.exit_status = exitStatusOf(result);
  MeasurementSummaryBuilder::set(s, table, json.dump(2) + "\n");
  return s;
}

// A copy of the library's messages while it lives (measure.log).
class LogCopy {
 public:
  LogCopy() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(log_)) {
    sink_->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~LogCopy() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  LogCopy(const LogCopy&) = delete;
  LogCopy& operator=(const LogCopy&) = delete;
  std::string text() const { return log_.str(); }

 private:
  std::ostringstream log_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

MeasurementInputs loadInputs(const MeasurementOptions& options) {
  if (!options.job_file.empty()) return loadMeasurementInputs(options.job_file);
  const ConfigNode root = ConfigNode::parse(options.job_json, "<job>");
  // Relative paths are the base folder's, as a job file's are its folder's.
  MeasurementInputs inputs = loadMeasurementInputs(root, options.base_folder / "job.json", true);
  root.finish();
  return inputs;
}

MeasurementSummary measureOrThrow(const MeasurementOptions& options) {
  const bool writes = !options.output_folder.empty();
  if (writes) checkOutputFolder(options.output_folder);
  // measure.log from the first file read: what reading and normalising did.
  std::optional<LogCopy> log;
  if (writes) log.emplace();
  const MeasurementInputs inputs = loadInputs(options);
  std::optional<DatasetTruth> truth;
  if (!options.truth_file.empty()) truth = DatasetTruth::load(options.truth_file);

  ForwardModel model(inputs);
  std::function<void(const StageReport&)> on_stage;
  if (options.on_stage)
    on_stage = [&options](const StageReport& s) { options.on_stage(stageSummary(s)); };
  auto [result, simulated] = measureWithPictures(model, on_stage);
  const std::string table = reportTable(result, truth);
  // result.json's contents, made once: the summary's ToJson and the file.
  const nlohmann::json json = measurementJson(model, result);
  MeasurementSummary summary = summarize(result, truth, table, json);
  spdlog::info("{} evaluations in {:.1f} s; final loss {:.6g}", result.evaluations, result.seconds,
               result.total_loss);
  if (writes) {
    OutputTransaction outputs;
    nlohmann::json true_values = nullptr;
    if (truth)
      for (const auto& [name, value] : truth->dimensions) true_values[name] = value;
    writeMeasurementOutputs(model, result, options.output_folder, options.write_report, true_values,
                            std::move(simulated), &json);
    const std::string text = log->text();
    log.reset();
    writeFileAtomically(options.output_folder / "measure.log", text + table);
    outputs.commit();
    spdlog::info("wrote {}/result.json", options.output_folder.string());
  }
  return summary;
}

MeasurementSummary failure(const std::string& message) {
  MeasurementSummary s;
  s.termination = TerminationType::kFailure;
  s.message = message;
  s.exit_status = kExitCouldNotMeasure;
  return s;
}

}  // namespace

const char* TerminationTypeToString(TerminationType type) {
  switch (type) {
    case TerminationType::kMeasured:
      return "measured";
    case TerminationType::kNotMeasured:
      return "not measured";
    case TerminationType::kFailure:
      return "failure";
  }
  return "unknown";
}

const char* VerdictTypeToString(VerdictType type) {
  switch (type) {
    case VerdictType::kNone:
      return "";
    case VerdictType::kConforms:
      return "conforms";
    case VerdictType::kDoesNotConform:
      return "does not conform";
    case VerdictType::kInconclusive:
      return "inconclusive";
  }
  return "unknown";
}

bool MeasurementOptions::IsValid(std::string* error) const {
  const auto invalid = [error](std::string why) {
    if (error) *error = std::move(why);
    return false;
  };
  if (job_file.empty() == job_json.empty())
    return invalid("give the job as job_file or as job_json, not both and not neither");
  if (!job_json.empty() && base_folder.empty())
    return invalid("base_folder: empty (\".\" for the current folder)");
  // Files and folders are checked when they are used, by the loaders that
  // name the file and key (a file may appear or go between here and there).
  return true;
}

std::string MeasurementSummary::BriefReport() const {
  if (termination == TerminationType::kFailure) return "failure: " + message;
  int toleranced = 0, conforming = 0;
  for (const auto& d : dimensions)
    if (d.verdict != VerdictType::kNone)
      ++toleranced, conforming += d.verdict == VerdictType::kConforms;
  std::string line = fmt::format("{}: {} dimension(s) in {} attempt(s), {} evaluations, {:.1f} s",
                                 TerminationTypeToString(termination), dimensions.size(), attempts,
                                 evaluations, seconds);
  if (termination == TerminationType::kNotMeasured)
    line += fmt::format("; {} failure(s), the first: {}", failures.size(),
                        failures.empty() ? std::string("-") : failures.front());
  else if (toleranced > 0)
    line += fmt::format("; {} of {} verdict(s) conform", conforming, toleranced);
  if (!warnings.empty()) line += fmt::format("; {} warning(s)", warnings.size());
  return line;
}

std::string MeasurementSummary::FullReport() const {
  if (termination == TerminationType::kFailure) return "failure: " + message + "\n";
  return full_report_;
}

std::string MeasurementSummary::ToJson() const { return json_; }

MeasurementSummary measure(const MeasurementOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return failure(why);
  try {
    return measureOrThrow(options);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    return failure(e.what());
  }
}

}  // namespace xgauge
