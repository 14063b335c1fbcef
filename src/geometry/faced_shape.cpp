#include "faced_shape.h"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace xgauge {
namespace {

// A vertex is placed when every surface has its nominal value there within
// this (mm); a placement further off than kMeetToleranceMm is a fold.
constexpr double kNewtonToleranceMm = 1e-12;
constexpr double kMeetToleranceMm = 1e-6;
// Directions with a smaller eigenvalue of the gradients' normal matrix than
// this times the largest are left alone (tangent surfaces, parallel planes).
constexpr double kRankCutoff = 1e-10;

// The least-norm solution x of (sum g g^T) x = b, for the normal matrix
// `a` = sum g g^T of unit gradients g.
Vec3 leastNormSolve(const Mat3& a, const Vec3& b) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(a);
  const Vec3& values = eigen.eigenvalues();
  const double cutoff = kRankCutoff * std::max(values.maxCoeff(), 0.0);
  Vec3 x = Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    if (!(values[i] > cutoff)) continue;
    const Vec3 v = eigen.eigenvectors().col(i);
    x += v * (v.dot(b) / values[i]);
  }
  return x;
}

class FacedShape final : public Shape {
 public:
  FacedShape(std::shared_ptr<const FacedStep> faced, std::span<const double> nominal)
      : faced_(std::move(faced)), nominal_scalars_(nominal.begin(), nominal.end()) {
    const StepSolid& solid = faced_->solid;
    triangles_ = solid.mesh.triangles;
    vertex_count_ = solid.mesh.vertices.size();
    nominal_vertices_ = solid.mesh.vertices;
    nominalSurfaces();
    vertexGroups();
    for (uint32_t v = 0; v < vertex_count_; ++v) plan(v);
    for (const Triangle& t : triangles_) nominal_normals_.push_back(normalOf(nominal_vertices_, t));
  }

  void place(std::span<const double> s, std::span<Vec3> out) const override {
    const Moved& moved = surfacesFor(s);
    for (uint32_t v = 0; v < vertex_count_; ++v) out[v] = placeVertex(v, moved);
  }

  std::optional<std::string> placementProblem(std::span<const double> s,
                                              std::span<const Vec3> vertices) const override {
    const Moved& moved = surfacesFor(s);
    for (uint32_t v = 0; v < vertex_count_; ++v) {
      const Plan& plan = plans_[v];
      if (!plan.check || !anyChanged(v, moved)) continue;
      if (auto problem = meetProblem(v, vertices[v], moved)) return problem;
    }
    for (size_t t = 0; t < triangles_.size(); ++t) {
      const Vec3& n0 = nominal_normals_[t];
      if (n0.isZero()) continue;
      if (normalOf(vertices, triangles_[t]).dot(n0) > 0.0) continue;
      const uint32_t face = faced_->solid.triangle_face[t];
      if (faced_->groups[faced_->face_group[face]].moves())
        return fmt::format("{} turns over (moved by {})", faced_->describeFace(face),
                           movedBy(triangles_[t]));
      return fmt::format("{} turns over where its triangles, fixed at nominal values, no longer "
                         "fit its moved edges (moved by {})",
                         faced_->describeFace(face), movedBy(triangles_[t]));
    }
    return std::nullopt;
  }

 private:
  enum class Method : uint8_t { kFixed, kLinear, kNewton, kPinned };
  struct Plan {
    Method method = Method::kFixed;
    bool check = false;  // placementProblem() tests that its surfaces still meet there
    uint32_t first = 0;  // its groups in vertex_groups_
    uint32_t count = 0;
  };
  // The groups' surfaces for one set of scalars, and which differ from nominal.
  struct Moved {
    std::vector<Surface> surfaces;
    std::vector<Vec3> translation;  // terms' translation (freeform groups, starts)
    std::vector<double> growth;     // terms' growth
    std::vector<char> changed;
  };

  static Vec3 normalOf(std::span<const Vec3> vertices, const Triangle& t) {
    return (vertices[t[1]] - vertices[t[0]]).cross(vertices[t[2]] - vertices[t[0]]);
  }

  void nominalSurfaces() {
    const std::vector<FaceGroup>& groups = faced_->groups;
    for (size_t g = 0; g < groups.size(); ++g) {
      const FaceGroup& group = groups[g];
      nominal_surfaces_.push_back(group.at(nominal_scalars_, nominal_scalars_));
      if (group.expressed == FaceGroup::Expressed::kNone) continue;
      // An expressed surface must pass through its faces at nominal values.
      double worst = 0.0;
      for (size_t t = 0; t < triangles_.size(); ++t)
        if (faced_->face_group[faced_->solid.triangle_face[t]] == g)
          for (const uint32_t v : triangles_[t])
            worst = std::max(worst, std::abs(nominal_surfaces_[g].value(nominal_vertices_[v])));
      if (!(worst <= kNominalAgreementMm))
        throw Error(fmt::format("{}: at nominal values the {} passes up to {:.4g} mm from {}, "
                                "whose surface it gives (at most {} mm)",
                                faced_->movers(g), surfaceKindName(group.surface.kind), worst,
                                faced_->describeFace(group.faces[0]), kNominalAgreementMm),
                    group.where);
    }
  }

  void vertexGroups() {
    const double off_surface_limit = kFaceSelectionMm + 4.0 * faced_->chord_tolerance_mm;
    std::vector<std::vector<uint32_t>> of(vertex_count_);
    for (size_t t = 0; t < triangles_.size(); ++t) {
      const uint32_t g = faced_->face_group[faced_->solid.triangle_face[t]];
      for (const uint32_t v : triangles_[t])
        if (std::find(of[v].begin(), of[v].end(), g) == of[v].end()) of[v].push_back(g);
    }
    for (auto& groups : of) std::sort(groups.begin(), groups.end());
    for (uint32_t v = 0; v < vertex_count_; ++v) {
      Plan& plan = plans_.emplace_back();
      plan.first = static_cast<uint32_t>(vertex_groups_.size());
      plan.count = static_cast<uint32_t>(of[v].size());
      for (const uint32_t g : of[v]) {
        vertex_groups_.push_back(g);
        const Surface& s = nominal_surfaces_[g];
        const double value = s.kind == SurfaceKind::kOther ? 0.0 : s.value(nominal_vertices_[v]);
        // The tessellation's nodes lie on their faces; a surface that misses
        // them is one this code reads wrongly, and moving it would be wrong.
        if (faced_->groups[g].moves() && !(std::abs(value) <= off_surface_limit))
          throw Error(fmt::format("{}: a vertex of its tessellation lies {:.3g} mm from its {} as "
                                  "read; xgauge cannot move this face",
                                  faced_->describeFace(faced_->groups[g].faces[0]), value,
                                  surfaceKindName(s.kind)));
        nominal_values_.push_back(value);
      }
    }
    linear_columns_.assign(vertex_groups_.size(), Vec3::Zero());
  }

  std::span<const uint32_t> groupsOf(uint32_t v) const {
    return std::span<const uint32_t>(vertex_groups_).subspan(plans_[v].first, plans_[v].count);
  }

  // How vertex v is placed (plans_ holds its groups already).
  void plan(uint32_t v) {
    Plan& plan = plans_[v];
    const std::vector<FaceGroup>& groups = faced_->groups;
    bool moves = false, freeform = false, planes_only = true;
    for (const uint32_t g : groupsOf(v)) {
      moves = moves || groups[g].moves();
      freeform = freeform || nominal_surfaces_[g].kind == SurfaceKind::kOther;
      planes_only = planes_only && nominal_surfaces_[g].kind == SurfaceKind::kPlane &&
                    groups[g].expressed == FaceGroup::Expressed::kNone;
    }
    if (!moves) {
      plan.method = Method::kFixed;
      return;
    }
    if (freeform) {
      plan.method = Method::kPinned;
      plan.check = true;
      return;
    }
    if (!planes_only) {
      plan.method = Method::kNewton;
      plan.check = true;
      return;
    }
    // Planes keep their normals: the displacement is a fixed linear map of
    // the planes' shifts, pinv(N) with N's rows the normals.
    plan.method = Method::kLinear;
    const auto span = groupsOf(v);
    Eigen::Matrix<double, Eigen::Dynamic, 3> normals(span.size(), 3);
    for (size_t i = 0; i < span.size(); ++i)
      normals.row(static_cast<Eigen::Index>(i)) = nominal_surfaces_[span[i]].axis.transpose();
    const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 3>> svd(
        normals, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const auto& values = svd.singularValues();
    const double cutoff = std::sqrt(kRankCutoff) * (values.size() > 0 ? values[0] : 0.0);
    Eigen::Index rank = 0;
    Eigen::Matrix<double, 3, Eigen::Dynamic> pinv =
        Eigen::Matrix<double, 3, Eigen::Dynamic>::Zero(3, normals.rows());
    for (Eigen::Index i = 0; i < values.size(); ++i) {
      if (!(values[i] > cutoff)) continue;
      ++rank;
      pinv += svd.matrixV().col(i) * svd.matrixU().col(i).transpose() / values[i];
    }
    for (size_t i = 0; i < span.size(); ++i)
      linear_columns_[plan.first + i] = pinv.col(static_cast<Eigen::Index>(i));
    // More planes than the rank: they meet at the vertex only while they
    // move consistently.
    plan.check = rank < normals.rows();
  }

  const Moved& surfacesFor(std::span<const double> s) const {
    thread_local Moved moved;
    const std::vector<FaceGroup>& groups = faced_->groups;
    moved.surfaces.assign(nominal_surfaces_.begin(), nominal_surfaces_.end());
    moved.translation.assign(groups.size(), Vec3::Zero());
    moved.growth.assign(groups.size(), 0.0);
    moved.changed.assign(groups.size(), 0);
    for (size_t g = 0; g < groups.size(); ++g) {
      const FaceGroup& group = groups[g];
      if (!group.moves()) continue;
      if (group.expressed != FaceGroup::Expressed::kNone) {
        const size_t count = group.expressed == FaceGroup::Expressed::kPlaneNormal ? 6
                             : group.expressed == FaceGroup::Expressed::kPlaneThrough ? 9
                                                                                        : 7;
        bool changed = false;
        for (size_t i = group.first_scalar; i < group.first_scalar + count; ++i)
          changed = changed || s[i] != nominal_scalars_[i];
        if (!changed) continue;
        moved.surfaces[g] = group.at(s, nominal_scalars_);
        moved.changed[g] = 1;
        continue;
      }
      Vec3 translation = Vec3::Zero();
      double growth = 0.0;
      for (const FaceGroup::Term& term : group.terms) {
        const double delta = s[term.scalar] - nominal_scalars_[term.scalar];
        translation += delta * term.translation;
        growth += delta * term.growth;
      }
      if (translation.isZero() && growth == 0.0) continue;
      moved.translation[g] = translation;
      moved.growth[g] = growth;
      moved.surfaces[g] = nominal_surfaces_[g].moved(translation, growth);
      moved.changed[g] = 1;
    }
    return moved;
  }

  bool anyChanged(uint32_t v, const Moved& moved) const {
    for (const uint32_t g : groupsOf(v))
      if (moved.changed[g]) return true;
    return false;
  }

  Vec3 placeVertex(uint32_t v, const Moved& moved) const {
    const Plan& plan = plans_[v];
    const Vec3& p0 = nominal_vertices_[v];
    if (plan.method == Method::kFixed || !anyChanged(v, moved)) return p0;
    const auto groups = groupsOf(v);
    switch (plan.method) {
      case Method::kLinear: {
        Vec3 p = p0;
        for (size_t i = 0; i < groups.size(); ++i) {
          const uint32_t g = groups[i];
          if (!moved.changed[g]) continue;
          const Surface& now = moved.surfaces[g];
          const double shift = now.axis.dot(now.origin - nominal_surfaces_[g].origin);
          p += linear_columns_[plan.first + i] * shift;
        }
        return p;
      }
      case Method::kPinned:
        for (const uint32_t g : groups)
          if (nominal_surfaces_[g].kind == SurfaceKind::kOther) return p0 + moved.translation[g];
        return p0;
      case Method::kNewton:
        return newton(v, moved);
      case Method::kFixed:
        break;
    }
    return p0;
  }

  // The start: the mean of what the vertex's curved surfaces' own moves do
  // to it (a translation carries it, a growth moves it along the normal);
  // planes do not pull a vertex along themselves.
  Vec3 start(uint32_t v, const Moved& moved) const {
    const Vec3& p0 = nominal_vertices_[v];
    Vec3 sum = Vec3::Zero();
    int curved = 0;
    for (const uint32_t g : groupsOf(v)) {
      const Surface& nominal = nominal_surfaces_[g];
      if (nominal.kind == SurfaceKind::kPlane) continue;
      ++curved;
      if (!moved.changed[g] || faced_->groups[g].expressed != FaceGroup::Expressed::kNone)
        continue;
      sum += moved.translation[g] + moved.growth[g] * nominal.gradient(p0);
    }
    return curved > 0 ? Vec3(p0 + sum / curved) : p0;
  }

  Vec3 newton(uint32_t v, const Moved& moved) const {
    const auto groups = groupsOf(v);
    const double* nominal_value = nominal_values_.data() + plans_[v].first;
    Vec3 q = start(v, moved);
    for (int step = 0; step < kMaxNewtonSteps; ++step) {
      Mat3 normal = Mat3::Zero();
      Vec3 rhs = Vec3::Zero();
      double worst = 0.0;
      for (size_t i = 0; i < groups.size(); ++i) {
        const Surface& s = moved.surfaces[groups[i]];
        const double r = s.value(q) - nominal_value[i];
        const Vec3 gradient = s.gradient(q);
        normal += gradient * gradient.transpose();
        rhs += gradient * r;
        worst = std::max(worst, std::abs(r));
      }
      if (!(worst > kNewtonToleranceMm)) break;
      q -= leastNormSolve(normal, rhs);
    }
    return q;
  }

  std::optional<std::string> meetProblem(uint32_t v, const Vec3& p, const Moved& moved) const {
    const auto groups = groupsOf(v);
    const double* nominal_value = nominal_values_.data() + plans_[v].first;
    std::optional<Vec3> carried;
    for (size_t i = 0; i < groups.size(); ++i) {
      const uint32_t g = groups[i];
      const Surface& s = moved.surfaces[g];
      if (s.kind == SurfaceKind::kOther) {
        if (carried && !carried->isApprox(moved.translation[g], 0.0))
          return slideProblem(v, p, g);
        carried = moved.translation[g];
        continue;
      }
      if (std::isfinite(s.value(p)) &&
          std::abs(s.value(p) - nominal_value[i]) <= kMeetToleranceMm)
        continue;
      return meetFailure(v, p);
    }
    return std::nullopt;
  }

  std::string vertexFaces(uint32_t v) const {
    std::string text;
    for (const uint32_t g : groupsOf(v)) {
      if (!text.empty()) text += ", ";
      text += faced_->describeFace(faced_->groups[g].faces[0]);
    }
    return text;
  }

  // What moves these vertices' surfaces: "thickness, groove_depth".
  std::string movedBy(std::span<const uint32_t> vertices) const {
    std::vector<std::string> names;
    for (const uint32_t v : vertices)
      for (const uint32_t g : groupsOf(v))
        for (const std::string& name : faced_->group_movers[g])
          if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
    std::string text;
    for (const std::string& name : names) text += (text.empty() ? "" : ", ") + name;
    return text.empty() ? std::string("nothing") : text;
  }

  std::string meetFailure(uint32_t v, const Vec3& p) const {
    const Vec3& p0 = nominal_vertices_[v];
    return fmt::format("the faces that meet at ({:.4f}, {:.4f}, {:.4f}) at nominal values, {}, "
                       "no longer meet at one point (moved by {}; nearest found ({:.4f}, {:.4f}, "
                       "{:.4f}))",
                       p0.x(), p0.y(), p0.z(), vertexFaces(v), movedBy({&v, 1}), p.x(), p.y(), p.z());
  }

  std::string slideProblem(uint32_t v, const Vec3& /*p*/, uint32_t g) const {
    const Vec3& p0 = nominal_vertices_[v];
    return fmt::format("the vertex at ({:.4f}, {:.4f}, {:.4f}) would have to slide along the "
                       "freeform {} (moved by {}): a freeform face can only move with all its "
                       "neighbours",
                       p0.x(), p0.y(), p0.z(), faced_->describeFace(faced_->groups[g].faces[0]),
                       movedBy({&v, 1}));
  }

  std::shared_ptr<const FacedStep> faced_;
  std::vector<double> nominal_scalars_;
  std::vector<Vec3> nominal_vertices_;
  std::vector<Surface> nominal_surfaces_;  // per group, at nominal scalars
  std::vector<Plan> plans_;                // per vertex
  std::vector<uint32_t> vertex_groups_;    // per vertex, its groups (plans_[v].first, count)
  std::vector<double> nominal_values_;     // aligned with vertex_groups_: surface value at p0
  std::vector<Vec3> linear_columns_;       // aligned with vertex_groups_: pinv(N)'s columns
  std::vector<Vec3> nominal_normals_;      // per triangle, unnormalised
};

}  // namespace

std::unique_ptr<const Shape> buildFacedShape(std::shared_ptr<const FacedStep> faced,
                                             std::span<const double> nominal_scalars) {
  return std::make_unique<FacedShape>(std::move(faced), nominal_scalars);
}

}  // namespace xgauge
