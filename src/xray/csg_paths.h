// Path lengths through a CSG part (geometry/csg.h), private to the xray
// module.
//
// Method. Every piece is a closed surface that the rasterizer covers
// watertightly on its own, so along each sample ray its crossings alternate
// entry and exit. A first pass sums sigma / m as for a single solid, but only
// for pieces that are the part by themselves (Csg::alone), and notes which
// piece covers each sample; a sample covered by one piece only is then
// exact already (the ray misses every other piece). The "mixed" samples,
// covered by several pieces, get a second pass that stores their crossings
// (depth 1 / m, piece, entry or exit), sorts them along the ray and walks
// them, keeping each piece's winding number: the part's path is the sum of
// the segments where the tree says "inside". Crossings at equal depth give
// segments of zero length, whatever their order.
//
// Why not the boolean mesh: a mesh boolean (CGAL corefinement) per
// evaluation of a fit costs milliseconds to tens of milliseconds for a
// bracket with three holes, more than the render itself at the pyramid
// levels a fit spends most evaluations on, and its vertices come out of
// exact constructions rounded back to doubles, which the exact watertight
// rasterizer then has to trust. Along-the-ray booleans reuse the watertight
// coverage of each closed piece and cost only where pieces overlap on the
// detector (bench/render_bench.cpp measures both parts).
//
// Deterministic: each sample's crossings are gathered in mesh order and
// sorted stably, whatever the thread count.
#pragma once

#include "rasterizer.h"

#include "xgauge/geometry/csg.h"

#include <cstdint>
#include <span>
#include <vector>

namespace xgauge::raster {

// Per-thread buffers, reused from band to band.
struct CsgScratch {
  struct Crossing {
    double depth;       // 1 / m
    uint32_t code;      // piece << 1 | 1 for an exit
    uint32_t triangle;  // the mesh triangle crossed
  };
  std::vector<uint8_t> owner;  // per sample: the only piece seen, or kNone / kMixed
  std::vector<uint32_t> count, start;
  std::vector<Crossing> crossings;
  std::vector<int> row_lo, row_hi, col_lo, col_hi;  // mixed samples per line
};

// The band of sample rows [row_begin, row_end) and sample columns
// [col_begin, col_begin + width): writes each sample's path through the part
// divided by |P - S| into `sum` (row-major, zeroed by the caller), from the
// triangles `bin` of `scene` (mesh order) whose `piece` fields are set.
//
// With `terms`, also tells which triangle's depth enters each sample's path
// with which sign (the derivative render, derivatives.cpp): add() for every
// term of the sum, and for a sample whose crossings are walked, reset() and
// then add() for each crossing that bounds the part's path.
class PathTerms {
 public:
  virtual ~PathTerms() = default;
  virtual void add(int row, int column, uint32_t triangle, double sign) = 0;
  virtual void reset(int row, int column) = 0;
};
void accumulateCsgBand(const SceneSetup& scene, std::span<const uint32_t> bin, const Csg& csg,
                       int row_begin, int row_end, int col_begin, int width, double* sum,
                       CsgScratch& scratch, PathTerms* terms = nullptr);

// Sets each triangle's `piece` from the CSG's triangle ranges.
void assignPieces(const Csg& csg, SceneSetup& scene);

}  // namespace xgauge::raster
