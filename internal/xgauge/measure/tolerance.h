// Tolerances and conformity verdicts by the default decision rule of
// ISO 14253-1 (decision rules for verifying conformity with specifications),
// and the exit status of `xgauge measure` that a line script reads.
//
// A tolerance comes from the part model (a dimension's "tolerance": the
// drawing's default, geometry/part_model.h) or from the job ("tolerances",
// measure/job.h), which overrides the part model's per dimension so that one
// part model serves several inspection plans. Every key is documented in
// docs/formats.md.
//
// The rule (ISO 14253-1, the default "guard band = U" rule). With the
// specification zone [L, H] = [nominal + lower, nominal + upper], its width
// T = upper - lower and the expanded uncertainty U (k = 2) of the value y:
//
//   conforms          L + U <= y <= H - U, and U < T / 2
//   does not conform  y < L - U  or  y > H + U
//   inconclusive      otherwise
//
// Boundary cases, decided here once:
// - The specification zone includes its limits (U = 0: y = H conforms), so
//   the conformance zone [L + U, H - U] is closed too: a value exactly on a
//   shrunk limit conforms.
// - The nonconformance zone is open: a value exactly on a widened limit
//   (y = H + U) is inconclusive, not nonconforming. With U = 0 the two
//   zones meet and no value is inconclusive.
// - When U >= T / 2 the conformance zone is empty (at U = T / 2 it would be
//   the single point y = nominal + (lower + upper) / 2; it is treated as
//   empty): no value conforms, however close to the middle.
// - U = +infinity (no uncertainty could be given) makes every value
//   inconclusive.
// - Limits are compared in double precision, after adding the deviations to
//   the nominal: a value that equals a limit only in decimal may fall on
//   either side of it by one rounding (1e-15 mm); the printed values round
//   far coarser than that.
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

class PartModel;
struct MeasurementJob;

// A dimension's specification: the deviation limits [lower, upper] from
// `nominal`, all in the dimension's unit (mm or deg). lower < upper; the zone
// may lie on one side of the nominal (both limits of one sign), asymmetric
// zones are allowed.
struct Tolerance {
  double nominal = 0.0;
  double lower = 0.0;  // e.g. -0.05
  double upper = 0.0;  // e.g. +0.05
  std::string source;  // where it was given, for the output: "job" or "part model"

  double lowerLimit() const { return nominal + lower; }  // L
  double upperLimit() const { return nominal + upper; }  // H
  double width() const { return upper - lower; }         // T
};

enum class Verdict { kConforms, kDoesNotConform, kInconclusive };

// "conforms", "does not conform", "inconclusive".
std::string_view verdictName(Verdict verdict);

// The rule in one sentence, as written in results and tables.
inline constexpr std::string_view kDecisionRule =
    "ISO 14253-1 default rule: a value conforms when it lies inside the tolerance zone shrunk by "
    "the expanded uncertainty U at both ends, does not conform when it lies outside the zone "
    "widened by U, and is inconclusive otherwise";

struct Decision {
  Verdict verdict = Verdict::kInconclusive;
  // U > T / 3 (strictly): the measurement is too uncertain for this
  // tolerance to decide reliably; a warning in the output whatever the
  // verdict. Exactly U = T / 3 is not flagged.
  bool cannot_decide = false;
  std::string rule;  // kDecisionRule
  // Why it cannot decide where the model discrepancy alone makes it so (U
  // without that component would be at most T / 3): names the residual
  // regions where the part differs from its model; empty otherwise.
  std::string cannot_decide_reason;
};

// The verdict on a measured `value` with expanded uncertainty
// `expanded_uncertainty` (U, k = 2, >= 0, may be +infinity), in the
// tolerance's unit, by the rule above. A NaN value or a negative or NaN U is
// a broken invariant (XG_CHECK), as is lower > upper.
Decision decide(double value, double expanded_uncertainty, const Tolerance& tolerance);

// Exit status of `xgauge measure` (apps/xgauge), documented in
// docs/formats.md. A script tells "measured, all conform" from "measured,
// something is inconclusive or does not conform" from "could not measure".
// Arguments the command line parser refuses exit with its own codes (>= 100),
// and a signal ends the process with 128 + its number (core/output.h).
inline constexpr int kExitConforms = 0;         // measured; every toleranced dimension conforms,
                                                // or none has a tolerance
inline constexpr int kExitCouldNotMeasure = 1;  // any error: bad input, a failed fit, ...
inline constexpr int kExitInconclusive = 2;     // measured; some verdict inconclusive, none
                                                // "does not conform"
inline constexpr int kExitDoesNotConform = 3;   // measured; some dimension does not conform

// kExitDoesNotConform if any decision does not conform, else
// kExitInconclusive if any is inconclusive, else kExitConforms (also for
// none). cannot_decide does not change the code: it is a warning.
int exitCodeFor(const std::vector<Decision>& decisions);

// The tolerance of every free (measured) dimension that has one, by name:
// the part model's default (source "part model", nominal = the dimension's
// nominal) replaced by the job's where the job gives one (source "job").
// Fixed dimensions are not measured and get none, even with a default.
std::map<std::string, Tolerance> tolerancesFor(const MeasurementJob& job, const PartModel& part);

}  // namespace xgauge
