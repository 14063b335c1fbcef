// CSG part models: the boolean program (Csg), the "shape" tree of a part file
// (solid.h: union, difference, intersection, placements, extrusion holes) and
// the reference parts 5 and 6 (docs/conventions.md). Rendering of CSG parts is
// tested in src/xray/csg_test.cpp.
#include "xgauge/geometry/csg.h"
#include "xgauge/geometry/part_model.h"

#include "shape.h"
#include "test_files.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <numbers>
#include <random>

namespace xgauge {
namespace {

using testing::expectLoadError;
using testing::kTetrahedronStl;
using testing::loadText;
using testing::writeTestFile;
using Op = Csg::Op;

constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------------------
// Csg: the program

// `n` pieces of one triangle each.
std::vector<uint32_t> oneTriangleEach(size_t n) {
  std::vector<uint32_t> ends(n);
  for (size_t i = 0; i < n; ++i) ends[i] = static_cast<uint32_t>(i + 1);
  return ends;
}

Csg::Node piece(uint32_t i) { return {Op::kPiece, i}; }
Csg::Node op(Op o, uint32_t operands) { return {o, operands}; }

bool bit(uint64_t mask, int i) { return ((mask >> i) & 1) != 0; }

// Piece 63's bit, out of the compiler's sight: with a constant 1 << 63, GCC
// 12's -Warray-bounds flags the inlined table lookup in Csg::contains (a
// branch never taken for 64 pieces) and -Werror stops the build.
uint64_t topBit() {
  static volatile int shift = 63;
  return uint64_t{1} << shift;
}

TEST(Csg, TruthTablesOfUnionDifferenceIntersection) {
  const Csg u(oneTriangleEach(3), {piece(0), piece(1), piece(2), op(Op::kUnion, 3)});
  const Csg d(oneTriangleEach(3), {piece(0), piece(1), piece(2), op(Op::kDifference, 3)});
  const Csg i(oneTriangleEach(3), {piece(0), piece(1), piece(2), op(Op::kIntersection, 3)});
  for (uint64_t m = 0; m < 8; ++m) {
    SCOPED_TRACE(m);
    EXPECT_EQ(u.contains(m), bit(m, 0) || bit(m, 1) || bit(m, 2));
    // Difference: the first operand minus all the others.
    EXPECT_EQ(d.contains(m), bit(m, 0) && !bit(m, 1) && !bit(m, 2));
    EXPECT_EQ(i.contains(m), bit(m, 0) && bit(m, 1) && bit(m, 2));
  }
  EXPECT_EQ(u.pieces(), 3u);
  for (size_t p = 0; p < 3; ++p) {
    EXPECT_TRUE(u.alone(p));
    EXPECT_EQ(d.alone(p), p == 0);
    EXPECT_FALSE(i.alone(p));
  }
  // Operand order matters for a difference only.
  const Csg reversed(oneTriangleEach(2), {piece(1), piece(0), op(Op::kDifference, 2)});
  EXPECT_FALSE(reversed.contains(0b01));
  EXPECT_TRUE(reversed.contains(0b10));
  EXPECT_FALSE(reversed.contains(0b11));
  EXPECT_FALSE(reversed.alone(0));
  EXPECT_TRUE(reversed.alone(1));
  // One operand: the operation is the identity.
  for (Op o : {Op::kUnion, Op::kDifference, Op::kIntersection}) {
    const Csg single(oneTriangleEach(1), {piece(0), op(o, 1)});
    EXPECT_FALSE(single.contains(0));
    EXPECT_TRUE(single.contains(1));
    EXPECT_TRUE(single.alone(0));
  }
}

TEST(Csg, NestedTreeAndAlone) {
  // (0 | 1) - (2 & 3) - 4, the bracket's shape with an intersection for a hole.
  const Csg csg(oneTriangleEach(5),
                {piece(0), piece(1), op(Op::kUnion, 2), piece(2), piece(3),
                 op(Op::kIntersection, 2), piece(4), op(Op::kDifference, 3)});
  for (uint64_t m = 0; m < 32; ++m) {
    const bool expected =
        (bit(m, 0) || bit(m, 1)) && !(bit(m, 2) && bit(m, 3)) && !bit(m, 4);
    EXPECT_EQ(csg.contains(m), expected) << m;
  }
  EXPECT_EQ(std::vector<bool>({csg.alone(0), csg.alone(1), csg.alone(2), csg.alone(3),
                               csg.alone(4)}),
            std::vector<bool>({true, true, false, false, false}));
  // ((0 - 1) | 2) & 3: nothing alone; 3 with 2 or with 0 but not 1.
  const Csg deep(oneTriangleEach(4), {piece(0), piece(1), op(Op::kDifference, 2), piece(2),
                                      op(Op::kUnion, 2), piece(3), op(Op::kIntersection, 2)});
  for (uint64_t m = 0; m < 16; ++m)
    EXPECT_EQ(deep.contains(m), ((bit(m, 0) && !bit(m, 1)) || bit(m, 2)) && bit(m, 3)) << m;
  for (size_t p = 0; p < 4; ++p) EXPECT_FALSE(deep.alone(p));
}

TEST(Csg, PieceOfTriangle) {
  const Csg csg({3, 3 + 5, 8 + 1}, {piece(0), piece(1), piece(2), op(Op::kUnion, 3)});
  const std::vector<uint32_t> expected = {0, 0, 0, 1, 1, 1, 1, 1, 2};
  for (uint32_t t = 0; t < expected.size(); ++t) EXPECT_EQ(csg.pieceOfTriangle(t), expected[t]);
  EXPECT_EQ(std::vector<uint32_t>(csg.pieceTriangleEnds().begin(), csg.pieceTriangleEnds().end()),
            (std::vector<uint32_t>{3, 8, 9}));
}

// An independent evaluator: a random tree, evaluated recursively, and its
// postfix program for Csg.
struct Tree {
  Op op = Op::kPiece;
  uint32_t piece = 0;
  std::vector<Tree> children;

  bool contains(uint64_t mask) const {
    switch (op) {
      case Op::kPiece: return bit(mask, static_cast<int>(piece));
      case Op::kUnion:
        return std::any_of(children.begin(), children.end(),
                           [&](const Tree& c) { return c.contains(mask); });
      case Op::kIntersection:
        return std::all_of(children.begin(), children.end(),
                           [&](const Tree& c) { return c.contains(mask); });
      case Op::kDifference:
        return children[0].contains(mask) &&
               std::none_of(children.begin() + 1, children.end(),
                            [&](const Tree& c) { return c.contains(mask); });
    }
    return false;
  }
  void postfix(std::vector<Csg::Node>& out) const {
    if (op == Op::kPiece) {
      out.push_back({Op::kPiece, piece});
      return;
    }
    for (const Tree& c : children) c.postfix(out);
    out.push_back({op, static_cast<uint32_t>(children.size())});
  }
};

// A random tree over the pieces [first, last) of `order`.
Tree randomTree(std::mt19937_64& rng, const std::vector<uint32_t>& order, size_t first,
                size_t last) {
  Tree tree;
  if (last - first == 1) {
    tree.piece = order[first];
    // Sometimes a one-operand operation over a leaf.
    if (std::uniform_int_distribution<int>(0, 5)(rng) == 0) {
      Tree leaf = tree;
      tree = Tree{Op::kUnion, 0, {leaf}};
    }
    return tree;
  }
  const Op ops[] = {Op::kUnion, Op::kDifference, Op::kIntersection};
  tree.op = ops[std::uniform_int_distribution<int>(0, 2)(rng)];
  // Split into 2 to 4 consecutive groups.
  const size_t size = last - first;
  const size_t groups = std::min<size_t>(size, std::uniform_int_distribution<size_t>(2, 4)(rng));
  std::vector<size_t> cuts = {first, last};
  while (cuts.size() < groups + 1) {
    const size_t cut = std::uniform_int_distribution<size_t>(first + 1, last - 1)(rng);
    if (std::find(cuts.begin(), cuts.end(), cut) == cuts.end()) cuts.push_back(cut);
  }
  std::sort(cuts.begin(), cuts.end());
  for (size_t g = 0; g + 1 < cuts.size(); ++g)
    tree.children.push_back(randomTree(rng, order, cuts[g], cuts[g + 1]));
  return tree;
}

// Masks that exercise a tree: random ones, sparse ones and near-full ones.
uint64_t randomMask(std::mt19937_64& rng, size_t pieces) {
  const uint64_t all = pieces == 64 ? ~uint64_t{0} : (uint64_t{1} << pieces) - 1;
  switch (std::uniform_int_distribution<int>(0, 3)(rng)) {
    case 0: return rng() & all;
    case 1: return rng() & rng() & rng() & all;
    case 2: return (rng() | rng() | rng()) & all;
    default: return uint64_t{1} << std::uniform_int_distribution<size_t>(0, pieces - 1)(rng);
  }
}

TEST(Csg, RandomTreesAgreeWithADirectEvaluationWithAndWithoutTheTable) {
  std::mt19937_64 rng(77);
  // 16 pieces use the table of all masks; 17 and more evaluate the program.
  for (size_t pieces : {5, 12, 16, 17, 20, 33, 64}) {
    for (int tree_index = 0; tree_index < 20; ++tree_index) {
      std::vector<uint32_t> order(pieces);
      for (size_t i = 0; i < pieces; ++i) order[i] = static_cast<uint32_t>(i);
      std::shuffle(order.begin(), order.end(), rng);
      const Tree tree = randomTree(rng, order, 0, pieces);
      std::vector<Csg::Node> program;
      tree.postfix(program);
      const Csg csg(oneTriangleEach(pieces), program);
      ASSERT_EQ(csg.pieces(), pieces);
      for (size_t p = 0; p < pieces; ++p)
        ASSERT_EQ(csg.alone(p), tree.contains(uint64_t{1} << p)) << pieces << " pieces, piece " << p;
      ASSERT_FALSE(csg.contains(0));
      const uint64_t all = pieces == 64 ? ~uint64_t{0} : (uint64_t{1} << pieces) - 1;
      ASSERT_EQ(csg.contains(all), tree.contains(all));
      if (pieces <= 12) {
        for (uint64_t m = 0; m <= all; ++m)
          ASSERT_EQ(csg.contains(m), tree.contains(m)) << pieces << " pieces, mask " << m;
      } else {
        for (int k = 0; k < 20000; ++k) {
          const uint64_t m = randomMask(rng, pieces);
          ASSERT_EQ(csg.contains(m), tree.contains(m)) << pieces << " pieces, mask " << m;
        }
      }
    }
  }
}

TEST(Csg, PieceCountIsOneTo64) {
  EXPECT_THROW(Csg({}, {}), Error);
  std::vector<Csg::Node> program;
  for (uint32_t i = 0; i < 65; ++i) program.push_back(piece(i));
  program.push_back(op(Op::kUnion, 65));
  try {
    Csg(oneTriangleEach(65), program);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "a part has 1 to 64 solids, this one has 65");
  }
  program.erase(program.end() - 2);
  program.back() = op(Op::kUnion, 64);
  const Csg max(oneTriangleEach(64), program);
  EXPECT_TRUE(max.contains(topBit()));
  EXPECT_TRUE(max.alone(63));
}

// Malformed programs are internal errors (the reader makes well-formed ones):
// they abort through XG_CHECK. (csg.h says "Throws Error otherwise"; only the
// piece count throws.)
TEST(CsgDeathTest, MalformedProgramsAreRefused) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(Csg(oneTriangleEach(2), {piece(0), piece(0), op(Op::kUnion, 2)}),
               "every CSG piece must appear once");
  EXPECT_DEATH(Csg(oneTriangleEach(2), {piece(0)}), "every CSG piece must appear once");
  EXPECT_DEATH(Csg(oneTriangleEach(2), {piece(0), piece(1)}), "leaves 2 values");
  EXPECT_DEATH(Csg(oneTriangleEach(1), {piece(0), op(Op::kUnion, 0)}), "operands");
  EXPECT_DEATH(Csg(oneTriangleEach(2), {piece(0), op(Op::kUnion, 2), piece(1)}), "operands");
  EXPECT_DEATH(Csg(oneTriangleEach(2), {piece(0), piece(2), op(Op::kUnion, 2)}), "piece 2 of 2");
  EXPECT_DEATH(Csg({2, 1}, {piece(0), piece(1), op(Op::kUnion, 2)}), "out of order");
}

// ---------------------------------------------------------------------------
// Part files

PartModel loadPart(const std::string& name) {
  return PartModel::load(std::filesystem::path(XGAUGE_SOURCE_DIR) / "parts" / (name + ".json"));
}

// Segments for a 0.001 mm chord error, from the sagitta r (1 - cos(pi / N)),
// computed here (not with segmentsForChordError): the least N >= 8 with
// r (1 - cos(pi / N)) <= 0.001.
int segmentsFor(double radius) {
  int n = 8;
  while (radius * (1 - std::cos(kPi / n)) > 0.001) ++n;
  return n;
}

std::vector<uint32_t> ends(const Csg& csg) {
  return {csg.pieceTriangleEnds().begin(), csg.pieceTriangleEnds().end()};
}

TEST(Solid, BracketAndShaftLoadAsCsgParts) {
  const PartModel bracket = loadPart("bracket");
  EXPECT_EQ(bracket.dimensions().size(), 9u);
  ASSERT_NE(bracket.csg(), nullptr);
  EXPECT_EQ(bracket.csg()->pieces(), 5u);  // two plates, three hole cylinders
  // Boxes: 12 triangles; a cylinder of N segments: 4 N (two fans, one band).
  const uint32_t n_base = segmentsFor(6.6 / 2), n_upright = segmentsFor(8.4 / 2);
  EXPECT_EQ(ends(*bracket.csg()),
            (std::vector<uint32_t>{12, 24, 24 + 4 * n_base, 24 + 8 * n_base,
                                   24 + 8 * n_base + 4 * n_upright}));
  EXPECT_EQ(bracket.vertexCount(), 16u + 2 * (2 * n_base + 2) + (2 * n_upright + 2));
  // (plate | plate) - hole - hole - hole.
  for (uint64_t m = 0; m < 32; ++m)
    EXPECT_EQ(bracket.csg()->contains(m), (bit(m, 0) || bit(m, 1)) && (m >> 2) == 0) << m;

  const PartModel shaft = loadPart("stepped_shaft");
  EXPECT_EQ(shaft.dimensions().size(), 6u);
  ASSERT_NE(shaft.csg(), nullptr);
  EXPECT_EQ(shaft.csg()->pieces(), 2u);
  // The revolved profile has 6 points, 2 of them on the axis: 2 fans, 3 bands.
  const uint32_t n_shaft = segmentsFor(10.0), n_hole = segmentsFor(2.5);
  EXPECT_EQ(ends(*shaft.csg()), (std::vector<uint32_t>{8 * n_shaft, 8 * n_shaft + 4 * n_hole}));
  EXPECT_EQ(shaft.vertexCount(), 4u * n_shaft + 2 + 2 * n_hole + 2);

  // mesh() hands the same program on; every piece is closed on its own.
  for (const PartModel* model : {&bracket, &shaft}) {
    const TriangleMesh mesh = model->mesh(model->nominalValues());
    EXPECT_EQ(mesh.csg, model->csg());
    uint32_t begin = 0;
    for (uint32_t end : model->csg()->pieceTriangleEnds()) {
      TriangleMesh piece_mesh;
      piece_mesh.vertices = mesh.vertices;
      piece_mesh.triangles.assign(mesh.triangles.begin() + begin, mesh.triangles.begin() + end);
      const MeshCheck check = checkClosedMesh(piece_mesh);
      EXPECT_TRUE(check.ok()) << check.message;
      begin = end;
    }
    EXPECT_EQ(begin, mesh.triangles.size());
  }

  // One solid, written plainly or as a one-element union: no CSG.
  const PartModel cylinder = loadPart("cylinder");
  EXPECT_EQ(cylinder.csg(), nullptr);
  EXPECT_EQ(cylinder.mesh(cylinder.nominalValues()).csg, nullptr);
  const PartModel single = loadText(R"({"description": "one box", "dimensions": [],
      "shape": {"type": "union", "solids": [{"type": "box", "min": [0, 0, 0], "max": [1, 2, 3]}]}})");
  EXPECT_EQ(single.csg(), nullptr);
  EXPECT_NEAR(signedVolume(single.mesh({})), 6.0, 1e-12);
}

TEST(Solid, BracketConstraintNamesTheValues) {
  const PartModel bracket = loadPart("bracket");
  // c - d/2 - T = 9 - 5 - 4 = 0: the first hole touches the upright.
  const std::vector<double> values =
      bracket.values({{"hole_position", 9.0}, {"hole_diameter", 10.0}});
  try {
    bracket.validate(values);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(),
              "constraint violated: the first base hole must clear the upright (c - d/2 > T) "
              "(hole_position - hole_diameter / 2 - thickness = 0, must be > 0) at "
              "base_length=40 mm, height=30 mm, width=25 mm, thickness=4 mm, hole_diameter=10 mm, "
              "hole_position=9 mm, hole_spacing=16 mm, upright_hole_diameter=8.4 mm, "
              "upright_hole_height=19 mm");
    EXPECT_EQ(e.where().key_path, "/constraints/0/expr");
  }
  EXPECT_THROW(bracket.mesh(values), Error);
  EXPECT_FALSE(bracket.invalidity(bracket.values({{"hole_position", 9.01}, {"hole_diameter", 10.0}})));
}

// Vertex i of a box, as the reader lays it out: the (x, y) rectangle's
// corners (lo, lo), (hi, lo), (hi, hi), (lo, hi) at z = lo, then at z = hi.
Vec3 boxCorner(const Vec3& lo, const Vec3& hi, int i) {
  const int c = i % 4;
  return {c == 1 || c == 2 ? hi.x() : lo.x(), c >= 2 ? hi.y() : lo.y(), i >= 4 ? hi.z() : lo.z()};
}

TEST(Solid, PlacementsFollowThePoseConvention) {
  // An outer placement on the union, an inner one on the second box, both
  // expressions of the dimensions.
  const PartModel model = loadText(R"({"description": "placed boxes",
    "dimensions": [{"name": "a", "nominal": 30, "min": -90, "max": 90, "unit": "deg"},
                   {"name": "t", "nominal": 5, "min": 1, "max": 10, "unit": "mm"}],
    "shape": {"type": "union", "rotate": [0, 0, "a / 3"], "translate": [1, 2, 3],
      "solids": [
        {"type": "box", "min": [0, 0, 0], "max": [1, 2, 3]},
        {"type": "box", "min": ["-t", 0, 1], "max": ["t", "t", 2],
         "rotate": ["a", "2 * a", "-a"], "translate": ["t", "t / 2", 3]},
        {"type": "box", "min": [0, 0, 0], "max": [1, 1, 1], "translate": [0, 0, "2 * t"]}
      ]}})");
  ASSERT_NE(model.csg(), nullptr);
  ASSERT_EQ(model.vertexCount(), 24u);
  for (const auto& [a, t] : {std::pair{30.0, 5.0}, std::pair{-71.5, 2.25}, std::pair{0.0, 10.0}}) {
    SCOPED_TRACE(fmt::format("a={} t={}", a, t));
    const TriangleMesh mesh = model.mesh(std::vector<double>{a, t});
    // x_world = R x + t with R = Rz Ry Rx (fixed axes x, y, z), written out
    // here rather than taken from Pose.
    auto rotation = [](double rx, double ry, double rz) {
      const double d = kPi / 180;
      return (Eigen::AngleAxisd(rz * d, Vec3::UnitZ()) * Eigen::AngleAxisd(ry * d, Vec3::UnitY()) *
              Eigen::AngleAxisd(rx * d, Vec3::UnitX()))
          .toRotationMatrix();
    };
    const Mat3 outer = rotation(0, 0, a / 3), inner = rotation(a, 2 * a, -a);
    const Vec3 outer_t(1, 2, 3), inner_t(t, t / 2, 3);
    for (int i = 0; i < 8; ++i) {
      const Vec3 p0 = outer * boxCorner({0, 0, 0}, {1, 2, 3}, i) + outer_t;
      const Vec3 p1 = outer * (inner * boxCorner({-t, 0, 1}, {t, t, 2}, i) + inner_t) + outer_t;
      const Vec3 p2 = outer * (boxCorner({0, 0, 0}, {1, 1, 1}, i) + Vec3(0, 0, 2 * t)) + outer_t;
      EXPECT_LT((mesh.vertices[i] - p0).norm(), 1e-12) << i;
      EXPECT_LT((mesh.vertices[8 + i] - p1).norm(), 1e-12) << i;
      EXPECT_LT((mesh.vertices[16 + i] - p2).norm(), 1e-12) << i;
    }
    // Rigid placements keep every piece's volume.
    EXPECT_NEAR(signedVolume(mesh.vertices, std::span(mesh.triangles).subspan(0, 12)), 6.0, 1e-12);
    EXPECT_NEAR(signedVolume(mesh.vertices, std::span(mesh.triangles).subspan(12, 12)),
                2 * t * t * 1, 1e-12);
  }
}

// An extrusion with holes is the outer prism minus prisms of the holes that
// reach a twentieth of the length beyond each cap (solid.cpp); written out as
// a difference it is the same mesh and the same program.
TEST(Solid, ExtrusionHolesAreADifferenceOfPrisms) {
  const std::string dimensions = R"("dimensions": [
      {"name": "w", "nominal": 30, "min": 20, "max": 40, "unit": "mm"},
      {"name": "h", "nominal": 6, "min": 2, "max": 10, "unit": "mm"}])";
  const PartModel with_holes = loadText(R"({"description": "plate with holes", )" + dimensions + R"(,
    "shape": {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
      "profile": [[0, 0], ["w", 0], ["w", 20], [0, 20]], "from": 0, "to": "h",
      "holes": [[[3, 3], [7, 3], [7, 7], [3, 7]], [["w - 6", 10], ["w - 2", 12], ["w - 4", 15]]],
      "rotate": [10, 20, 30], "translate": [1, 2, "h"]}})");
  const PartModel explicit_difference = loadText(R"({"description": "the same", )" + dimensions + R"(,
    "shape": {"type": "difference", "rotate": [10, 20, 30], "translate": [1, 2, "h"], "solids": [
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [[0, 0], ["w", 0], ["w", 20], [0, 20]], "from": 0, "to": "h"},
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [[3, 3], [7, 3], [7, 7], [3, 7]], "from": "-h / 20", "to": "h + h / 20"},
      {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
       "profile": [["w - 6", 10], ["w - 2", 12], ["w - 4", 15]], "from": "-h / 20", "to": "h + h / 20"}
    ]}})");
  ASSERT_NE(with_holes.csg(), nullptr);
  ASSERT_NE(explicit_difference.csg(), nullptr);
  EXPECT_EQ(with_holes.csg()->pieces(), 3u);
  EXPECT_EQ(ends(*with_holes.csg()), ends(*explicit_difference.csg()));
  const auto a = with_holes.csg()->program(), b = explicit_difference.csg()->program();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].op, b[i].op);
    EXPECT_EQ(a[i].arg, b[i].arg);
  }
  EXPECT_EQ(with_holes.triangles(), explicit_difference.triangles());
  for (const std::vector<double>& values :
       {with_holes.nominalValues(), std::vector<double>{37.5, 2.5}}) {
    const TriangleMesh x = with_holes.mesh(values), y = explicit_difference.mesh(values);
    ASSERT_EQ(x.vertices.size(), y.vertices.size());
    for (size_t i = 0; i < x.vertices.size(); ++i)
      EXPECT_LT((x.vertices[i] - y.vertices[i]).norm(), 1e-12) << i;
    // The hole prisms are 1.1 h long, the plate h.
    const auto triangles = std::span<const Triangle>(x.triangles);
    const auto e = with_holes.csg()->pieceTriangleEnds();
    EXPECT_NEAR(signedVolume(x.vertices, triangles.subspan(0, e[0])), values[0] * 20 * values[1],
                1e-9);
    EXPECT_NEAR(signedVolume(x.vertices, triangles.subspan(e[0], e[1] - e[0])),
                16 * 1.1 * values[1], 1e-9);
    EXPECT_NEAR(signedVolume(x.vertices, triangles.subspan(e[1], e[2] - e[1])),
                0.5 * std::abs(4 * 5 - 2 * 2) * 1.1 * values[1], 1e-9);
  }
  // An extrusion that runs backwards: the holes still reach beyond both caps.
  const PartModel backwards = loadText(R"({"description": "backwards", )" + dimensions + R"(,
    "shape": {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
      "profile": [[0, 0], ["w", 0], ["w", 20], [0, 20]], "from": "h", "to": 0,
      "holes": [[[3, 3], [7, 3], [7, 7], [3, 7]]]}})");
  const TriangleMesh mesh = backwards.mesh(backwards.nominalValues());
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (size_t i = 8; i < mesh.vertices.size(); ++i)
    lo = std::min(lo, mesh.vertices[i].z()), hi = std::max(hi, mesh.vertices[i].z());
  EXPECT_NEAR(lo, -0.3, 1e-12);
  EXPECT_NEAR(hi, 6.3, 1e-12);
}

const std::string kTwoBoxes = R"({"description": "two boxes", "dimensions": [],
  "shape": {"type": "union", "solids": [
    {"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]},
    {"type": "box", "min": [0, 0, 0], "max": [2, 2, 2]}]}})";

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(Solid, ErrorsNameTheKeyPath) {
  ASSERT_NO_THROW(loadText(kTwoBoxes));
  // A misspelled list of solids: the unknown key is named before the
  // missing one it misspells, at its own path.
  expectLoadError(replaced(kTwoBoxes, R"("solids")", R"("solid")"),
                  "unknown key 'solid'; did you mean 'solids'?", "/shape/solid");
  // ... also in a nested node.
  expectLoadError(replaced(kTwoBoxes, R"({"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]})",
                           R"({"type": "difference", "solid": []})"),
                  "unknown key 'solid'; did you mean 'solids'?", "/shape/solids/0/solid");
  // A required key absent, with nothing like it: missing, at the node.
  expectLoadError(replaced(kTwoBoxes, R"({"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]})",
                           R"({"type": "difference"})"),
                  "missing key 'solids'", "/shape/solids/0");
  // A key that no CSG node has.
  expectLoadError(replaced(kTwoBoxes, R"("type": "union",)", R"("type": "union", "colour": "red",)"),
                  "unknown key 'colour'", "/shape/colour");
  expectLoadError(replaced(kTwoBoxes, R"("type": "union",)", R"("type": "union", "translat": [1, 2, 3],)"),
                  "unknown key 'translat'; did you mean 'translate'?", "/shape/translat");
  expectLoadError(replaced(kTwoBoxes, R"("max": [1, 1, 1])", R"("max": [1, 1, 1], "rotat": [1, 2, 3])"),
                  "unknown key 'rotat'; did you mean 'rotate'?", "/shape/solids/0/rotat");
  // Holes belong to extrusions only.
  expectLoadError(replaced(kTwoBoxes, R"("max": [2, 2, 2])", R"("max": [2, 2, 2], "holes": [])"),
                  "unknown key 'holes'", "/shape/solids/1/holes");
  expectLoadError(replaced(kTwoBoxes, R"("solids": [)", R"("solids": [], "x": [)"),
                  "a union needs a list of one or more solids", "/shape/solids");
}

TEST(Solid, MoreErrors) {
  try {
    loadText(R"({"description": "x", "dimensions": [],
        "shape": {"type": "intersection", "solids": []}})");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "an intersection needs a list of one or more solids");
    EXPECT_EQ(e.where().key_path, "/shape/solids");
  }
  expectLoadError(R"({"description": "x", "dimensions": [],
      "shape": {"type": "difference", "solids": {"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]}}})",
                  "a difference needs a list of one or more solids", "/shape/solids");
  // "rotate" and "translate" take three expressions.
  expectLoadError(replaced(kTwoBoxes, R"("max": [2, 2, 2])", R"("max": [2, 2, 2], "rotate": [10, 20])"),
                  "expected a list of 3 expressions", "/shape/solids/1/rotate");
  expectLoadError(replaced(kTwoBoxes, R"("type": "union",)", R"("type": "union", "translate": 5,)"),
                  "expected a list of 3 expressions", "/shape/translate");
  // A placement's expressions see the dimensions (none here: muparser's
  // message then ends "(known names: )").
  try {
    loadText(replaced(kTwoBoxes, R"("max": [2, 2, 2])", R"("max": [2, 2, 2], "translate": [0, "q", 0])"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(e.message().starts_with(
        "bad expression 'q': Unexpected token \"q\" found at position 0. (known names:"))
        << e.message();
    EXPECT_EQ(e.where().key_path, "/shape/solids/1/translate/1");
  }
  // Holes: a list of profiles of at least 3 points.
  const std::string plate = R"({"description": "x", "dimensions": [],
      "shape": {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
        "profile": [[0, 0], [10, 0], [10, 10], [0, 10]], "from": 0, "to": 1, "holes": HOLES}})";
  expectLoadError(replaced(plate, "HOLES", "[]"),
                  "expected a list of hole profiles, each a list of [a, b] points", "/shape/holes");
  expectLoadError(replaced(plate, "HOLES", "[[[1, 1], [2, 1]]]"),
                  "expected a hole profile: a list of at least 3 [a, b] points", "/shape/holes/0");
  expectLoadError(replaced(plate, "HOLES", "[[[1, 1], [2, 1], [2]]]"),
                  "expected a list of 2 expressions", "/shape/holes/0/2");
  // A bad hole profile is located at the hole.
  expectLoadError(replaced(plate, "HOLES", "[[[1, 1], [2, 1], [1, 2], [2, 2]]]"),
                  "at nominal values the profile is not a simple polygon: edges 1-2 and 3-0 touch "
                  "or cross",
                  "/shape/holes/0");
}

// N boxes in one union.
std::string manyBoxes(int n) {
  std::string solids;
  for (int i = 0; i < n; ++i)
    solids += fmt::format(R"({}{{"type": "box", "min": [{}, 0, 0], "max": [{}, 1, 1]}})",
                          i ? ", " : "", 2 * i, 2 * i + 1);
  return R"({"description": "many", "dimensions": [], "shape": {"type": "union", "solids": [)" +
         solids + "]}}";
}

TEST(Solid, AtMost64Pieces) {
  const PartModel max = loadText(manyBoxes(64));
  ASSERT_NE(max.csg(), nullptr);
  EXPECT_EQ(max.csg()->pieces(), 64u);
  EXPECT_TRUE(max.csg()->contains(topBit()));
  EXPECT_NEAR(signedVolume(max.mesh({})), 64.0, 1e-9);
  expectLoadError(manyBoxes(65),
                  "a part has at most 64 solids (holes of an extrusion count as solids)",
                  "/shape/solids/64");
  // Holes count: 63 boxes and a plate with one hole make 65.
  std::string text = manyBoxes(63);
  text.replace(text.rfind("]}}"), 3,
               R"(, {"type": "extrusion", "plane": ["x", "y"], "axis": "z",
                     "profile": [[0, 5], [10, 5], [10, 15], [0, 15]], "from": 0, "to": 1,
                     "holes": [[[1, 6], [2, 6], [2, 7]]]}]}})");
  expectLoadError(text, "a part has at most 64 solids (holes of an extrusion count as solids)",
                  "/shape/solids/63");
}

// Inside a tree, an STL file is a fixed solid that dimensions can cut or add
// to (docs/formats.md); its placement applies to it as to any solid.
TEST(Solid, StlPieceInATree) {
  writeTestFile("tetra.stl", kTetrahedronStl);
  const PartModel model = loadText(R"({"description": "box minus a tetrahedron",
    "dimensions": [{"name": "s", "nominal": 2, "min": 1, "max": 3, "unit": "mm"}],
    "shape": {"type": "difference", "solids": [
      {"type": "box", "min": [0, 0, 0], "max": ["s", "s", "s"]},
      {"type": "stl", "file": "tetra.stl", "translate": ["s - 0.5", 0, 0]}]}})");
  ASSERT_NE(model.csg(), nullptr);
  EXPECT_EQ(ends(*model.csg()), (std::vector<uint32_t>{12, 16}));
  const TriangleMesh mesh = model.mesh(model.values({{"s", 2.5}}));
  ASSERT_EQ(mesh.vertices.size(), 12u);
  double x_min = HUGE_VAL;
  for (size_t i = 8; i < 12; ++i) x_min = std::min(x_min, mesh.vertices[i].x());
  EXPECT_EQ(x_min, 2.0);
  EXPECT_NEAR(signedVolume(mesh.vertices, std::span(mesh.triangles).subspan(12)), 1.0 / 6, 1e-15);
}

// A piece that folds at some values names itself in the message.
TEST(Solid, AFoldingPieceIsNamed) {
  const PartModel model = loadText(R"({"description": "a plate and a pin", "dimensions": [
      {"name": "d", "nominal": 8, "min": 1, "max": 10, "unit": "mm"}],
    "shape": {"type": "difference", "solids": [
      {"type": "box", "min": [-10, -10, 0], "max": [10, 10, 2]},
      {"type": "cylinder", "axis": "z", "diameter": "d - 5", "from": -1, "to": 3, "segments": 16}]}})");
  std::vector<Vec3> vertices;
  EXPECT_FALSE(model.tryEvaluate(std::vector<double>{6.0}, vertices));
  const auto folded = model.tryEvaluate(std::vector<double>{4.0}, vertices);
  ASSERT_TRUE(folded);
  EXPECT_EQ(*folded,
            "solid /shape/solids/1: a profile point reached or crossed the axis (radius <= 0) at "
            "d=4 mm");
}

TEST(Solid, AutomaticSegmentsKeepTheChordErrorWithin1Micrometre) {
  const PartModel cylinder = loadText(R"({"description": "auto", "dimensions": [
      {"name": "d", "nominal": 20, "min": 10, "max": 30, "unit": "mm"}],
    "shape": {"type": "cylinder", "axis": "z", "diameter": "d", "from": 0, "to": 5}})");
  // Two poles and two rings of N.
  ASSERT_EQ((cylinder.vertexCount() - 2) % 2, 0u);
  const int n = static_cast<int>((cylinder.vertexCount() - 2) / 2);
  EXPECT_EQ(cylinder.triangles().size(), 4u * n);
  EXPECT_LE(10.0 * (1 - std::cos(kPi / n)), 0.001);
  EXPECT_GT(10.0 * (1 - std::cos(kPi / (n - 1))), 0.001) << "not the least such N";
  EXPECT_EQ(n, segmentsFor(10.0));
  EXPECT_EQ(n, segmentsForChordError(10.0, 0.001));
  // Vertices on the true circle, 2 pi / N apart; the greatest distance of the
  // surface from the circle is at mid-chord, the sagitta.
  const TriangleMesh mesh = cylinder.mesh(cylinder.nominalValues());
  std::vector<Vec3> ring;
  for (const Vec3& v : mesh.vertices)
    if (v.head<2>().norm() > 1 && v.z() == 0) ring.push_back(v);
  ASSERT_EQ(ring.size(), static_cast<size_t>(n));
  for (size_t k = 0; k < ring.size(); ++k) {
    EXPECT_NEAR(ring[k].head<2>().norm(), 10.0, 1e-13);
    const Vec3& next = ring[(k + 1) % ring.size()];
    EXPECT_NEAR((next - ring[k]).norm(), 20.0 * std::sin(kPi / n), 1e-12);
    const double sagitta = 10.0 - (0.5 * (ring[k] + next)).head<2>().norm();
    EXPECT_LE(sagitta, 0.001);
    EXPECT_GT(sagitta, 0.0009);
  }
  // Small radii get at least 8; explicit segments win.
  EXPECT_EQ(segmentsForChordError(0.0005, 0.001), 8);
  EXPECT_EQ(segmentsForChordError(0.01, 0.001), 8);
  const PartModel explicit_segments = loadText(R"({"description": "twelve", "dimensions": [],
    "shape": {"type": "cylinder", "axis": "x", "diameter": 20, "from": 0, "to": 5, "segments": 12}})");
  EXPECT_EQ(explicit_segments.vertexCount(), 2u * 12 + 2);
  // The reference parts' holes and shaft: Solid.BracketAndShaftLoadAsCsgParts
  // finds their triangle counts from segmentsFor(), so they obey it too.
}

}  // namespace
}  // namespace xgauge
