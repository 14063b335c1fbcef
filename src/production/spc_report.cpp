#include "xgauge/production/spc_report.h"

#include "xgauge/core/error.h"
#include "xgauge/report/html.h"
#include "xgauge/version.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace xgauge {

namespace {

struct Series {
  std::string unit;
  std::vector<std::string> parts;
  std::vector<double> values;
  std::vector<std::optional<double>> u;
  std::optional<double> nominal, lsl, usl;
};

// Every dimension's series over a lot's measured parts, in production order.
std::map<std::string, Series> seriesOf(ResultStore& store, const std::string& lot,
                                       std::vector<std::string>& order) {
  std::map<std::string, Series> out;
  for (const StoredPart& part : store.lotSeries(lot)) {
    if (part.status != "measured") continue;
    for (const StoredDimension& d : part.dimensions) {
      if (!out.count(d.name)) order.push_back(d.name);
      Series& s = out[d.name];
      s.unit = d.unit;
      s.parts.push_back(part.part);
      s.values.push_back(d.value);
      s.u.push_back(d.expanded_uncertainty);
      // The latest part's tolerance: a plan changed mid-lot shows its current one.
      if (d.lower_limit) s.nominal = d.nominal, s.lsl = d.lower_limit, s.usl = d.upper_limit;
    }
  }
  return out;
}

nlohmann::json optionalJson(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json();
}

nlohmann::json intervalJson(const Interval& i) {
  return {{"value", i.value}, {"low", i.low}, {"high", i.high}};
}

// The histogram of the lot's values, bins by a rule on the data
// (histogramBins: Freedman-Diaconis, else Scott); the page draws the
// tolerance limits over it as lines, and its x range takes them in.
nlohmann::json histogram(const DimensionSpc& s) {
  const HistogramBins h = histogramBins(s.values);
  std::vector<double> centres(h.count);
  for (size_t b = 0; b < h.count; ++b) centres[b] = h.centre(b);
  return {{"centres", centres}, {"counts", h.counts}, {"width", h.width},
          {"start", h.start},   {"bins", h.count},    {"rule", h.rule}};
}

}  // namespace

nlohmann::json DimensionSpc::toJson() const {
  nlohmann::json hits_json = nlohmann::json::array();
  for (const auto& h : hits)
    hits_json.push_back(
        {{"rule", ruleName(h.rule)},
         {"description", ruleDescription(h.rule)},
         {"chart", h.rule == SpcRule::kMovingRange ? "moving range" : "individuals"},
         {"index", h.index},
         {"position", h.index + 1},
         {"part", parts[h.index]},
         {"value", values[h.index]}});
  std::vector<nlohmann::json> moving = {nullptr};
  for (size_t i = 1; i < values.size(); ++i) moving.push_back(std::abs(values[i] - values[i - 1]));
  std::vector<nlohmann::json> u;
  for (const auto& x : expanded_uncertainty) u.push_back(optionalJson(x));
  nlohmann::json out = {
      {"software", "xgauge " XGAUGE_VERSION_STRING},
      {"lot", lot},
      {"dimension", dimension},
      {"unit", unit},
      {"parts", parts},
      {"values", values},
      {"moving_ranges", moving},
      {"expanded_uncertainty", u},
      {"baseline", {{"description", baseline}, {"n", limits.baseline_n}}},
      {"limits",
       {{"centre", limits.centre},
        {"sigma_within", limits.sigma_within},
        {"lower", limits.lower},
        {"upper", limits.upper},
        {"sigma_1", {limits.centre - limits.sigma_within, limits.centre + limits.sigma_within}},
        {"sigma_2",
         {limits.centre - 2 * limits.sigma_within, limits.centre + 2 * limits.sigma_within}},
        {"mr_centre", limits.mr_bar},
        {"mr_upper", limits.mr_upper}}},
      {"hits", hits_json},
      {"tolerance",
       {{"nominal", optionalJson(nominal)},
        {"lower", optionalJson(lsl)},
        {"upper", optionalJson(usl)}}},
      {"u_over_t", optionalJson(u_over_t)},
      {"u_over_t_warning", u_over_t && *u_over_t > 1.0 / 3.0},
      {"histogram", histogram(*this)},
  };
  if (capability)
    out["capability"] = {{"n", capability->n},
                         {"mean", capability->mean},
                         {"s", capability->s},
                         {"confidence", capability->confidence},
                         {"cp", intervalJson(capability->cp)},
                         {"cpk", intervalJson(capability->cpk)}};
  else
    out["capability"] = nullptr;
  return out;
}

std::vector<DimensionSpc> analyseLot(ResultStore& store, const std::string& lot,
                                     const SpcOptions& options) {
  std::vector<std::string> order, baseline_order;
  const auto series = seriesOf(store, lot, order);
  std::map<std::string, Series> baseline_lot;
  if (!options.baseline_lot.empty())
    baseline_lot = seriesOf(store, options.baseline_lot, baseline_order);
  std::vector<DimensionSpc> out;
  for (const auto& name : order) {
    const Series& s = series.at(name);
    if (s.values.size() < 2) continue;
    DimensionSpc d;
    d.lot = lot;
    d.dimension = name;
    d.unit = s.unit;
    d.parts = s.parts;
    d.values = s.values;
    d.expanded_uncertainty = s.u;
    d.nominal = s.nominal, d.lsl = s.lsl, d.usl = s.usl;
    std::vector<double> phase1;
    std::vector<std::optional<double>> phase1_u;
    if (!options.baseline_lot.empty()) {
      const auto found = baseline_lot.find(name);
      if (found == baseline_lot.end())
        fail("{}: the baseline lot '{}' has no values of {}", store.where(), options.baseline_lot,
             name);
      phase1 = found->second.values;
      phase1_u = found->second.u;
      d.baseline = "lot " + options.baseline_lot;
    } else {
      // A lot shorter than the baseline asked for: phase I would be every
      // part, drift included, and the limits would hide the drift. Refused,
      // unless the caller skips such dimensions (inspect --spc: phase I not
      // complete yet); a smaller --baseline, at most the parts present, is
      // the explicit choice of a shorter phase I.
      if (s.values.size() < options.baseline_parts) {
        if (options.skip_short_baseline) continue;
        fail(
            "{}: lot {} has {} measured part(s) with a value of {}, fewer than the {} of the "
            "phase-I baseline asked for: limits from every part would take in any drift. Give "
            "--baseline N with N at most {} to take the first N parts as phase I, or "
            "--baseline-lot LOT",
            store.where(), lot, s.values.size(), name, options.baseline_parts, s.values.size());
      }
      const size_t n = options.baseline_parts;
      phase1.assign(s.values.begin(), s.values.begin() + static_cast<long>(n));
      phase1_u.assign(s.u.begin(), s.u.begin() + static_cast<long>(n));
      d.baseline = fmt::format("first {} parts", n);
    }
    try {
      d.limits = controlLimits(phase1);
    } catch (const Error& e) {
      fail("{}: lot {}, {}: {}", store.where(), lot, name, e.message());
    }
    d.hits = applyRules(d.values, d.limits, options.rules);
    if (d.lsl && d.usl && *d.lsl < *d.usl) {
      d.capability = capability(phase1, *d.lsl, *d.usl, options.confidence);
      double sum = 0.0;
      int n = 0;
      for (const auto& u : phase1_u)
        if (u) sum += *u, ++n;
      if (n > 0) d.u_over_t = sum / n / (*d.usl - *d.lsl);
    }
    out.push_back(std::move(d));
  }
  return out;
}

std::vector<StoredAlarm> alarmsOf(const DimensionSpc& spc, const std::string& raised_at) {
  std::vector<StoredAlarm> out;
  for (const auto& h : spc.hits) {
    StoredAlarm a;
    a.lot = spc.lot;
    a.dimension = spc.dimension;
    a.rule = ruleName(h.rule);
    a.chart = h.rule == SpcRule::kMovingRange ? "moving range" : "individuals";
    a.part = spc.parts[h.index];
    a.position = static_cast<int64_t>(h.index) + 1;
    a.value = spc.values[h.index];
    a.detail = ruleDescription(h.rule);
    a.raised_at = raised_at;
    out.push_back(a);
  }
  return out;
}

std::string alarmLine(const StoredAlarm& a) {
  return fmt::format("ALARM {} {} {} {} (#{}) {:.4f}: {}", a.lot, a.dimension, a.rule, a.part,
                     a.position, a.value, a.detail);
}

void writeSpcPage(const std::filesystem::path& path, const DimensionSpc& spc) {
  nlohmann::json data = {{"spc", spc.toJson()}, {"generated", utcTimestamp()}};
  writeReport(path, ReportKind::kSpc, fmt::format("SPC: {} {}", spc.lot, spc.dimension), data);
}

}  // namespace xgauge
