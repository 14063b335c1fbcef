#include "csg_paths.h"

#include "xgauge/core/error.h"

#include <algorithm>
#include <array>

namespace xgauge::raster {
namespace {

constexpr uint8_t kNone = 0xff;
constexpr uint8_t kMixed = 0xfe;
static_assert(Csg::kMaxPieces < kMixed);

}  // namespace

void assignPieces(const Csg& csg, SceneSetup& scene) {
  const auto ends = csg.pieceTriangleEnds();
  XG_CHECK(ends.back() == scene.triangles.size(), "CSG of {} triangles for a mesh of {}",
           ends.back(), scene.triangles.size());
  uint32_t begin = 0;
  for (size_t p = 0; p < ends.size(); ++p) {
    for (uint32_t i = begin; i < ends[p]; ++i) scene.triangles[i].piece = static_cast<uint8_t>(p);
    begin = ends[p];
  }
}

void accumulateCsgBand(const SceneSetup& scene, std::span<const uint32_t> bin, const Csg& csg,
                       int row_begin, int row_end, int col_begin, int width, double* sum,
                       CsgScratch& scratch, PathTerms* terms) {
  const int rows = row_end - row_begin;
  const size_t samples = static_cast<size_t>(rows) * static_cast<size_t>(width);
  const auto index = [&](int row, int column) {
    return static_cast<size_t>(row - row_begin) * static_cast<size_t>(width) +
           static_cast<size_t>(column - col_begin);
  };

  // Pass 1: sums of the pieces that stand alone, who covers each sample, and
  // how many crossings it has.
  std::vector<uint8_t>& owner = scratch.owner;
  std::vector<uint32_t>& count = scratch.count;
  owner.assign(samples, kNone);
  count.assign(samples, 0);
  for (uint32_t i : bin) {
    const TriangleSetup& t = scene.triangles[i];
    const uint8_t piece = t.piece;
    const bool alone = csg.alone(piece);
    const double sigma = t.sigma;
    // Two plain loops per span (the compiler vectorizes both); pieces that
    // are nothing by themselves (holes) only mark their samples.
    forEachSpan(t, row_begin, row_end, [&](int line, int k0, int k1) {
      if (terms && alone)
        for (int k = k0; k <= k1; ++k)
          t.by_rows ? terms->add(line, k, i, sigma) : terms->add(k, line, i, sigma);
      if (t.by_rows) {
        const size_t first = index(line, k0);
        const int n = k1 - k0 + 1;
        if (alone) {
          double* row = sum + first;
          for (int j = 0; j < n; ++j) row[j] += sigma * inverseMagnification(t, line, k0 + j);
        }
        uint8_t* o = owner.data() + first;
        for (int j = 0; j < n; ++j) o[j] = (o[j] == kNone || o[j] == piece) ? piece : kMixed;
        uint32_t* c = count.data() + first;
        for (int j = 0; j < n; ++j) ++c[j];
      } else {
        for (int k = k0; k <= k1; ++k) {
          const size_t s = index(k, line);
          if (alone) sum[s] += sigma * inverseMagnification(t, k, line);
          owner[s] = (owner[s] == kNone || owner[s] == piece) ? piece : kMixed;
          ++count[s];
        }
      }
    });
  }

  // Where the mixed samples are, per sample row and per sample column.
  scratch.row_lo.assign(static_cast<size_t>(rows), width);
  scratch.row_hi.assign(static_cast<size_t>(rows), -1);
  scratch.col_lo.assign(static_cast<size_t>(width), rows);
  scratch.col_hi.assign(static_cast<size_t>(width), -1);
  bool any = false;
  for (int r = 0; r < rows; ++r) {
    const uint8_t* o = owner.data() + static_cast<size_t>(r) * static_cast<size_t>(width);
    for (int c = 0; c < width; ++c) {
      if (o[c] != kMixed) continue;
      any = true;
      scratch.row_lo[r] = std::min(scratch.row_lo[r], c);
      scratch.row_hi[r] = c;
      scratch.col_lo[c] = std::min(scratch.col_lo[c], r);
      scratch.col_hi[c] = r;
    }
  }
  if (!any) return;

  // Visits the mixed samples of `t` only: spans clipped to the mixed range
  // of their line first.
  const auto for_each_mixed = [&](const TriangleSetup& t, auto&& visit) {
    forEachSpan(t, row_begin, row_end, [&](int line, int k0, int k1) {
      if (t.by_rows) {
        const size_t r = static_cast<size_t>(line - row_begin);
        k0 = std::max(k0, scratch.row_lo[r] + col_begin);
        k1 = std::min(k1, scratch.row_hi[r] + col_begin);
        for (int k = k0; k <= k1; ++k)
          if (owner[index(line, k)] == kMixed) visit(line, k);
      } else {
        const size_t c = static_cast<size_t>(line - col_begin);
        k0 = std::max(k0, scratch.col_lo[c] + row_begin);
        k1 = std::min(k1, scratch.col_hi[c] + row_begin);
        for (int k = k0; k <= k1; ++k)
          if (owner[index(k, line)] == kMixed) visit(k, line);
      }
    });
  };

  // Pass 2: place and gather the crossings of the mixed samples.
  std::vector<uint32_t>& start = scratch.start;
  start.resize(samples);
  uint32_t total = 0;
  for (size_t s = 0; s < samples; ++s) {
    start[s] = total;
    total += owner[s] == kMixed ? count[s] : 0;
  }
  scratch.crossings.resize(total);
  std::fill(count.begin(), count.end(), 0u);
  for (uint32_t i : bin) {
    const TriangleSetup& t = scene.triangles[i];
    const uint32_t code = static_cast<uint32_t>(t.piece) << 1 | (t.sigma > 0 ? 1u : 0u);
    for_each_mixed(t, [&](int row, int column) {
      const size_t s = index(row, column);
      scratch.crossings[start[s] + count[s]++] = {inverseMagnification(t, row, column), code, i};
    });
  }

  // Walk each mixed sample's crossings along the ray.
  std::array<int, Csg::kMaxPieces> winding{};
  for (size_t s = 0; s < samples; ++s) {
    if (owner[s] != kMixed) continue;
    CsgScratch::Crossing* first = scratch.crossings.data() + start[s];
    CsgScratch::Crossing* last = first + count[s];
    // Insertion sort: a handful of crossings, stable.
    for (CsgScratch::Crossing* c = first + 1; c < last; ++c) {
      const CsgScratch::Crossing value = *c;
      CsgScratch::Crossing* hole = c;
      while (hole > first && hole[-1].depth > value.depth) {
        *hole = hole[-1];
        --hole;
      }
      *hole = value;
    }
    const int row = row_begin + static_cast<int>(s / static_cast<size_t>(width));
    const int column = col_begin + static_cast<int>(s % static_cast<size_t>(width));
    if (terms) terms->reset(row, column);
    uint64_t inside = 0;
    bool in_part = false;
    double path = 0.0;
    for (const CsgScratch::Crossing* c = first; c < last; ++c) {
      const uint32_t piece = c->code >> 1;
      const int w = winding[piece] += (c->code & 1) ? -1 : 1;
      const uint64_t bit = uint64_t{1} << piece;
      inside = w > 0 ? inside | bit : inside & ~bit;
      const bool now = csg.contains(inside);
      if (now != in_part) {
        path += now ? -c->depth : c->depth;
        if (terms) terms->add(row, column, c->triangle, now ? -1.0 : 1.0);
        in_part = now;
      }
    }
    for (const CsgScratch::Crossing* c = first; c < last; ++c) winding[c->code >> 1] = 0;
    sum[s] = path;
  }
}

}  // namespace xgauge::raster
