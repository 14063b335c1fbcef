// SPC over a lot in the results store: one analysis per dimension (the
// series in production order, limits from a phase-I baseline, the rules'
// hits, capability, U against the tolerance) and its page, a
// self-contained report.html kind "spc" drawn by src/report/web/spc.js
// with the reports' machinery (report/html.h). docs/formats.md, "SPC page".
#pragma once

#include "xgauge/production/spc.h"
#include "xgauge/production/store.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct SpcOptions {
  // Phase I: the first `baseline_parts` measured parts of the lot, or, when
  // `baseline_lot` is given, every measured part of that lot.
  // A dimension with fewer measured values than `baseline_parts` is refused
  // (Error naming the lot, the parts present and the baseline asked), or,
  // with `skip_short_baseline`, left out (phase I not complete yet).
  size_t baseline_parts = 30;
  bool skip_short_baseline = false;
  std::string baseline_lot;
  std::vector<SpcRule> rules = allRules();
  double confidence = 0.95;
};

struct DimensionSpc {
  std::string lot, dimension, unit;
  std::vector<std::string> parts;  // production order, measured parts only
  std::vector<double> values;
  std::vector<std::optional<double>> expanded_uncertainty;
  std::string baseline;  // "first 30 parts" or "lot L0"
  ControlLimits limits;
  std::vector<RuleHit> hits;  // first of each run
  std::optional<double> nominal, lsl, usl;
  std::optional<Capability> capability;  // with both limits
  // The baseline's mean U over the tolerance zone's width; a warning above 1/3.
  std::optional<double> u_over_t;

  nlohmann::json toJson() const;
};

// Every dimension of `lot` that has a value in at least two parts. Error
// when the lot is unknown, the baseline has fewer than 2 parts, or (without
// skip_short_baseline) fewer than baseline_parts.
std::vector<DimensionSpc> analyseLot(ResultStore& store, const std::string& lot,
                                     const SpcOptions& options);

// The alarms of an analysis, for the store and stdout.
std::vector<StoredAlarm> alarmsOf(const DimensionSpc& spc, const std::string& raised_at);
// "ALARM lot width nelson-2 p0128 (#128) 21.0093: nine points in a row ..."
std::string alarmLine(const StoredAlarm& alarm);

// The page, written atomically.
void writeSpcPage(const std::filesystem::path& path, const DimensionSpc& spc);

}  // namespace xgauge
