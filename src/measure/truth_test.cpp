// The true material curve a study measures with: fitted over the paths the
// dataset's shots show, to a residual far below a radiograph's noise.
#include "xgauge/measure/truth.h"

#include "xgauge/geometry/part_model.h"
#include "xgauge/xray/machine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace xgauge {
namespace {

const std::string kRoot = XGAUGE_SOURCE_DIR;

// A filtered tube's curve: a steep soft component that only thin paths see,
// and the hard ones, tabulated to 120 mm as the virtual lab does (its table
// runs to the part's bounding-box diagonal).
DatasetTruth tabulated() {
  const ExponentialSum curve({{0.12, 1.1}, {0.25, 0.30}, {0.45, 0.085}, {0.18, 0.045}});
  DatasetTruth truth;
  truth.folder = "/nowhere";
  for (int i = 0; i <= 600; ++i) {
    const double x = 0.2 * i;
    truth.path_mm.push_back(x);
    truth.transmission.push_back(curve.transmission(x));
  }
  return truth;
}

double largestError(const ExponentialSum& fitted, const DatasetTruth& truth, double up_to_mm) {
  double worst = 0.0;
  for (size_t i = 0; i < truth.path_mm.size() && truth.path_mm[i] <= up_to_mm; ++i)
    worst =
        std::max(worst, std::abs(fitted.transmission(truth.path_mm[i]) - truth.transmission[i]));
  return worst;
}

TEST(TrueCurve, FitsThePathsTheShotsShowToFarBelowTheNoise) {
  const DatasetTruth truth = tabulated();
  const ExponentialSum fitted = fitTrueCurve(truth, 22.0);
  EXPECT_LE(largestError(fitted, truth, 22.0), 1e-4);
  EXPECT_NE(fitted.description().find("over 0-22.0 mm"), std::string::npos) << fitted.description();
}

TEST(TrueCurve, OneFitOfThreeTermsOverTheWholeTableMissesTheThinPaths) {
  // Why the range matters: three terms spread over 0-120 mm leave an error
  // at the thin paths that fitTrueCurve's range and terms remove.
  const DatasetTruth truth = tabulated();
  const ExponentialSum whole = fitTrueCurve(truth, 1e9, 3, 1.0);  // 3 terms, whole table
  EXPECT_EQ(whole.terms().size(), 3u);
  EXPECT_GT(largestError(whole, truth, 22.0), 5e-4);
}

TEST(TrueCurve, TheLongestPathOfAnUprightCuboidIsItsDepthAlongTheBeam) {
  // A 20 x 30 x 12 mm cuboid at 500 mm from a source 1000 mm from the
  // detector: every ray through both z faces crosses 12 / cos(angle) mm, and
  // the steepest such ray (through a corner) is 1.7 degrees off the axis.
  const PartModel part = PartModel::load(kRoot + "/parts/cuboid.json");
  DatasetTruth truth;
  truth.dimensions = {{"size_x", 20.0}, {"size_y", 30.0}, {"size_z", 12.0}};
  TruthShot shot;
  shot.pose.translation_mm = Vec3(0.0, 0.0, 500.0);
  truth.shots = {shot};
  Machine machine;
  machine.columns = machine.rows = 2048;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.1;
  machine.cx_px = machine.cy_px = 1024.0;
  const double longest = longestTruePathMm(truth, part, machine);
  EXPECT_GE(longest, 12.0 - 1e-6);
  EXPECT_LE(longest, 12.0 / std::cos(std::atan(std::hypot(10.0, 15.0) / 494.0)) + 1e-6);
}

}  // namespace
}  // namespace xgauge
