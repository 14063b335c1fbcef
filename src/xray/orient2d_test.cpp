#include "orient2d.h"

#include <gtest/gtest.h>

#include <random>

namespace xgauge::raster {
namespace {

// Exact reference for coordinates that are integers times 2^-28 (|c| < 2^40):
// the determinant in 128-bit integers.
__extension__ typedef __int128 Int128;

int referenceSign(double ax, double ay, double bx, double by, double px, double py) {
  auto fixed = [](double v) { return static_cast<Int128>(std::ldexp(v, 28)); };
  const Int128 det = (fixed(ax) - fixed(px)) * (fixed(by) - fixed(py)) -
                     (fixed(ay) - fixed(py)) * (fixed(bx) - fixed(px));
  return det > 0 ? 1 : (det < 0 ? -1 : 0);
}

TEST(Orient2d, ExactOnNearlyCollinearPoints) {
  std::mt19937_64 rng(7);
  // Vertices on a 2^-20 grid within +-1024, points on their line at t = j / 256
  // (exactly representable), then nudged by -2..2 steps of a 2^-28 grid.
  std::uniform_int_distribution<int64_t> coord(-(int64_t{1} << 30), int64_t{1} << 30);
  std::uniform_int_distribution<int64_t> fraction(0, 256), jitter(-2, 2);
  auto grid = [&](int64_t v, int exponent) { return std::ldexp(static_cast<double>(v), exponent); };
  int ties = 0, filter_misses = 0;
  for (int i = 0; i < 200000; ++i) {
    const double ax = grid(coord(rng), -20), ay = grid(coord(rng), -20);
    const double bx = grid(coord(rng), -20), by = grid(coord(rng), -20);
    const double t = grid(fraction(rng), -8);
    const double px = ax + t * (bx - ax) + grid(jitter(rng), -28);
    const double py = ay + t * (by - ay) + grid(jitter(rng), -28);
    const int expected = referenceSign(ax, ay, bx, by, px, py);
    ASSERT_EQ(exactOrientSign(ax, ay, bx, by, px, py), expected);
    const int s = orientSign(ax, ay, bx, by, px, py);
    if (expected != 0) {
      ASSERT_EQ(s, expected);
    } else {
      ++ties;
      ASSERT_NE(s, 0);
    }
    // Antisymmetry holds exactly, ties included.
    ASSERT_EQ(orientSign(bx, by, ax, ay, px, py), -s);
  }
  EXPECT_GT(ties, 1000);  // the test does exercise exact ties
  // Full 53-bit coordinates on a 2^-60 grid (|c| < 2^-7) and points rounded
  // next to the line: here plain double arithmetic often gets the sign wrong.
  std::uniform_int_distribution<int64_t> wide(-(int64_t{1} << 53) + 1, (int64_t{1} << 53) - 1);
  std::uniform_real_distribution<double> along(0.0, 1.0);
  auto fine = [&](double v) { return std::ldexp(std::round(std::ldexp(v, 60)), -60); };
  for (int i = 0; i < 200000; ++i) {
    const double ax = grid(wide(rng), -60), ay = grid(wide(rng), -60);
    const double bx = grid(wide(rng), -60), by = grid(wide(rng), -60);
    const double t = along(rng);
    const double px = fine(ax + t * (bx - ax)), py = fine(ay + t * (by - ay));
    auto fixed = [](double v) { return static_cast<Int128>(std::ldexp(v, 60)); };
    const Int128 det = (fixed(ax) - fixed(px)) * (fixed(by) - fixed(py)) -
                       (fixed(ay) - fixed(py)) * (fixed(bx) - fixed(px));
    const int expected = det > 0 ? 1 : (det < 0 ? -1 : 0);
    ASSERT_EQ(exactOrientSign(ax, ay, bx, by, px, py), expected);
    const double plain = (ax - px) * (by - py) - (ay - py) * (bx - px);
    if ((plain > 0) - (plain < 0) != expected) ++filter_misses;
  }
  EXPECT_GT(filter_misses, 1000);
}

TEST(Orient2d, TieBreakIsASymbolicPerturbation) {
  // p on a horizontal edge: decided by the x order of the edge.
  EXPECT_EQ(orientSign(0, 0, 1, 0, 0.5, 0), 1);
  EXPECT_EQ(orientSign(1, 0, 0, 0, 0.5, 0), -1);
  // p on a non-horizontal edge: decided by ay - by.
  EXPECT_EQ(orientSign(0, 1, 0, 0, 0, 0.5), 1);
  EXPECT_EQ(orientSign(0, 0, 0, 1, 0, 0.5), -1);
  // Degenerate edge.
  EXPECT_EQ(orientSign(1, 1, 1, 1, 0, 0), 0);
}

}  // namespace
}  // namespace xgauge::raster
