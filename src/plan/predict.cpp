// The sets of views screened, searched, budgeted and ranked (plan.h).
#include "views.h"

#include "xgauge/measure/self_check.h"

#include "xgauge/core/progress.h"
#include "xgauge/lab/random.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <tuple>

namespace xgauge {

namespace pi = plan_internal;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDegToRadPlan = 3.14159265358979323846 / 180.0;
// Beyond PlanJob::exhaustive_up_to sets, local exchange from this many
// seeded starts.
constexpr int kStarts = 64;
constexpr double kPoseStep = 1e-5;  // deg or mm: the chain rule's central differences

Vec3 axisFromAngles(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kDegToRadPlan, el = elevation_deg * kDegToRadPlan;
  return {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
}

// A set's parameters as the measurement lays them out (model_parameters.cpp):
// the free dimensions, then per view its free pose (rotation, centre), a
// translated view's axis (azimuth, elevation) or nothing (turned). Fixed
// pose parameters (equal bounds) are left out.
struct SetLayout {
  std::vector<std::string> names;  // "dim/<d>", "<view>/rotation/rx", ...
  std::vector<double> values;      // at the nominal part
  std::vector<pi::Relation> relations;
};

// The free parameters of a view's pose (ForwardModel's "free" pattern):
// Euler angles (deg) and the reference centre's world position (mm).
using Xi = Eigen::Matrix<double, 6, 1>;
Xi xiOf(const Pose& pose, const Vec3& centre) {
  const Vec3 e = pose.eulerDeg(), c = pose.apply(centre);
  Xi xi;
  xi << e[0], e[1], e[2], c[0], c[1], c[2];
  return xi;
}
Pose poseOf(const double* xi, const Vec3& centre) {
  Pose p = Pose::fromEulerDeg(Vec3(xi[0], xi[1], xi[2]), Vec3::Zero());
  p.translation_mm = Vec3(xi[3], xi[4], xi[5]) - p.rotation * centre;
  return p;
}

class Screening {
 public:
  Screening(const PlanJob& job, const std::vector<pi::SimulatedView>& views)
      : job_(job), views_(views) {
    const BoundingBox box = boundingBox(job.inputs.part->mesh(job.inputs.part->nominalValues()));
    centre_ = 0.5 * (box.min_mm + box.max_mm);
    for (const std::string& d : job.inputs.job.free_dimensions) dims_.push_back("dim/" + d);
    // The influences every view has, in the first view's order, but those
    // the budget does not take linearised: their one linearised step
    // overshoots along weakly determined directions (on the bracket's
    // translated pairs up to 50 times the budget's U), where leaving them
    // out keeps the screening near or below the budget, so that a good set
    // is budgeted and an overrated one falls in the budget's ranking.
    const ViewInformation& first = views.front().information;
    for (size_t k = 0; k < first.influences.size(); ++k) {
      if (first.iterated[k]) continue;
      const std::string& f = first.influences[k];
      bool everywhere = true;
      for (const auto& v : views)
        everywhere &= std::find(v.information.influences.begin(), v.information.influences.end(),
                                f) != v.information.influences.end();
      if (everywhere) influences_.push_back(f);
    }
  }

  std::vector<PredictedDimension> predict(const std::vector<int>& set) const {
    const SetLayout layout = layoutOf(set);
    const auto n = static_cast<Eigen::Index>(layout.names.size());
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n), b = Eigen::MatrixXd::Zero(n, n);
    Eigen::MatrixXd vertices = Eigen::MatrixXd::Zero(n, n);
    std::vector<Eigen::VectorXd> g(influences_.size(), Eigen::VectorXd::Zero(n));
    for (size_t r = 0; r < set.size(); ++r) {
      const ViewInformation& info = views_[static_cast<size_t>(set[r])].information;
      const Eigen::MatrixXd map = chain(layout, set, r, info);
      a += map.transpose() * info.a * map;
      b += map.transpose() * info.b * map;
      vertices += map.transpose() * info.vertex_normal * map;
      for (size_t f = 0; f < influences_.size(); ++f) {
        const auto column = std::find(info.influences.begin(), info.influences.end(),
                                      influences_[f]) - info.influences.begin();
        g[f] += map.transpose() * info.g.col(column);
      }
      // The stage's or the turntable's move of this view, off by its
      // standard uncertainty: the view's pose moves, its residuals by J
      // times that, so J^T W dr = A_v times the pose's move.
      if (const std::optional<Eigen::VectorXd> move = poseMove(layout, set, r, info))
        g.push_back(map.transpose() * (info.a * *move));
    }
    // As the budget: the directions that move no vertex in any view out.
    const Eigen::MatrixXd unseen = budgetGeometricNullSpace(vertices);
    Eigen::MatrixXd project = Eigen::MatrixXd::Identity(n, n);
    if (unseen.cols() > 0) {
      project -= unseen * unseen.transpose();
      a = project * a * project;
      b = project * b * project;
    }
    std::vector<Eigen::VectorXd> null;
    const Eigen::MatrixXd inverse = budgetPseudoInverse(a, null);
    Eigen::MatrixXd covariance = inverse * b * inverse;
    for (const Eigen::VectorXd& column : g) {
      const Eigen::VectorXd shift = -(inverse * (project * column));
      covariance += shift * shift.transpose();
    }
    std::vector<PredictedDimension> out;
    for (size_t d = 0; d < dims_.size(); ++d) {
      PredictedDimension p;
      p.name = job_.inputs.job.free_dimensions[d];
      const auto c = static_cast<Eigen::Index>(d);
      for (const Eigen::VectorXd& v : null) p.identifiable &= std::abs(v(c)) < 1e-3;
      p.expanded = p.identifiable ? 2.0 * std::sqrt(std::max(0.0, covariance(c, c))) : 0.0;
      if (auto t = job_.tolerances.find(p.name); t != job_.tolerances.end())
        p.tolerance_width = t->second.width();
      out.push_back(std::move(p));
    }
    return out;
  }

 private:
  bool freeRange(const std::array<double, 2>& range) const { return range[0] < range[1]; }

  // A translated or turned view's pose moved by the stage's or turntable's
  // standard uncertainty, in the view's own columns (Xi components; zero for
  // the dimensions); nullopt for a free view.
  std::optional<Eigen::VectorXd> poseMove(const SetLayout& layout, const std::vector<int>& set,
                                          size_t r, const ViewInformation& info) const {
    const pi::Relation& rel = layout.relations[r];
    if (rel.pattern == Acquisition::kFree) return std::nullopt;
    const Pose at = poseAt(layout, set, r, layout.values);
    Pose moved = at;
    if (rel.pattern == Acquisition::kTranslated) {
      moved.translation_mm += job_.stage_uncertainty_mm.value_or(kDefaultTranslationUncertaintyMm) *
                              rel.direction;
    } else {
      const Pose first = poseAt(layout, set, 0, layout.values);
      moved = job_.inputs.machine.turntable->turn(
          first, rel.angle_deg + job_.turn_uncertainty_deg.value_or(kDefaultTurnUncertaintyDeg));
    }
    const Xi change = xiOf(moved, centre_) - xiOf(at, centre_);
    static const char* kComponents[6] = {"/rotation/rx", "/rotation/ry", "/rotation/rz",
                                         "/position/x",  "/position/y",  "/position/z"};
    const std::string& view = job_.views[static_cast<size_t>(set[r])].name;
    Eigen::VectorXd e = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(info.names.size()));
    for (size_t i = 0; i < info.names.size(); ++i)
      for (int k = 0; k < 6; ++k)
        if (info.names[i] == view + kComponents[k]) e(static_cast<Eigen::Index>(i)) = change(k);
    return e;
  }

  SetLayout layoutOf(const std::vector<int>& set) const {
    SetLayout out;
    for (size_t d = 0; d < dims_.size(); ++d) {
      out.names.push_back(dims_[d]);
      out.values.push_back(job_.nominal.at(job_.inputs.job.free_dimensions[d]));
    }
    const MeasurementJob& mj = job_.inputs.job;
    for (size_t r = 0; r < set.size(); ++r) {
      const CandidateView& v = job_.views[static_cast<size_t>(set[r])];
      const pi::Relation rel = r == 0 ? pi::Relation{} : pi::relationOf(job_, set[0], set[r]);
      out.relations.push_back(rel);
      if (rel.pattern == Acquisition::kFree) {
        const Xi xi = xiOf(v.pose, centre_);
        static const char* kNames[6] = {"rotation/rx", "rotation/ry", "rotation/rz",
                                        "position/x",  "position/y",  "position/z"};
        for (int k = 0; k < 6; ++k) {
          const auto& range = k < 3 ? mj.rotation_bounds_deg[static_cast<size_t>(k)]
                                    : mj.centre_bounds_mm[static_cast<size_t>(k - 3)];
          if (!freeRange(range)) continue;
          out.names.push_back(v.name + "/" + kNames[k]);
          out.values.push_back(xi(k));
        }
      } else if (rel.pattern == Acquisition::kTranslated) {
        out.names.push_back(v.name + "/axis/azimuth");
        out.values.push_back(std::atan2(rel.direction.z(), rel.direction.x()) / kDegToRadPlan);
        out.names.push_back(v.name + "/axis/elevation");
        out.values.push_back(std::asin(std::clamp(rel.direction.y(), -1.0, 1.0)) / kDegToRadPlan);
      }
    }
    return out;
  }

  // The pose of view r of the set at the set's parameters `s`.
  Pose poseAt(const SetLayout& layout, const std::vector<int>& set, size_t r,
              const std::vector<double>& s) const {
    const auto value = [&](const std::string& name, double fallback) {
      const auto it = std::find(layout.names.begin(), layout.names.end(), name);
      return it == layout.names.end() ? fallback : s[static_cast<size_t>(it - layout.names.begin())];
    };
    const auto freePose = [&](size_t k) {
      const CandidateView& v = job_.views[static_cast<size_t>(set[k])];
      const Xi nominal = xiOf(v.pose, centre_);
      static const char* kNames[6] = {"rotation/rx", "rotation/ry", "rotation/rz",
                                      "position/x",  "position/y",  "position/z"};
      double xi[6];
      for (int i = 0; i < 6; ++i) xi[i] = value(v.name + "/" + kNames[i], nominal(i));
      return poseOf(xi, centre_);
    };
    const pi::Relation& rel = layout.relations[r];
    if (rel.pattern == Acquisition::kFree) return freePose(r);
    Pose first = freePose(0);
    if (rel.pattern == Acquisition::kTurned) return job_.inputs.machine.turntable->turn(first, rel.angle_deg);
    const std::string& name = job_.views[static_cast<size_t>(set[r])].name;
    first.translation_mm +=
        rel.distance_mm * axisFromAngles(value(name + "/axis/azimuth", 0.0),
                                         value(name + "/axis/elevation", 0.0));
    return first;
  }

  // d(view r's own parameters, as `info` lists them) / d(the set's), by the
  // chain rule through the view's pose (central differences of the poses;
  // no render).
  Eigen::MatrixXd chain(const SetLayout& layout, const std::vector<int>& set, size_t r,
                        const ViewInformation& info) const {
    const auto rows = static_cast<Eigen::Index>(info.names.size());
    const auto cols = static_cast<Eigen::Index>(layout.names.size());
    Eigen::MatrixXd map = Eigen::MatrixXd::Zero(rows, cols);
    // Each of the view's pose components (Xi order) that it has as a column.
    static const char* kComponents[6] = {"/rotation/rx", "/rotation/ry", "/rotation/rz",
                                         "/position/x",  "/position/y",  "/position/z"};
    const std::string& view = job_.views[static_cast<size_t>(set[r])].name;
    std::vector<std::pair<Eigen::Index, int>> pose_rows;
    for (Eigen::Index i = 0; i < rows; ++i) {
      const std::string& name = info.names[static_cast<size_t>(i)];
      const auto same = std::find(layout.names.begin(), layout.names.end(), name);
      if (name.starts_with("dim/") && same != layout.names.end())
        map(i, same - layout.names.begin()) = 1.0;
      for (int k = 0; k < 6; ++k)
        if (name == view + kComponents[k]) pose_rows.emplace_back(i, k);
    }
    std::vector<double> s = layout.values;
    for (Eigen::Index c = 0; c < cols; ++c) {
      if (layout.names[static_cast<size_t>(c)].starts_with("dim/")) continue;
      const double keep = s[static_cast<size_t>(c)];
      s[static_cast<size_t>(c)] = keep + kPoseStep;
      const Xi plus = xiOf(poseAt(layout, set, r, s), centre_);
      s[static_cast<size_t>(c)] = keep - kPoseStep;
      const Xi minus = xiOf(poseAt(layout, set, r, s), centre_);
      s[static_cast<size_t>(c)] = keep;
      for (const auto& [i, k] : pose_rows) map(i, c) = (plus(k) - minus(k)) / (2.0 * kPoseStep);
    }
    return map;
  }

  const PlanJob& job_;
  const std::vector<pi::SimulatedView>& views_;
  Vec3 centre_;
  std::vector<std::string> dims_, influences_;
};

// The patterns of a set's views, as the measurement job names them.
std::vector<std::string> patternsOf(const PlanJob& job, const std::vector<int>& set) {
  std::vector<std::string> out{"free"};
  for (size_t k = 1; k < set.size(); ++k)
    out.emplace_back(acquisitionName(pi::relationOf(job, set[0], set[k]).pattern));
  return out;
}

// Whether the job's "sets" admits the set (its views in shot order).
bool admitted(const PlanJob& job, const std::vector<int>& set) {
  if (!job.known_moves_only) return true;
  for (size_t k = 1; k < set.size(); ++k)
    if (pi::relationOf(job, set[0], set[k]).pattern == Acquisition::kFree) return false;
  return true;
}

int64_t combinations(int n, int k) {
  int64_t c = 1;
  for (int i = 0; i < k; ++i) c = c * (n - i) / (i + 1);
  return c;
}

// Every k-subset of 0 .. n-1 in lexicographic order.
void forEachCombination(int n, int k, const std::function<void(const std::vector<int>&)>& visit) {
  std::vector<int> set(static_cast<size_t>(k));
  for (int i = 0; i < k; ++i) set[static_cast<size_t>(i)] = i;
  while (true) {
    visit(set);
    int i = k - 1;
    while (i >= 0 && set[static_cast<size_t>(i)] == n - k + i) --i;
    if (i < 0) return;
    ++set[static_cast<size_t>(i)];
    for (int j = i + 1; j < k; ++j) set[static_cast<size_t>(j)] = set[static_cast<size_t>(j - 1)] + 1;
  }
}

struct Screened {
  std::map<std::vector<int>, std::vector<PredictedDimension>> sets;
  double scoreOf(const PlanJob& job, const std::vector<int>& set) const {
    return criterionOf(job, sets.at(set));
  }
};

// Local exchange from `start`: swap one view for any other while that lowers
// the criterion (best swap first).
void exchange(const PlanJob& job, const Screening& screening, std::vector<int> set, Screened& out) {
  const int n = static_cast<int>(job.views.size());
  const auto screen = [&](std::vector<int> s) {
    std::sort(s.begin(), s.end());
    if (!admitted(job, s)) return std::pair{kInf, s};
    if (!out.sets.contains(s)) out.sets[s] = screening.predict(s);
    return std::pair{criterionOf(job, out.sets[s]), s};
  };
  auto [best, best_set] = screen(set);
  for (bool improved = true; improved;) {
    improved = false;
    for (size_t k = 0; k < best_set.size(); ++k)
      for (int v = 0; v < n; ++v) {
        if (std::find(best_set.begin(), best_set.end(), v) != best_set.end()) continue;
        std::vector<int> trial = best_set;
        trial[k] = v;
        auto [score, sorted] = screen(trial);
        if (score < best) best = score, best_set = sorted, improved = true;
      }
  }
}

// The views of `set` whose longest path runs beyond the material's
// calibrated range (by more than kBeyondRange).
std::vector<std::pair<std::string, double>> beyondRange(const PlanJob& job,
                                                        const std::vector<pi::SimulatedView>& views,
                                                        const std::vector<int>& set) {
  std::vector<std::pair<std::string, double>> out;
  const auto& range = job.inputs.material->calibratedRange();
  if (!range) return out;
  for (int v : set) {
    const double longest = views[static_cast<size_t>(v)].longest_path_mm;
    if (longest > (*range)[1] * (1.0 + kBeyondRange))
      out.emplace_back(job.views[static_cast<size_t>(v)].name, longest);
  }
  return out;
}

PredictedSet budgetSet(const PlanJob& job, const std::vector<pi::SimulatedView>& views,
                       const std::vector<int>& set) {
  PredictedSet out;
  out.views = set;
  out.patterns = patternsOf(job, set);
  out.beyond_range = beyondRange(job, views, set);
  MeasurementInputs inputs = pi::inputsFor(job, set, views);
  ForwardModel model(inputs);
  const std::vector<double> theta = pi::nominalTheta(job, model, set);
  std::optional<UncertaintyBudget> budget = budgetAt(model, theta);
  if (!budget) fail("the set {} could not be simulated at the nominal part", fmt::join(set, ", "));
  for (const DimensionUncertainty& d : budget->dimensions) {
    PredictedDimension p;
    p.name = d.name, p.expanded = d.expanded, p.identifiable = d.identifiable;
    if (auto t = job.tolerances.find(d.name); t != job.tolerances.end())
      p.tolerance_width = t->second.width();
    out.dimensions.push_back(std::move(p));
  }
  out.score = criterionOf(job, out.dimensions);
  out.budgeted = true;
  out.budget = std::move(budget);
  return out;
}

}  // namespace

std::optional<double> PredictedDimension::u_over_t() const {
  if (!tolerance_width) return std::nullopt;
  return identifiable ? expanded / *tolerance_width : kInf;
}

double criterionOf(const PlanJob& job, const std::vector<PredictedDimension>& dimensions) {
  double worst = 0.0, sum = 0.0;
  for (const PredictedDimension& d : dimensions) {
    if (job.criterion == PlanCriterion::kDimension) {
      if (d.name == job.criterion_dimension) return d.identifiable ? d.expanded : kInf;
      continue;
    }
    const std::optional<double> r = d.u_over_t();
    if (!r) continue;
    worst = std::max(worst, *r), sum += *r;
  }
  return job.criterion == PlanCriterion::kSum ? sum : worst;
}

namespace {

// Each view on its own core (a render's rows are parallel too, but its
// Jacobian's columns and the influences' renders are small at 1024^2);
// each view's noise is its own stream, so the result does not depend on
// the thread count.
std::vector<pi::SimulatedView> simulateViews(const PlanJob& job) {
  std::vector<pi::SimulatedView> views(job.views.size());
  ProgressBar bar("plan: simulating the views", static_cast<int64_t>(job.views.size()));
  tbb::parallel_for(0, static_cast<int>(job.views.size()), [&](int v) {
    views[static_cast<size_t>(v)] = pi::simulateView(job, v);
    bar.advance();
  });
  return views;
}

// Every admitted set screened, or local exchange from seeded starts (the
// job's compare sets among them) beyond exhaustive_up_to; how, in words.
std::string searchSets(const PlanJob& job, const Screening& screening, Screened& screened) {
  const int n = static_cast<int>(job.views.size());
  const int64_t all = combinations(n, job.per_set);
  std::string search;
  if (all <= job.exhaustive_up_to) {
    forEachCombination(n, job.per_set, [&](const std::vector<int>& set) {
      if (admitted(job, set)) screened.sets[set] = screening.predict(set);
    });
    search = job.known_moves_only
                 ? fmt::format("every one of the {} sets of known moves among the {} sets of {} "
                               "of the {} views screened",
                               screened.sets.size(), all, job.per_set, n)
                 : fmt::format("every one of the {} sets of {} of the {} views screened", all,
                               job.per_set, n);
  } else {
    std::vector<std::vector<int>> starts = job.compare;
    SplitMix64 stream = SplitMix64::stream(job.seed, 0x706c616e73746172ULL);
    const int64_t starts_wanted = std::min<int64_t>(kStarts, all);
    while (static_cast<int64_t>(starts.size()) < starts_wanted) {
      std::set<int> s;
      while (static_cast<int>(s.size()) < job.per_set)
        s.insert(static_cast<int>(stream() % static_cast<uint64_t>(n)));
      starts.emplace_back(s.begin(), s.end());
    }
    for (const auto& s : starts) exchange(job, screening, s, screened);
    search = fmt::format(
        "{} sets of {} of the {} views ({} combinations): local exchange of one view at a time "
        "from {} seeded starts, {} sets screened",
        job.per_set, job.per_set, n, all, starts.size(), screened.sets.size());
  }
  if (screened.sets.empty())
    fail("{}: no set of the {} candidate views is a set of known moves (\"sets\": "
         "\"known_moves\": every view after a set's first must be a stage move or a turntable turn "
         "of it, from the same fixture rotation)",
         job.file.string(), n);
  return search;
}

// The screened sets by score.
std::vector<PredictedSet> rankScreened(const PlanJob& job,
                                       const std::vector<pi::SimulatedView>& views,
                                       const Screened& screened) {
  std::vector<PredictedSet> ranked;
  for (const auto& [set, dims] : screened.sets) {
    PredictedSet p;
    p.views = set, p.patterns = patternsOf(job, set), p.dimensions = dims;
    p.beyond_range = beyondRange(job, views, set);
    p.score = criterionOf(job, dims);
    ranked.push_back(std::move(p));
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const PredictedSet& a, const PredictedSet& b) { return a.score < b.score; });
  return ranked;
}

// The best `job.budgeted` of `ranked` and the compared sets given the
// measurement's budget (one set per core), the compared ones joining the
// ranking unless the same views in the same order are there; the budgeted
// sets then lead it: complete budgets before those known to be too small,
// within each views inside the calibrated range before those beyond it,
// then by score. Returns how many lead.
int budgetBest(const PlanJob& job, const std::vector<pi::SimulatedView>& views,
               const Screening& screening, std::vector<PredictedSet>& ranked,
               std::vector<PredictedSet>& compared) {
  int budgeted = std::min(job.budgeted, static_cast<int>(ranked.size()));
  ProgressBar bar("plan: budgets of the best sets",
                  budgeted + static_cast<int64_t>(job.compare.size()));
  compared.resize(job.compare.size());
  tbb::parallel_for(0, budgeted + static_cast<int>(job.compare.size()), [&](int k) {
    if (k < budgeted) {
      PredictedSet& set = ranked[static_cast<size_t>(k)];
      std::vector<PredictedDimension> screened_dimensions = std::move(set.dimensions);
      set = budgetSet(job, views, set.views);
      set.screened = std::move(screened_dimensions);
    } else {
      const std::vector<int>& views_of = job.compare[static_cast<size_t>(k - budgeted)];
      PredictedSet& set = compared[static_cast<size_t>(k - budgeted)];
      set = budgetSet(job, views, views_of);
      set.screened = screening.predict(views_of);
    }
    bar.advance();
  });
  for (const PredictedSet& c : compared)
    if (std::none_of(ranked.begin(), ranked.begin() + budgeted,
                     [&](const PredictedSet& s) { return s.views == c.views; })) {
      std::erase_if(ranked, [&](const PredictedSet& s) { return !s.budgeted && s.views == c.views; });
      ranked.insert(ranked.begin() + budgeted, c);
      ++budgeted;
    }
  std::stable_sort(ranked.begin(), ranked.begin() + budgeted,
                   [](const PredictedSet& a, const PredictedSet& b) {
                     const auto rank = [](const PredictedSet& s) {
                       return std::tuple{!s.complete(), !s.beyond_range.empty(), s.score};
                     };
                     return rank(a) < rank(b);
                   });
  return budgeted;
}

double secondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

PlanResult planViews(const PlanJob& job) {
  const auto start = std::chrono::steady_clock::now();
  PlanResult result;
  const std::vector<pi::SimulatedView> views = simulateViews(job);
  for (const auto& v : views) {
    result.view_images.push_back(v.image);
    result.white_regions.push_back(v.white_region);
  }
  result.views_seconds = secondsSince(start);

  const auto screening_start = std::chrono::steady_clock::now();
  const Screening screening(job, views);
  Screened screened;
  result.search = searchSets(job, screening, screened);
  result.screened = static_cast<int64_t>(screened.sets.size());
  std::vector<PredictedSet> ranked = rankScreened(job, views, screened);
  result.screening_seconds = secondsSince(screening_start);

  const auto budget_start = std::chrono::steady_clock::now();
  const int budgeted = budgetBest(job, views, screening, ranked, result.compared);
  result.ranked = std::move(ranked);
  result.budget_seconds = secondsSince(budget_start);
  result.seconds = secondsSince(start);
  spdlog::info("plan: {} candidate views, {}; {} budgeted, in {:.1f} s", job.views.size(),
               result.search, budgeted, result.seconds);
  return result;
}

}  // namespace xgauge
