#include "faced_shape.h"

#include "smallest_root_sets.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

namespace xgauge {
namespace {

// A vertex is placed when every surface has its nominal value there within
// this (mm); a placement further off than kMeetToleranceMm is a fold.
constexpr double kNewtonToleranceMm = 1e-12;
constexpr double kMeetToleranceMm = 1e-6;
// Directions with a smaller eigenvalue of the gradients' normal matrix than
// this times the largest are left alone (tangent surfaces, parallel planes).
constexpr double kRankCutoff = 1e-10;
// Unit gradients whose Gram determinant exceeds this are independent enough
// for the closed-form step (1e-6: 0.06 degrees apart).
constexpr double kCrossingDeterminant = 1e-6;
// The pull of a free vertex towards its nominal place, beside its
// neighbours' unit weights: what keeps a region without anchors in place.
constexpr double kHarmonicPull = 1e-6;
constexpr uint32_t kNoGroup = UINT32_MAX;
// A boundary vertex slides along a face when it leaves the face's own move
// by more than kSlideMm; the free vertices reach kBandFactor times the
// largest slide into the face.
constexpr double kSlideMm = 1e-9;
constexpr double kBandFactor = 3.0;

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
    const std::vector<char> touched = touchedGroups();
    for (uint32_t v = 0; v < vertex_count_; ++v) plan(v, touched);
    harmonicSystems();
    outlines();
    for (const Triangle& t : triangles_) nominal_normals_.push_back(normalOf(nominal_vertices_, t));
    for (uint32_t t = 0; t < triangles_.size(); ++t)
      if (!keepsItsTurn(triangles_[t])) may_turn_.push_back(t);
  }

  // Each vertex is a pure function of the scalars: the loops run on every
  // core and give the same numbers on any number.
  void place(std::span<const double> s, std::span<Vec3> out) const override {
    const Moved& moved = surfacesFor(s);
    forEach(vertex_count_, [&](size_t v) {
      if (plans_[v].method != Method::kHarmonic) out[v] = placeVertex(static_cast<uint32_t>(v), moved);
    });
    placeFree(edges_, moved, out);
    placeFree(insides_, moved, out);
  }

  // The first failure in vertex order, then in triangle order, whatever the
  // thread count.
  std::optional<std::string> placementProblem(std::span<const double> s,
                                              std::span<const Vec3> vertices) const override {
    const Moved& moved = surfacesFor(s);
    for (size_t g = 0; g < faced_->groups.size(); ++g)
      if (moved.changed[g] && moved.surfaces[g].kind == SurfaceKind::kCylinder &&
          !(moved.surfaces[g].radius > 0.0))
        return fmt::format("{} shrinks to no radius (moved by {})",
                           faced_->describeFace(faced_->groups[g].faces[0]),
                           fmt::join(faced_->group_movers[g], ", "));
    const size_t first_apart = firstWhere(vertex_count_, [&](size_t v) {
      const Plan& plan = plans_[v];
      return plan.check && anyChanged(static_cast<uint32_t>(v), moved) &&
             meetProblem(static_cast<uint32_t>(v), vertices[v], moved).has_value();
    });
    if (first_apart < vertex_count_)
      return meetProblem(static_cast<uint32_t>(first_apart), vertices[first_apart], moved);
    thread_local std::vector<char> scratch;
    std::vector<char>& turned = scratch;  // this thread's, for the workers too
    turned.assign(may_turn_.size(), 0);
    forEach(may_turn_.size(), [&](size_t k) {
      const uint32_t t = may_turn_[k];
      const Vec3& n0 = nominal_normals_[t];
      turned[k] = !n0.isZero() && !(normalOf(vertices, triangles_[t]).dot(n0) > 0.0);
    });
    std::vector<char> planar_checked(faced_->groups.size(), 0);
    for (size_t k = 0; k < may_turn_.size(); ++k) {
      if (!turned[k]) continue;
      const uint32_t t = may_turn_[k];
      const uint32_t face = faced_->solid.triangle_face[t];
      // Inside a plane, a folded triangle changes no path (each ray crosses
      // the plane once and counts the triangles there with their signs:
      // once inside the face's outline, whatever the fold), as long as the
      // outline itself stays a simple polygon of the same orientation.
      const uint32_t group = faced_->face_group[face];
      if (nominal_surfaces_[group].kind == SurfaceKind::kPlane) {
        if (planar_checked[group]) continue;
        planar_checked[group] = 1;
        if (outlineIsSimple(group, vertices, moved.surfaces[group])) continue;
      }
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
  // kFixed: nothing around the vertex moves. Anchors, placed from their own
  // surfaces: kLinear (planes only, at a corner), kNewton (at a corner, or on
  // a curved surface that moves), kPinned (on a freeform face). kHarmonic:
  // the others (on an edge or inside a face whose boundary moves), started
  // from the harmonic interpolation of the anchors' displacements over the
  // mesh, then placed on their surfaces: an edge's vertices stay spread
  // between its moved ends, a face's inside follows its moved boundary.
  // kCarried: inside a face, far from any boundary that slides along it:
  // the face's own move carries it.
  enum class Method : uint8_t { kFixed, kLinear, kNewton, kPinned, kHarmonic, kCarried };
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

  static constexpr size_t kGrain = 512;

  template <typename Work>
  static void forEach(size_t count, const Work& work) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, kGrain),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) work(i);
                      });
  }

  // The smallest i < count with test(i), or count.
  template <typename Test>
  static size_t firstWhere(size_t count, const Test& test) {
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, count, kGrain), count,
        [&](const tbb::blocked_range<size_t>& range, size_t found) {
          for (size_t i = range.begin(); i != range.end() && i < found; ++i)
            if (test(i)) return i;
          return found;
        },
        [](size_t a, size_t b) { return std::min(a, b); });
  }

  // A triangle whose vertices stay at nominal, or which its plane or
  // cylinder carries whole (a translation, and for a cylinder a radial
  // scaling while its radius stays positive, which placementProblem()
  // checks), cannot turn over: the turn check skips it.
  bool keepsItsTurn(const Triangle& t) const {
    const auto method = [&](int k) { return plans_[t[k]].method; };
    if (method(0) == Method::kFixed && method(1) == Method::kFixed && method(2) == Method::kFixed)
      return true;
    for (int k = 0; k < 3; ++k)
      if (method(k) != Method::kCarried) return false;
    const uint32_t g = groupsOf(t[0])[0];
    if (groupsOf(t[1])[0] != g || groupsOf(t[2])[0] != g) return false;
    const SurfaceKind kind = nominal_surfaces_[g].kind;
    return kind == SurfaceKind::kPlane || kind == SurfaceKind::kCylinder;
  }

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

  // Per group: whether any vertex of its faces can move (a vertex of it lies
  // on a surface that moves).
  std::vector<char> touchedGroups() const {
    std::vector<char> touched(faced_->groups.size(), 0);
    for (uint32_t v = 0; v < vertex_count_; ++v) {
      bool moves = false;
      for (const uint32_t g : groupsOf(v)) moves = moves || faced_->groups[g].moves();
      if (moves)
        for (const uint32_t g : groupsOf(v)) touched[g] = 1;
    }
    return touched;
  }

  // Each plane's outline: the directed mesh edges of its triangles whose
  // other side belongs to another surface.
  void outlines() {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> group_of_edge;
    for (size_t t = 0; t < triangles_.size(); ++t)
      for (int k = 0; k < 3; ++k)
        group_of_edge[{triangles_[t][k], triangles_[t][(k + 1) % 3]}] =
            faced_->face_group[faced_->solid.triangle_face[t]];
    outline_.resize(faced_->groups.size());
    for (const auto& [edge, group] : group_of_edge) {
      if (nominal_surfaces_[group].kind != SurfaceKind::kPlane) continue;
      const auto twin = group_of_edge.find({edge.second, edge.first});
      if (twin != group_of_edge.end() && twin->second == group) continue;
      outline_[group].push_back(edge);
    }
  }

  // Whether the plane's outline, in the moved plane, is a simple polygon
  // (no two of its edges that share no vertex cross or touch) enclosing
  // area with its nominal orientation.
  bool outlineIsSimple(uint32_t group, std::span<const Vec3> vertices, const Surface& plane) const {
    const Vec3 n = plane.axis;
    const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
    const Vec3 w = n.cross(u);
    const auto flat = [&](uint32_t v) { return Vec2(vertices[v].dot(u), vertices[v].dot(w)); };
    const auto& edges = outline_[group];
    double area = 0.0, nominal_area = 0.0;
    for (const auto& [a, b] : edges) {
      const Vec2 p = flat(a), q = flat(b);
      area += p.x() * q.y() - q.x() * p.y();
      const Vec2 p0(nominal_vertices_[a].dot(u), nominal_vertices_[a].dot(w));
      const Vec2 q0(nominal_vertices_[b].dot(u), nominal_vertices_[b].dot(w));
      nominal_area += p0.x() * q0.y() - q0.x() * p0.y();
    }
    if (!(area * nominal_area > 0.0)) return false;
    const auto cross = [](const Vec2& o, const Vec2& a, const Vec2& b) {
      return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
    };
    for (size_t i = 0; i < edges.size(); ++i) {
      const Vec2 a = flat(edges[i].first), b = flat(edges[i].second);
      const Vec2 lo = a.cwiseMin(b), hi = a.cwiseMax(b);
      for (size_t j = i + 1; j < edges.size(); ++j) {
        if (edges[j].first == edges[i].first || edges[j].first == edges[i].second ||
            edges[j].second == edges[i].first || edges[j].second == edges[i].second)
          continue;
        const Vec2 c = flat(edges[j].first), d = flat(edges[j].second);
        if ((c.cwiseMax(d) - lo).minCoeff() < 0.0 || (hi - c.cwiseMin(d)).minCoeff() < 0.0)
          continue;
        const double d1 = cross(c, d, a), d2 = cross(c, d, b);
        const double d3 = cross(a, b, c), d4 = cross(a, b, d);
        if (d1 * d2 <= 0.0 && d3 * d4 <= 0.0) return false;
      }
    }
    return true;
  }

  // How vertex v is placed (plans_ holds its groups already).
  void plan(uint32_t v, const std::vector<char>& touched) {
    Plan& plan = plans_[v];
    const std::vector<FaceGroup>& groups = faced_->groups;
    bool freeform = false, planes_only = true, near_moves = false, curved_moves = false;
    for (const uint32_t g : groupsOf(v)) {
      const SurfaceKind kind = nominal_surfaces_[g].kind;
      freeform = freeform || kind == SurfaceKind::kOther;
      near_moves = near_moves || touched[g];
      curved_moves = curved_moves || (kind != SurfaceKind::kPlane && groups[g].moves());
      planes_only = planes_only && kind == SurfaceKind::kPlane &&
                    groups[g].expressed == FaceGroup::Expressed::kNone;
    }
    if (!near_moves) {
      plan.method = Method::kFixed;
      return;
    }
    if (freeform) {
      plan.method = Method::kPinned;
      plan.check = true;
      return;
    }
    // Inside a face, and on an edge that no moving curved surface carries.
    // Inside a face the step onto the surface is exact (its value is a
    // distance along its gradient): only the triangles' turns are checked.
    if (plan.count == 1 || (plan.count == 2 && !curved_moves)) {
      plan.method = Method::kHarmonic;
      plan.check = plan.count == 2;
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

  // A Laplace problem over some free vertices: each one's displacement the
  // weighted mean of its neighbours' (weights of the mesh at nominal
  // values), the anchors among them given. A small diagonal term keeps a
  // region without anchors (a closed edge without corners) at its nominal
  // place. Split into its connected pieces (one face's inside, one edge),
  // each with its own sparse Cholesky factor: an evaluation solves only
  // the pieces whose anchors left their surfaces' own moves, on every core.
  struct Harmonic {
    std::vector<uint32_t> vertices;  // the free vertices, by row
    // Per row, the surface whose own move the row's displacement is taken
    // beyond (the face it lies inside); kNoGroup: none (on an edge).
    std::vector<uint32_t> group;
    struct Piece {
      std::vector<uint32_t> rows;                         // rows of `vertices`, ascending
      std::vector<uint32_t> anchor_first{0};              // per row, its anchors in `anchors`
      std::vector<std::pair<uint32_t, double>> anchors;   // (vertex, weight)
      // P A P^T = L D L^T (Eigen's SimplicialLDLT with AMD ordering): P as
      // `order` (row i of A is row order[i] of the factor), L's strictly
      // lower part by columns, D.
      std::vector<int> order;
      std::vector<uint32_t> column_first{0}, lower_row;
      std::vector<double> lower, diagonal;

      // Solves A x = b in place for the three coordinates at once, reading
      // the factor once per pass (Eigen's solve takes a column of the
      // right-hand side at a time: three passes over L each way).
      void solve(std::vector<Vec3>& b) const {
        thread_local std::vector<Vec3> y;
        y.resize(b.size());
        for (size_t i = 0; i < b.size(); ++i) y[static_cast<size_t>(order[i])] = b[i];
        for (size_t j = 0; j < y.size(); ++j) {
          const Vec3 yj = y[j];
          for (uint32_t k = column_first[j]; k < column_first[j + 1]; ++k)
            y[lower_row[k]] -= lower[k] * yj;
        }
        for (size_t j = 0; j < y.size(); ++j) y[j] /= diagonal[j];
        for (size_t j = y.size(); j-- > 0;) {
          Vec3 sum = y[j];
          for (uint32_t k = column_first[j]; k < column_first[j + 1]; ++k)
            sum -= lower[k] * y[lower_row[k]];
          y[j] = sum;
        }
        for (size_t i = 0; i < b.size(); ++i) b[i] = y[static_cast<size_t>(order[i])];
      }
    };
    std::vector<Piece> pieces;  // ordered by their first row

    // `weights[v]`: (neighbour, weight) pairs v's displacement follows,
    // symmetric (w(v, n) == w(n, v) where both are free); `row` maps a
    // vertex to its row or -1 (an anchor).
    void build(const std::vector<std::map<uint32_t, double>>& weights,
               const std::vector<int32_t>& row) {
      SmallestRootSets sets(vertices.size());
      for (size_t r = 0; r < vertices.size(); ++r)
        for (const auto& [n, w] : weights[vertices[r]])
          if (row[n] >= 0) sets.join(static_cast<uint32_t>(r), static_cast<uint32_t>(row[n]));
      std::vector<int32_t> piece_of(vertices.size(), -1), local(vertices.size(), -1);
      for (uint32_t r = 0; r < vertices.size(); ++r) {
        const uint32_t root = sets.root(r);
        if (piece_of[root] < 0) {
          piece_of[root] = static_cast<int32_t>(pieces.size());
          pieces.emplace_back();
        }
        Piece& piece = pieces[static_cast<size_t>(piece_of[root])];
        local[r] = static_cast<int32_t>(piece.rows.size());
        piece.rows.push_back(r);
      }
      for (Piece& piece : pieces) {
        std::vector<Eigen::Triplet<double>> entries;
        for (const uint32_t r : piece.rows) {
          const uint32_t v = vertices[r];
          double total = 0.0;
          for (const auto& [n, w] : weights[v]) total += w;
          entries.emplace_back(local[r], local[r], total * (1.0 + kHarmonicPull));
          for (const auto& [n, w] : weights[v]) {
            if (row[n] >= 0) {
              entries.emplace_back(local[r], local[static_cast<size_t>(row[n])], -w);
            } else {
              piece.anchors.emplace_back(n, w);
            }
          }
          piece.anchor_first.push_back(static_cast<uint32_t>(piece.anchors.size()));
        }
        const auto n = static_cast<Eigen::Index>(piece.rows.size());
        Eigen::SparseMatrix<double> laplacian(n, n);
        laplacian.setFromTriplets(entries.begin(), entries.end());
        laplacian.makeCompressed();
        const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> factor(laplacian);
        XG_CHECK(factor.info() == Eigen::Success, "a Laplacian of the free vertices");
        const auto& indices = factor.permutationP().indices();
        piece.order.assign(indices.data(), indices.data() + indices.size());
        const Eigen::SparseMatrix<double>& stored = factor.matrixL().nestedExpression();
        for (Eigen::Index j = 0; j < stored.outerSize(); ++j) {
          for (Eigen::SparseMatrix<double>::InnerIterator it(stored, j); it; ++it)
            if (it.row() > j) {
              piece.lower_row.push_back(static_cast<uint32_t>(it.row()));
              piece.lower.push_back(it.value());
            }
          piece.column_first.push_back(static_cast<uint32_t>(piece.lower.size()));
        }
        const Eigen::VectorXd& d = factor.vectorD();
        piece.diagonal.assign(d.data(), d.data() + d.size());
      }
    }
  };

  // The free vertices' two Laplace problems. On an edge (two surfaces): its
  // neighbours along the same edge, weighted by 1 / length, so that the
  // edge's vertices stay spread by arc length between the corners that end
  // it. Inside a face: all its neighbours with mean value weights (Floater
  // 2003: tan(a/2) / length summed over the angles a at the vertex beside
  // each edge), made symmetric by averaging the edge's two ends' (so that
  // one sparse Cholesky factor solves them): positive, so a vertex stays
  // within what its neighbours span, and close to harmonic on a graded
  // mesh, where uniform weights leave the small triangles along a moved edge
  // behind. Displacements do not spread across an edge from one face into
  // another.
  void harmonicSystems() {
    const auto& p = nominal_vertices_;
    const auto contains = [&](uint32_t n, std::span<const uint32_t> groups) {
      const auto of = groupsOf(n);
      return std::all_of(groups.begin(), groups.end(), [&](uint32_t g) {
        return std::find(of.begin(), of.end(), g) != of.end();
      });
    };
    // Along edges: 1 / length.
    std::vector<std::map<uint32_t, double>> weights(vertex_count_);
    std::vector<int32_t> edge_row(vertex_count_, -1), inside_row(vertex_count_, -1);
    for (uint32_t v = 0; v < vertex_count_; ++v)
      if (plans_[v].method == Method::kHarmonic && plans_[v].count == 2) {
        edge_row[v] = static_cast<int32_t>(edges_.vertices.size());
        edges_.vertices.push_back(v);
        edges_.group.push_back(kNoGroup);
      }
    for (const Triangle& t : triangles_)
      for (int k = 0; k < 3; ++k) {
        const uint32_t i = t[k];
        if (edge_row[i] < 0) continue;
        for (const uint32_t n : {t[(k + 1) % 3], t[(k + 2) % 3]})
          if (contains(n, groupsOf(i))) weights[i][n] = 1.0 / std::max((p[n] - p[i]).norm(), 1e-12);
      }
    edges_.build(weights, edge_row);

    // Inside faces: only where the face's boundary can slide along it.
    bandInsides();
    for (uint32_t v = 0; v < vertex_count_; ++v)
      if (plans_[v].method == Method::kHarmonic && plans_[v].count == 1) {
        inside_row[v] = static_cast<int32_t>(insides_.vertices.size());
        insides_.vertices.push_back(v);
        insides_.group.push_back(groupsOf(v)[0]);
      }
    // Mean value weights at every corner of every triangle with a free
    // vertex inside a face; each free vertex takes the mean of the two ends'
    // weight for each of its edges.
    std::vector<std::map<uint32_t, double>> mean_value(vertex_count_);
    for (const Triangle& t : triangles_)
      for (int k = 0; k < 3; ++k) {
        const uint32_t i = t[k], j = t[(k + 1) % 3], l = t[(k + 2) % 3];
        if (inside_row[i] < 0 && inside_row[j] < 0 && inside_row[l] < 0) continue;
        const Vec3 a = p[j] - p[i], b = p[l] - p[i];
        const double half = std::tan(0.5 * std::atan2(a.cross(b).norm(), a.dot(b)));
        mean_value[i][j] += half / std::max(a.norm(), 1e-12);
        mean_value[i][l] += half / std::max(b.norm(), 1e-12);
      }
    for (const Triangle& t : triangles_)
      for (int k = 0; k < 3; ++k) {
        const uint32_t i = t[k];
        if (inside_row[i] < 0) continue;
        for (const uint32_t n : {t[(k + 1) % 3], t[(k + 2) % 3]})
          weights[i][n] = 0.5 * (mean_value[i][n] + mean_value[n][i]);
      }
    insides_.build(weights, inside_row);
  }

  // Which vertices inside faces need the Laplace problem. A face carried
  // whole by its own move (a translated hole, a grown cylinder) needs none:
  // its inside follows that move exactly. Where a face's boundary slides
  // along it, each dimension is tried at its min and its max (the others at
  // nominal) and the boundary's slide recorded: the vertices inside the face
  // within kBandFactor times the face's largest slide (the sum over the
  // dimensions) of a boundary vertex that slides are free; those further in
  // follow the face's own move (kCarried). A face next to one given by
  // expressions, whose range is unknown, is free throughout.
  void bandInsides() {
    const size_t groups = faced_->groups.size();
    std::vector<double> reach(groups, 0.0);
    std::vector<char> sliding(vertex_count_, 0), whole(groups, 0);
    for (uint32_t v = 0; v < vertex_count_; ++v)
      for (const uint32_t g : groupsOf(v))
        if (faced_->groups[g].expressed != FaceGroup::Expressed::kNone)
          for (const uint32_t h : groupsOf(v)) whole[h] = 1;
    const auto is_inside = [&](uint32_t v) {
      return plans_[v].method == Method::kHarmonic && plans_[v].count == 1;
    };
    std::vector<Vec3> out;
    for (size_t s = 0; s < nominal_scalars_.size(); ++s) {
      const auto [low, high] = faced_->scalar_ranges[s];
      if (!std::isfinite(low) || !std::isfinite(high)) continue;
      std::vector<double> slide(groups, 0.0);
      for (const double value : {low, high}) {
        std::vector<double> scalars = nominal_scalars_;
        scalars[s] = value;
        const Moved& moved = surfacesFor(scalars);
        out = nominal_vertices_;
        for (uint32_t v = 0; v < vertex_count_; ++v)
          if (plans_[v].method != Method::kHarmonic) out[v] = placeVertex(v, moved);
        placeFree(edges_, moved, out);
        for (const Triangle& t : triangles_)
          for (int k = 0; k < 3; ++k) {
            const uint32_t v = t[k];
            if (!is_inside(v)) continue;
            const uint32_t g = groupsOf(v)[0];
            for (const uint32_t n : {t[(k + 1) % 3], t[(k + 2) % 3]}) {
              if (is_inside(n)) continue;
              const double d = (out[n] - nominal_vertices_[n] - ownMove(g, n, moved)).norm();
              if (!(d > kSlideMm)) continue;
              sliding[n] = 1;
              slide[g] = std::max(slide[g], d);
            }
          }
      }
      for (size_t g = 0; g < groups; ++g) reach[g] += slide[g];
    }
    // Each inside vertex's distance to the nearest sliding vertex of its face.
    std::vector<std::vector<uint32_t>> sliders(groups);
    for (uint32_t v = 0; v < vertex_count_; ++v)
      if (sliding[v])
        for (const uint32_t g : groupsOf(v)) sliders[g].push_back(v);
    for (uint32_t v = 0; v < vertex_count_; ++v) {
      if (!is_inside(v)) continue;
      const uint32_t g = groupsOf(v)[0];
      if (whole[g]) continue;
      const double band = kBandFactor * reach[g];
      bool near = false;
      for (const uint32_t n : sliders[g])
        if ((nominal_vertices_[n] - nominal_vertices_[v]).squaredNorm() <= band * band) {
          near = true;
          break;
        }
      if (!near) plans_[v].method = Method::kCarried, plans_[v].check = false;
    }
  }

  // The free vertices of one Laplace problem: what the anchors (in `out`
  // already) moved beyond their curved surfaces' own moves (start())
  // interpolated, added to each free vertex's own start, then each vertex
  // placed on its surfaces from there. A face carried whole by its surface
  // (a translated hole) gives nothing to interpolate; a face whose edge
  // moves along it (a chamfer's, as its shank grows) spreads that move over
  // its inside.
  void placeFree(const Harmonic& h, const Moved& moved, std::span<Vec3> out) const {
    tbb::parallel_for(size_t{0}, h.pieces.size(), [&](size_t k) {
      const Harmonic::Piece& piece = h.pieces[k];
      std::vector<Vec3> displacement(piece.rows.size(), Vec3::Zero());
      bool any = false;
      for (size_t i = 0; i < piece.rows.size(); ++i) {
        const uint32_t row = piece.rows[i];
        for (uint32_t a = piece.anchor_first[i]; a < piece.anchor_first[i + 1]; ++a) {
          const auto [anchor, weight] = piece.anchors[a];
          const Vec3 d =
              out[anchor] - nominal_vertices_[anchor] - ownMove(h.group[row], anchor, moved);
          if (d.isZero()) continue;
          displacement[i] += weight * d;
          any = true;
        }
      }
      if (any) piece.solve(displacement);
      forEach(piece.rows.size(), [&](size_t i) {
        const uint32_t row = piece.rows[i];
        const uint32_t v = h.vertices[row];
        const Vec3 from = nominal_vertices_[v] + ownMove(h.group[row], v, moved) + displacement[i];
        out[v] = any || anyChanged(v, moved) ? newton(v, moved, from) : nominal_vertices_[v];
      });
    });
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
        return newton(v, moved, start(v, moved));
      case Method::kCarried:
        return p0 + ownMove(groups[0], v, moved);
      case Method::kFixed:
      case Method::kHarmonic:
        break;
    }
    return p0;
  }

  // What surface `group`'s own move does to vertex v's nominal place: a
  // translation carries it, a growth moves it along the surface's normal (a
  // plane's: its shift along its normal). Zero for kNoGroup and for a
  // surface given by expressions.
  Vec3 ownMove(uint32_t group, uint32_t v, const Moved& moved) const {
    if (group == kNoGroup || !moved.changed[group] ||
        faced_->groups[group].expressed != FaceGroup::Expressed::kNone)
      return Vec3::Zero();
    const Surface& nominal = nominal_surfaces_[group];
    if (nominal.kind == SurfaceKind::kPlane)
      return nominal.axis * (nominal.axis.dot(moved.translation[group]) + moved.growth[group]);
    if (nominal.kind == SurfaceKind::kOther || moved.growth[group] == 0.0)
      return moved.translation[group];
    return moved.translation[group] + moved.growth[group] * nominal.gradient(nominal_vertices_[v]);
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

  Vec3 newton(uint32_t v, const Moved& moved, const Vec3& from) const {
    const auto groups = groupsOf(v);
    const double* nominal_value = nominal_values_.data() + plans_[v].first;
    Vec3 q = from;
    if (groups.size() == 1) {
      // One surface: its value is the distance along its unit gradient (for
      // planes, cylinders, spheres and tori exactly; for cones while the
      // foot stays on the nappe), so one step along the gradient lands on
      // it; placementProblem() checks that it did.
      Vec3 gradient;
      const double r =
          moved.surfaces[groups[0]].valueAndGradient(q, gradient) - nominal_value[0];
      if (std::abs(r) > kNewtonToleranceMm) q -= r * gradient;
      return q;
    }
    std::array<Vec3, 3> g;
    std::array<double, 3> r;
    for (int step = 0; step < kMaxNewtonSteps; ++step) {
      Mat3 normal = Mat3::Zero();
      Vec3 rhs = Vec3::Zero();
      double worst = 0.0;
      for (size_t i = 0; i < groups.size(); ++i) {
        Vec3 gradient;
        const double residual =
            moved.surfaces[groups[i]].valueAndGradient(q, gradient) - nominal_value[i];
        if (i < 3) g[i] = gradient, r[i] = residual;
        normal += gradient * gradient.transpose();
        rhs += gradient * residual;
        worst = std::max(worst, std::abs(residual));
      }
      if (!(worst > kNewtonToleranceMm)) break;
      q -= step_(groups.size(), g, r, normal, rhs);
    }
    return q;
  }

  // The least-norm correction: two surfaces that cross (an edge) and three
  // independent ones (a corner) in closed form, anything else (tangent
  // surfaces, more than three) through the eigen-decomposition.
  static Vec3 step_(size_t count, const std::array<Vec3, 3>& g, const std::array<double, 3>& r,
                    const Mat3& normal, const Vec3& rhs) {
    if (count == 2) {
      const double c = g[0].dot(g[1]);
      const double det = 1.0 - c * c;
      if (det > kCrossingDeterminant) {
        const double l0 = (r[0] - c * r[1]) / det, l1 = (r[1] - c * r[0]) / det;
        return l0 * g[0] + l1 * g[1];
      }
    } else if (count == 3) {
      Mat3 rows;
      rows << g[0].transpose(), g[1].transpose(), g[2].transpose();
      const double det = rows.determinant();
      if (std::abs(det) > kCrossingDeterminant) return rows.inverse() * Vec3(r[0], r[1], r[2]);
    }
    return leastNormSolve(normal, rhs);
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
      const double value = s.value(p);
      if (std::isfinite(value) && std::abs(value - nominal_value[i]) <= kMeetToleranceMm) continue;
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
  std::vector<uint32_t> may_turn_;         // the triangles the turn check looks at, ascending
  Harmonic edges_, insides_;  // the free vertices (harmonicSystems())
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> outline_;  // per plane group
};

}  // namespace

std::unique_ptr<const Shape> buildFacedShape(std::shared_ptr<const FacedStep> faced,
                                             std::span<const double> nominal_scalars) {
  return std::make_unique<FacedShape>(std::move(faced), nominal_scalars);
}

}  // namespace xgauge
