// The budget where a fit ends and one view's share of its linearisation
// (measure/prediction.h), from the budget's own steps (budget_internal.h).
#include "xgauge/measure/prediction.h"

#include "budget.h"
#include "budget_internal.h"
#include "stages.h"

#include "xgauge/measure/schedule.h"

#include <spdlog/spdlog.h>

namespace xgauge {

namespace {

// The linearisation measure() takes after its fit: the least-squares stage's
// level, point samples and edge samples.
std::optional<LinearizedFit> linearizeAsMeasured(ForwardModel& model,
                                                 std::span<const double> theta) {
  const Schedule& schedule = scheduleFor(model.job().schedule);
  const LeastSquaresStage ls = leastSquaresStage(model, schedule);
  if (ls.enabled) model.setEdgeSamples(ls.edge_samples);
  std::vector<int> radiographs;
  for (int r = 0; r < model.radiographCount(); ++r) radiographs.push_back(r);
  LinearizedFit fit;
  if (!linearize(model, theta, model.leastSquaresIndices(), radiographs,
                 leastSquaresLevel(model, schedule), ls.samples,
                 model.job().loss == LossKind::kMeanAbsolute, fit))
    return std::nullopt;
  return fit;
}

}  // namespace

Image simulatedShot(ForwardModel& model, std::span<const double> theta, int radiograph) {
  const LeastSquaresStage ls = leastSquaresStage(model, scheduleFor(model.job().schedule));
  if (ls.enabled) model.setEdgeSamples(ls.edge_samples);
  return model.simulate(theta, radiograph, 0, ls.samples, model.machine().detectorRect());
}

std::optional<UncertaintyBudget> budgetAt(ForwardModel& model, std::span<const double> theta) {
  const std::optional<LinearizedFit> fit = linearizeAsMeasured(model, theta);
  if (!fit) return std::nullopt;
  return estimateUncertainty(model, theta, *fit);
}

std::optional<ViewInformation> viewInformationAt(ForwardModel& model,
                                                 std::span<const double> theta) {
  namespace bi = budget_internal;
  XG_CHECK(model.radiographCount() == 1, "a view's information is one radiograph's");
  const std::optional<LinearizedFit> fit = linearizeAsMeasured(model, theta);
  if (!fit) return std::nullopt;
  ViewInformation out;
  for (int i : fit->indices) out.names.push_back(model.parameters()[i].name);
  const Eigen::VectorXd w = fit->weights();
  out.a = bi::normalMatrix(*fit, w);
  out.b = bi::scoreMatrix(*fit, w);
  out.pixels = fit->residuals.size();
  const std::vector<int> only{0};
  if (!bi::vertexNormalMatrix(model, theta, fit->indices, only, out.vertex_normal))
    out.vertex_normal = Eigen::MatrixXd::Zero(out.a.rows(), out.a.cols());
  if (fit->prior) {
    out.prior_lambda = fit->prior->lambda;
    // normalMatrix adds the prior's row; a set adds it once, not per view.
    out.a(fit->prior->column, fit->prior->column) -= out.prior_lambda * out.prior_lambda;
  }
  // Each influence: one render of the moved model at theta.
  const std::vector<int> radiographs{0};
  const std::vector<bi::InfluenceMove> moves = bi::listInfluences(model, fit->level, fit->level);
  std::vector<Eigen::VectorXd> columns;
  for (const bi::InfluenceMove& move : moves) {
    if (!move.left_out.empty()) continue;
    std::optional<MeasurementInputs> changed;  // the moved model keeps a reference to it
    if (move.change) {
      changed = model.inputs();
      move.change(*changed, 1.0);
    }
    ForwardModel moved(changed ? *changed : model.inputs(),
                       move.curve ? *move.curve : model.material());
    moved.setEdgeSamples(model.edgeSamples());
    std::vector<double> r;
    if (!moved.residuals(theta, fit->level, fit->samples, radiographs, r) ||
        r.size() != static_cast<size_t>(fit->residuals.size())) {
      spdlog::debug("plan: {} could not be simulated moved; left out", move.influence.name);
      continue;
    }
    const Eigen::VectorXd dr =
        Eigen::Map<const Eigen::VectorXd>(r.data(), fit->residuals.size()) - fit->residuals;
    columns.push_back(move.scale * (fit->jacobian.transpose() * w.cwiseProduct(dr)));
    out.influences.push_back(move.influence.name);
    out.iterated.push_back(move.how != bi::Propagation::kLinearised);
  }
  out.g.resize(static_cast<Eigen::Index>(out.names.size()),
               static_cast<Eigen::Index>(columns.size()));
  for (size_t f = 0; f < columns.size(); ++f) out.g.col(static_cast<Eigen::Index>(f)) = columns[f];
  return out;
}

}  // namespace xgauge

namespace xgauge {

Eigen::MatrixXd budgetPseudoInverse(const Eigen::MatrixXd& a, std::vector<Eigen::VectorXd>& null) {
  return budget_internal::pseudoInverse(a, null);
}

Eigen::MatrixXd budgetGeometricNullSpace(const Eigen::MatrixXd& vertex_normal) {
  return budget_internal::nullSpaceOfVertexNormal(vertex_normal);
}

}  // namespace xgauge
