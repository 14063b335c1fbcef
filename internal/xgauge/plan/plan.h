// Planning the views (xgauge plan): which two or three radiographs of a part
// measure its toleranced dimensions best, predicted before a shot is taken
// (docs/method.md, "Planning the views"; the job: docs/formats.md, "Plan
// job").
//
// Every candidate view (a rotation of the part in its fixture, a stage
// position, a turntable angle) is simulated once at the part's nominal
// dimensions with a shot's noise. A set of views is then predicted two
// ways:
//   screening  each view's share of the budget's linearisation (measure/
//              prediction.h: J^T W J, the sandwich's B and every influence's
//              J^T W dr) mapped onto the set's parameters through the views'
//              poses and added up; no render per set;
//   budget     the measurement's own budget at the nominal part
//              (budgetAt): every component, the stage's and turntable's
//              included, on the set's radiographs.
// Every set is screened; the best few by the criterion, and the sets the
// job names for comparison, get the budget, and are ranked by it.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/uncertainty.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <algorithm>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

// One place to put the part: its rotation in the fixture, the stage's
// position along its axis and the turntable's angle, and the pose they give.
struct CandidateView {
  std::string name;  // "v00", ...
  Vec3 rotation_deg = Vec3::Zero();
  double stage_mm = 0.0;
  double turntable_deg = 0.0;
  Pose pose;
};

// What ranks the sets: the largest U/T over the toleranced dimensions, their
// sum, or one dimension's U.
enum class PlanCriterion { kWorst, kSum, kDimension };

struct PlanJob {
  std::filesystem::path file;
  std::string description;
  // The measurement job the sets are measured with, without radiographs
  // (paths made absolute); its inputs read once.
  nlohmann::json job;
  MeasurementInputs inputs;
  std::map<std::string, Tolerance> tolerances;  // of the free dimensions
  std::map<std::string, double> nominal;        // the part's values the views are simulated at
  // The shot's noise: the relative standard deviation of one open-beam
  // pixel of the normalized radiograph; a pixel of intensity I has
  // sqrt(open^2 I + floor^2).
  double open_beam_noise = 0.0;
  double noise_floor = 0.0;
  Vec3 stage_axis = Vec3::UnitX();
  // The stage's positioning and the turntable's angle, standard
  // uncertainties (the measurement's defaults when not stated).
  std::optional<double> stage_uncertainty_mm, turn_uncertainty_deg;
  std::vector<CandidateView> views;
  int per_set = 2;
  PlanCriterion criterion = PlanCriterion::kWorst;
  std::string criterion_dimension;
  int budgeted = 8;  // best screened sets given the budget
  // Only sets whose every view after the first is a known move of it
  // (translated or turned): their scale is the stage's or the turntable's,
  // not the material curve's, which two free views rest on ("sets":
  // "known_moves"; default "any").
  bool known_moves_only = false;
  // Every set is screened up to this many; beyond, local exchange from
  // seeded starts.
  int64_t exhaustive_up_to = 20000;
  // Sets always given the budget and shown beside the best (the lab's usual
  // pair, say): indices into views.
  std::vector<std::vector<int>> compare;
  uint64_t seed = 1;

  // Reads and checks the plan file and everything it names; Error naming
  // the file and key of the first problem.
  static PlanJob load(const std::filesystem::path& path);
};

struct PredictedDimension {
  std::string name;
  double expanded = 0.0;  // U (k = 2), mm or deg
  bool identifiable = true;
  std::optional<double> tolerance_width;  // T
  // U / T where toleranced (+inf when not identifiable).
  std::optional<double> u_over_t() const;
};

struct PredictedSet {
  std::vector<int> views;             // indices into PlanJob::views, in shot order
  std::vector<std::string> patterns;  // per view: free, translated, turned
  // Every view after the first placed anew: nothing but the material's
  // curve sets the part's distance from the source, so its scale.
  bool scale_from_curve() const {
    return std::all_of(patterns.begin() + 1, patterns.end(),
                       [](const std::string& p) { return p == "free"; });
  }
  std::vector<PredictedDimension> dimensions;
  double score = 0.0;  // the criterion (lower is better; +inf: not every dimension determined)
  bool budgeted = false;
  std::optional<UncertaintyBudget> budget;  // when budgeted
  // A budgeted set whose budget propagated every influence; one that had to
  // leave one out (UncertaintyBudget::unpropagated: a shift that did not
  // settle, as the source-detector distance of two free views whose scale
  // only the curve sets) states a U smaller than it should be, and ranks
  // after every complete set.
  bool complete() const { return budget && budget->unpropagated.empty(); }
  // The views whose paths through the part run beyond the material's
  // calibrated range (by more than the measurement's 1 %), with their
  // longest path: the curve is extrapolated there, the model may not fit
  // and U does not say by how much. Such a set ranks after every set
  // within the range (and before every incomplete one).
  std::vector<std::pair<std::string, double>> beyond_range;
  std::vector<PredictedDimension> screened;  // a budgeted set's screening, for comparison
};

struct PlanResult {
  std::string search;   // how the sets were searched, in words
  int64_t screened = 0;  // sets screened
  // The budgeted sets (the compared ones among them) first: complete and
  // within the calibrated range, complete and beyond it, incomplete; each
  // by score. Then the screened ones by score.
  std::vector<PredictedSet> ranked;
  std::vector<PredictedSet> compared;  // the job's compare sets, budgeted
  std::vector<Image> view_images;      // each view's simulated radiograph (full size)
  std::vector<PixelRect> white_regions;  // each view's open-beam corner
  double seconds = 0.0;  // in all; of it:
  double views_seconds = 0.0, screening_seconds = 0.0, budget_seconds = 0.0;
};

// Screens the candidate sets, budgets the best and the compared ones.
PlanResult planViews(const PlanJob& job);

// The measurement job of a set: the plan's job with one radiograph per view
// (image "<view>.tif", its pattern and reference), for a lab to fill in.
nlohmann::json measurementJobFor(const PlanJob& job, const PlanResult& result,
                                 const std::vector<int>& views);

// plan.json, job.json (the best set's measurement job) and report.html into
// `folder` (created; every file written atomically).
void writePlan(const PlanJob& job, const PlanResult& result, const std::filesystem::path& folder);

// The criterion's value for a set's dimensions.
double criterionOf(const PlanJob& job, const std::vector<PredictedDimension>& dimensions);

}  // namespace xgauge
