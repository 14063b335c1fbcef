// Constructive solid geometry: a part as a boolean combination (union,
// difference, intersection) of closed solids, its "pieces". Each piece is a
// contiguous range of a mesh's triangles and is closed on its own; the tree
// says which points belong to the part given which pieces contain them.
//
// The renderer never builds the boolean mesh: along each ray it sorts the
// pieces' surface crossings and keeps the segments the tree accepts (see
// src/xray/csg_paths.h), which is exact, watertight and cheap to repeat for
// every evaluation of a fit.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace xgauge {

class Csg {
 public:
  // At most this many pieces: the renderer keeps a ray's inside/outside state
  // of every piece in one 64-bit mask.
  static constexpr size_t kMaxPieces = 64;

  enum class Op : uint8_t { kPiece, kUnion, kDifference, kIntersection };
  // One step of the tree in postfix order: kPiece pushes "inside piece
  // `arg`"; an operation pops its `arg` operands (at least 1) and pushes the
  // result. Difference: the first operand minus all the others.
  struct Node {
    Op op = Op::kPiece;
    uint32_t arg = 0;
  };

  // `piece_triangle_end[i]`: one past the last triangle of piece i (pieces are
  // consecutive, starting at triangle 0). Throws Error for no pieces or more
  // than kMaxPieces; a malformed program (a piece missing or used twice, an
  // operation without its operands, more than one value left) is a bug of
  // the caller and aborts (XG_CHECK).
  Csg(std::vector<uint32_t> piece_triangle_end, std::vector<Node> program);

  size_t pieces() const { return piece_triangle_end_.size(); }
  std::span<const uint32_t> pieceTriangleEnds() const { return piece_triangle_end_; }
  std::span<const Node> program() const { return program_; }
  // The piece that triangle `t` belongs to (binary search).
  uint32_t pieceOfTriangle(uint32_t t) const;

  // Whether a point inside exactly the pieces whose bits are set in `inside`
  // (bit i: piece i) belongs to the part.
  bool contains(uint64_t inside) const {
    return inside < table_.size() ? table_[inside] != 0 : evaluate(inside);
  }
  // contains() with piece i alone: a ray that meets no other piece gets its
  // path through piece i when true, and nothing when false.
  bool alone(size_t piece) const { return alone_[piece] != 0; }

 private:
  bool evaluate(uint64_t inside) const;

  std::vector<uint32_t> piece_triangle_end_;
  std::vector<Node> program_;
  std::vector<uint8_t> table_;  // contains() for every mask, when pieces() <= 16
  std::vector<uint8_t> alone_;
};

}  // namespace xgauge
