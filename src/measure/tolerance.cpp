#include "xgauge/measure/tolerance.h"

#include "xgauge/core/error.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/measure/job.h"

#include <cmath>

namespace xgauge {

std::string_view verdictName(Verdict verdict) {
  switch (verdict) {
    case Verdict::kConforms:
      return "conforms";
    case Verdict::kDoesNotConform:
      return "does not conform";
    case Verdict::kInconclusive:
      return "inconclusive";
  }
  return "?";
}

Decision decide(double value, double expanded_uncertainty, const Tolerance& tolerance) {
  const double u = expanded_uncertainty;
  XG_CHECK(!std::isnan(value), "a verdict on a NaN value");
  XG_CHECK(u >= 0.0, "expanded uncertainty {} is negative or NaN", u);
  XG_CHECK(tolerance.lower <= tolerance.upper, "tolerance lower {} above upper {}", tolerance.lower,
           tolerance.upper);
  const double low = tolerance.lowerLimit();
  const double high = tolerance.upperLimit();
  const double width = tolerance.width();

  Decision decision;
  decision.rule = std::string(kDecisionRule);
  decision.cannot_decide = u > width / 3.0;
  // The conformance zone [L + U, H - U] (closed) exists only while U < T / 2;
  // the nonconformance zone lies strictly outside [L - U, H + U].
  if (2.0 * u < width && value >= low + u && value <= high - u)
    decision.verdict = Verdict::kConforms;
  else if (value < low - u || value > high + u)
    decision.verdict = Verdict::kDoesNotConform;
  else
    decision.verdict = Verdict::kInconclusive;
  return decision;
}

int exitCodeFor(const std::vector<Decision>& decisions) {
  int code = kExitConforms;
  for (const Decision& decision : decisions) {
    if (decision.verdict == Verdict::kDoesNotConform) return kExitDoesNotConform;
    if (decision.verdict == Verdict::kInconclusive) code = kExitInconclusive;
  }
  return code;
}

std::map<std::string, Tolerance> tolerancesFor(const MeasurementJob& job, const PartModel& part) {
  std::map<std::string, Tolerance> out;
  for (const std::string& name : job.free_dimensions) {
    if (const auto given = job.tolerances.find(name); given != job.tolerances.end()) {
      out[name] = given->second;
      continue;
    }
    const Dimension& dimension = part.dimensions()[static_cast<size_t>(part.dimensionIndex(name))];
    if (dimension.tolerance)
      out[name] = Tolerance{dimension.nominal, dimension.tolerance->lower,
                            dimension.tolerance->upper, "part model"};
  }
  return out;
}

}  // namespace xgauge
