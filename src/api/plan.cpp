// The front door's view plan (xgauge/xgauge.h) over plan/plan.h. `xgauge
// plan` is this call and a print.
#include "guard.h"
#include "xgauge/core/output.h"
#include "xgauge/plan/plan.h"
#include "xgauge/xgauge.h"

#include <fmt/format.h>

#include <cmath>

namespace xgauge {

namespace {

// The best sets and the compared ones: views (patterns), criterion and U
// per dimension ("-" where the views do not determine it).
std::string planTable(const PlanJob& job, const PlanResult& result) {
  const auto row = [&](const std::string& label, const PredictedSet& set) {
    std::string views;
    for (size_t k = 0; k < set.views.size(); ++k)
      views += fmt::format("{}{}:{}", k ? " " : "", job.views[static_cast<size_t>(set.views[k])].name,
                           set.patterns[k]);
    const std::string score = std::isfinite(set.score) ? fmt::format("{:.4f}", set.score) : "-";
    const std::string marks =
        std::string(set.budgeted && !set.complete() ? "*" : "") + (set.beyond_range.empty() ? "" : "+");
    std::string line = fmt::format("{:<9} {:<36} {:>9}", label, views, score + marks);
    for (const PredictedDimension& d : set.dimensions)
      line += d.identifiable ? fmt::format(" {:>10.4f}", d.expanded) : fmt::format(" {:>10}", "-");
    return line + "\n";
  };
  std::string table = fmt::format("{:<9} {:<36} {:>9}", "set", "views", "criterion");
  for (const PredictedDimension& d : result.ranked.front().dimensions)
    table += fmt::format(" {:>10}", d.name.substr(0, 10));
  table += "\n";
  int budgeted = 0;
  for (const PredictedSet& s : result.ranked)
    if (s.budgeted) table += row(fmt::format("#{}", ++budgeted), s);
  for (const PredictedSet& s : result.compared) table += row("compared", s);
  table += fmt::format("U (k = 2) predicted by the measurement's budget at the nominal part; {}.\n",
                       result.search);
  bool beyond = false;
  for (const PredictedSet& s : result.ranked) beyond |= s.budgeted && !s.beyond_range.empty();
  if (beyond)
    table +=
        "+: a view's paths run beyond the material's calibrated range: the curve is extrapolated "
        "there, the model may not fit the shot and U does not say by how much; the set ranks "
        "after every set within the range (plan.json: \"beyond_calibrated_range\").\n";
  bool curve = false;
  for (const PredictedSet& s : result.ranked) curve |= s.budgeted && s.scale_from_curve();
  if (curve)
    table +=
        "Sets of free views only rest the part's scale on the material's curve: a curve off by "
        "more than its stated uncertainty biases every length beyond U (docs/method.md, "
        "\"Planning the views\"; \"sets\": \"known_moves\" leaves them out).\n";
  bool incomplete = false;
  for (const PredictedSet& s : result.ranked) incomplete |= s.budgeted && !s.complete();
  if (incomplete)
    table +=
        "*: its budget left an influence out (its shift did not settle): that U is too small, "
        "and the set ranks after every complete one (plan.json: \"unpropagated\").\n";
  return table;
}

PlanSummary planOrThrow(const PlanOptions& options) {
  checkOutputFolder(options.output_folder);
  const PlanJob job = PlanJob::load(options.job_file);
  const PlanResult result = planViews(job);
  writePlan(job, result, options.output_folder);
  PlanSummary summary;
  summary.screened = static_cast<std::size_t>(result.screened);
  summary.report = planTable(job, result);
  summary.termination = RunTermination::kDone;
  summary.message = fmt::format("wrote {0}/plan.json, {0}/job.json and {0}/report.html",
                                options.output_folder.string());
  return summary;
}

}  // namespace

PlanSummary plan(const PlanOptions& options) {
  return api::guarded<PlanSummary>([&] { return planOrThrow(options); });
}

}  // namespace xgauge
