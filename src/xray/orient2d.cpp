#include "orient2d.h"

#include <array>

namespace xgauge::raster {

namespace {

// Error-free transformations: a + b = s + e and a * b = p + e exactly.
inline void twoSum(double a, double b, double& s, double& e) {
  s = a + b;
  const double bv = s - a;
  const double av = s - bv;
  e = (a - av) + (b - bv);
}
inline void twoProduct(double a, double b, double& p, double& e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

}  // namespace

int exactOrientSign(double ax, double ay, double bx, double by, double px, double py) {
  // Each difference as an exact two-term expansion.
  double d[4][2];
  twoSum(ax, -px, d[0][0], d[0][1]);  // ax - px
  twoSum(by, -py, d[1][0], d[1][1]);  // by - py
  twoSum(ay, -py, d[2][0], d[2][1]);  // ay - py
  twoSum(bx, -px, d[3][0], d[3][1]);  // bx - px
  // The 16 exact partial products of (d0)(d1) - (d2)(d3).
  std::array<double, 16> terms{};
  size_t n = 0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      twoProduct(d[0][i], d[1][j], terms[n], terms[n + 1]);
      n += 2;
      twoProduct(-d[2][i], d[3][j], terms[n], terms[n + 1]);
      n += 2;
    }
  // Grow a nonoverlapping expansion (Shewchuk's GROW-EXPANSION); its sign is
  // the sign of its largest nonzero component.
  std::array<double, 17> expansion{};
  size_t length = 0;
  for (double term : terms) {
    double q = term;
    for (size_t k = 0; k < length; ++k) {
      double s, e;
      twoSum(q, expansion[k], s, e);
      expansion[k] = e;
      q = s;
    }
    expansion[length++] = q;
  }
  for (size_t k = length; k-- > 0;)
    if (expansion[k] != 0.0) return expansion[k] > 0 ? 1 : -1;
  return 0;
}

}  // namespace xgauge::raster
