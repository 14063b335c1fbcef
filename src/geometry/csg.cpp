#include "xgauge/geometry/csg.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <array>

namespace xgauge {

Csg::Csg(std::vector<uint32_t> piece_triangle_end, std::vector<Node> program)
    : piece_triangle_end_(std::move(piece_triangle_end)), program_(std::move(program)) {
  const size_t n = piece_triangle_end_.size();
  if (n == 0 || n > kMaxPieces) fail("a part has 1 to {} solids, this one has {}", kMaxPieces, n);
  XG_CHECK(std::is_sorted(piece_triangle_end_.begin(), piece_triangle_end_.end()),
           "piece triangle ranges out of order");
  // Well formed: the stack never runs dry and ends with one value; every
  // piece appears exactly once.
  std::vector<int> used(n, 0);
  size_t depth = 0;
  for (const Node& node : program_) {
    if (node.op == Op::kPiece) {
      XG_CHECK(node.arg < n, "CSG piece {} of {}", node.arg, n);
      ++used[node.arg];
      ++depth;
    } else {
      XG_CHECK(node.arg >= 1 && node.arg <= depth, "CSG operation with {} operands on {}", node.arg,
               depth);
      depth -= node.arg - 1;
    }
  }
  XG_CHECK(depth == 1, "CSG program leaves {} values", depth);
  XG_CHECK(std::all_of(used.begin(), used.end(), [](int u) { return u == 1; }),
           "every CSG piece must appear once");

  if (n <= 16) {
    table_.resize(size_t{1} << n);
    for (uint64_t mask = 0; mask < table_.size(); ++mask) table_[mask] = evaluate(mask);
  }
  for (size_t i = 0; i < n; ++i) alone_.push_back(contains(uint64_t{1} << i));
}

uint32_t Csg::pieceOfTriangle(uint32_t t) const {
  const auto it = std::upper_bound(piece_triangle_end_.begin(), piece_triangle_end_.end(), t);
  XG_CHECK(it != piece_triangle_end_.end(), "triangle {} beyond the last piece", t);
  return static_cast<uint32_t>(it - piece_triangle_end_.begin());
}

bool Csg::evaluate(uint64_t inside) const {
  // Postfix evaluation; the stack holds at most one value per piece.
  std::array<bool, kMaxPieces> stack{};
  size_t top = 0;
  for (const Node& node : program_) {
    if (node.op == Op::kPiece) {
      stack[top++] = ((inside >> node.arg) & 1) != 0;
      continue;
    }
    const size_t first = top - node.arg;
    bool value = stack[first];
    for (size_t k = first + 1; k < top; ++k) {
      switch (node.op) {
        case Op::kUnion:
          value = value || stack[k];
          break;
        case Op::kIntersection:
          value = value && stack[k];
          break;
        case Op::kDifference:
          value = value && !stack[k];
          break;
        case Op::kPiece:
          break;
      }
    }
    top = first;
    stack[top++] = value;
  }
  return stack[0];
}

}  // namespace xgauge
