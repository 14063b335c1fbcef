// Union-find over indices whose root is the smallest index of a set: sets
// of mesh vertices welded together (mesh.cpp), of faces on one surface
// (face_moves.cpp). Path halving; deterministic.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

namespace xgauge {

class SmallestRootSets {
 public:
  explicit SmallestRootSets(size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), uint32_t{0});
  }
  uint32_t root(uint32_t v) {
    while (parent_[v] != v) v = parent_[v] = parent_[parent_[v]];
    return v;
  }
  void join(uint32_t a, uint32_t b) {
    a = root(a), b = root(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<uint32_t> parent_;
};

}  // namespace xgauge
