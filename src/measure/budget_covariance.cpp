// The budget's statistical part: A = J^T W J, the directions no radiograph
// sees taken out of it, its pseudo-inverse, B and the sandwich A^-1 B A^-1
// (docs/method.md, "Uncertainty").
#include "budget_internal.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <ranges>

namespace xgauge::budget_internal {

namespace {

constexpr int kBlockPx = 16;                   // cluster size of the sandwich (uncertainty.h)
constexpr double kGeometricNullRatio = 1e-10;  // of the vertex velocities' scaled normal
                                               // matrix: exact up to the vertex map's
                                               // finite differences (about 1e-8 relative)
constexpr double kNullRatio = 1e-9;  // eigenvalue of the scaled normal matrix below which a
                                     // direction is taken as not determined at all


// The directions of the parameters `indices` along which no vertex of the
// posed part moves in any of `radiographs`: pose and dimensions that
// describe the same placed part, which no radiograph can tell apart. The
// wedge's four pocket edges, measured from a centre line the part does not
// show, are the standing example: moving them all one way and the part the
// other leaves every vertex where it was. The image Jacobian sees such a
// direction only blurred by its finite differences over point samples (on
// the wedge its eigenvalue came out 0.3 % of the largest, as large as the
// genuine ones), so it is found from the vertex velocities, which are exact.
// Returns orthonormal columns in the parameters' own units; empty when there
// are none or the velocities cannot be evaluated.
Eigen::MatrixXd geometricNullSpace(ForwardModel& model, std::span<const double> theta,
                                   std::span<const int> indices, std::span<const int> radiographs) {
  Eigen::MatrixXd normal;
  if (!vertexNormalMatrix(model, theta, indices, radiographs, normal)) return {};
  return nullSpaceOfVertexNormal(normal);
}

}  // namespace

bool vertexNormalMatrix(ForwardModel& model, std::span<const double> theta,
                        std::span<const int> indices, std::span<const int> radiographs,
                        Eigen::MatrixXd& normal) {
  const auto n = static_cast<Eigen::Index>(indices.size());
  const auto vertices = static_cast<Eigen::Index>(model.part().vertexCount());
  normal = Eigen::MatrixXd::Zero(n, n);  // M^T M of the stacked velocities
  std::vector<int> moving;
  std::vector<Vec3> velocities;
  for (int r : radiographs) {
    if (!model.poseVelocities(theta, indices, r, moving, velocities)) return false;
    Eigen::MatrixXd m(3 * vertices, static_cast<Eigen::Index>(moving.size()));
    for (size_t k = 0; k < moving.size(); ++k)
      for (Eigen::Index v = 0; v < vertices; ++v)
        m.block<3, 1>(3 * v, static_cast<Eigen::Index>(k)) =
            velocities[k * static_cast<size_t>(vertices) + static_cast<size_t>(v)];
    const Eigen::MatrixXd mm = m.transpose() * m;
    for (size_t i = 0; i < moving.size(); ++i)
      for (size_t j = 0; j < moving.size(); ++j)
        normal(moving[i], moving[j]) +=
            mm(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
  }
  return true;
}

Eigen::MatrixXd nullSpaceOfVertexNormal(const Eigen::MatrixXd& normal) {
  const Eigen::Index n = normal.rows();
  // Over the parameters that move something, scaled to a unit diagonal.
  std::vector<Eigen::Index> cols;
  for (Eigen::Index k = 0; k < n; ++k)
    if (normal(k, k) > 0.0) cols.push_back(k);
  const auto g = static_cast<Eigen::Index>(cols.size());
  if (g == 0) return {};
  Eigen::MatrixXd scaled(g, g);
  Eigen::VectorXd s(g);
  for (Eigen::Index i = 0; i < g; ++i) s(i) = 1.0 / std::sqrt(normal(cols[i], cols[i]));
  for (Eigen::Index i = 0; i < g; ++i)
    for (Eigen::Index j = 0; j < g; ++j) scaled(i, j) = normal(cols[i], cols[j]) * s(i) * s(j);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled);
  const double largest = eigen.eigenvalues().maxCoeff();
  std::vector<Eigen::VectorXd> found;
  for (Eigen::Index k = 0; k < g; ++k) {
    if (!(eigen.eigenvalues()(k) < kGeometricNullRatio * largest)) continue;
    Eigen::VectorXd direction = Eigen::VectorXd::Zero(n);
    for (Eigen::Index i = 0; i < g; ++i) direction(cols[i]) = s(i) * eigen.eigenvectors()(i, k);
    found.push_back(direction);
  }
  if (found.empty()) return {};
  Eigen::MatrixXd basis(n, static_cast<Eigen::Index>(found.size()));
  for (size_t k = 0; k < found.size(); ++k) basis.col(static_cast<Eigen::Index>(k)) = found[k];
  return Eigen::HouseholderQR<Eigen::MatrixXd>(basis).householderQ() *
         Eigen::MatrixXd::Identity(n, basis.cols());
}

// The pseudo-inverse of the symmetric positive semi-definite A, scaled to a
// unit diagonal first so that millimetres and degrees compare; `null` gets
// the directions (in unscaled parameters) it drops.
Eigen::MatrixXd pseudoInverse(const Eigen::MatrixXd& a, std::vector<Eigen::VectorXd>& null) {
  const Eigen::Index n = a.rows();
  Eigen::VectorXd s(n);
  for (Eigen::Index k = 0; k < n; ++k) s(k) = a(k, k) > 0.0 ? 1.0 / std::sqrt(a(k, k)) : 0.0;
  const Eigen::MatrixXd scaled = s.asDiagonal() * a * s.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scaled);
  const Eigen::VectorXd& lambda = eigen.eigenvalues();
  const double largest = lambda.maxCoeff();
  spdlog::debug(
      "uncertainty: the scaled normal matrix's smallest eigenvalues relative to its "
      "largest: {:.3g}",
      fmt::join(std::vector<double>(lambda.data(), lambda.data() + std::min<Eigen::Index>(n, 4)) |
                    std::views::transform([&](double l) { return l / largest; }),
                ", "));
  Eigen::VectorXd inverse(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const bool dropped = !(lambda(k) > kNullRatio * largest);
    inverse(k) = dropped ? 0.0 : 1.0 / lambda(k);
    if (dropped) null.push_back((s.asDiagonal() * eigen.eigenvectors().col(k)).normalized());
  }
  for (Eigen::Index k = 0; k < n; ++k)
    if (s(k) == 0.0) null.push_back(Eigen::VectorXd::Unit(n, k));  // a parameter nothing sees
  return s.asDiagonal() * eigen.eigenvectors() * inverse.asDiagonal() *
         eigen.eigenvectors().transpose() * s.asDiagonal();
}

// A = J^T W J, with the refinement's prior.
Eigen::MatrixXd normalMatrix(const LinearizedFit& fit, const Eigen::VectorXd& w) {
  const Eigen::MatrixXd& jacobian = fit.jacobian;
  const Eigen::Index m = fit.residuals.size(), n = jacobian.cols();
  // Accumulated in row chunks (J has millions of rows).
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  constexpr Eigen::Index kChunk = 8192;
  for (Eigen::Index i = 0; i < m; i += kChunk) {
    const Eigen::Index rows = std::min(kChunk, m - i);
    const auto block = jacobian.middleRows(i, rows);
    a.noalias() += block.transpose() * w.segment(i, rows).asDiagonal() * block;
  }
  // The refinement's prior is a row of its own (least_squares.h): in A, not
  // in B, since its centre is not noise; the curve's uncertainty it stands
  // for is propagated as the material's components (budget_influences.cpp),
  // which the fit with the rate scale free absorbs as far as the
  // radiographs allow.
  if (fit.prior) a(fit.prior->column, fit.prior->column) += fit.prior->lambda * fit.prior->lambda;
  return a;
}

// B: the scores J_i psi_i summed per block of pixels, then their outer
// products (the blocks' sums are taken as independent, the pixels within a
// block not).
Eigen::MatrixXd scoreMatrix(const LinearizedFit& fit, const Eigen::VectorXd& w) {
  const Eigen::MatrixXd& jacobian = fit.jacobian;
  const Eigen::VectorXd& r = fit.residuals;
  const Eigen::Index n = jacobian.cols();
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, n);
  for (const ResidualSegment& segment : fit.segments) {
    const int bw = (segment.roi.width + kBlockPx - 1) / kBlockPx;
    const int bh = (segment.roi.height + kBlockPx - 1) / kBlockPx;
    Eigen::MatrixXd scores = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(bw) * bh);
    for (int y = 0; y < segment.roi.height; ++y)
      for (int x = 0; x < segment.roi.width; ++x) {
        const auto i = static_cast<Eigen::Index>(segment.first) +
                       static_cast<Eigen::Index>(y) * segment.roi.width + x;
        scores.col(static_cast<Eigen::Index>(y / kBlockPx) * bw + x / kBlockPx) +=
            jacobian.row(i).transpose() * (w(i) * r(i));
      }
    b.noalias() += scores * scores.transpose();
  }
  return b;
}

std::vector<int> fitRadiographs(const LinearizedFit& fit) {
  std::vector<int> radiographs;
  for (const ResidualSegment& s : fit.segments) radiographs.push_back(s.radiograph);
  return radiographs;
}

Covariance statisticalCovariance(ForwardModel& model, std::span<const double> theta,
                                 const LinearizedFit& fit, std::span<const int> radiographs) {
  Covariance out;
  out.w = fit.weights();
  const Eigen::Index m = fit.residuals.size(), n = fit.jacobian.cols();
  Eigen::MatrixXd a = normalMatrix(fit, out.w);
  // Directions no radiograph can see are taken out of A (and below of B
  // and of every influence's shift), so that the pseudo-inverse drops them
  // exactly and the dimensions along them are reported as not identifiable.
  const Eigen::MatrixXd unseen = geometricNullSpace(model, theta, fit.indices, radiographs);
  out.project = Eigen::MatrixXd::Identity(n, n);
  if (unseen.cols() > 0) {
    out.project -= unseen * unseen.transpose();
    a = out.project * a * out.project;
    spdlog::debug("uncertainty: {} direction(s) of the parameters move no vertex of the part",
                  unseen.cols());
  }
  out.a_inverse = pseudoInverse(a, out.null);
  Eigen::MatrixXd b = scoreMatrix(fit, out.w);
  b = out.project * b * out.project;
  const double small_sample =
      static_cast<double>(m) / static_cast<double>(std::max<Eigen::Index>(1, m - n));
  out.statistical = small_sample * out.a_inverse * b * out.a_inverse;
  return out;
}

}  // namespace xgauge::budget_internal
