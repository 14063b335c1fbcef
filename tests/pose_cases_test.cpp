// The rotated shot's pose found from round starting values (issue 45;
// tests/pose_cases.h): a few cases of bench/pose_sweep's sweep, among them
// ones whose search's best pose was a wrong minimum (the joint fit needs a
// later pose candidate), each measured and compared with the truth.
#include "pose_cases.h"

#include <gtest/gtest.h>

namespace xgauge::pose_cases {
namespace {

const fs::path kRoot = XGAUGE_SOURCE_DIR;

struct Listed {
  int part, index;
};

// Cases of bench/pose_sweep's sweep of 20 per part: the prism and the
// bracket turned nearly 80 and 90 degrees; the shaft turned 7 degrees,
// where the search's best pose was the one its symmetry mirrors (42.7 deg
// off, passed by the rule at 1.98 times the noise), and 25 degrees, where
// the search's best failed the rule and a retry from other starts found
// the pose (2.5 times the time) before the pose candidates.
const Listed kCases[] = {{0, 17}, {1, 19}, {2, 1}, {2, 5}};

class PoseCases : public ::testing::TestWithParam<Listed> {};

TEST_P(PoseCases, TrueRotationFound) {
  const Listed listed = GetParam();
  const PoseCase c = sweepCase(listed.part, listed.index, 20);
  const fs::path folder =
      fs::temp_directory_path() / fmt::format("xgauge_pose_cases_{}_{}", listed.part, listed.index);
  fs::remove_all(folder);
  const PoseOutcome o = runCase(c, kRoot, folder);
  SCOPED_TRACE(o.summary);
  ASSERT_TRUE(o.in_bounds);
  EXPECT_TRUE(o.measured);
  EXPECT_LE(o.rotation_error_deg, 0.5);
  EXPECT_LE(o.max_dimension_error_mm, 0.1);
  EXPECT_LE(o.worst_misfit_ratio, 4.0);
  if (!HasFailure()) fs::remove_all(folder);
}

INSTANTIATE_TEST_SUITE_P(Sweep, PoseCases, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<Listed>& param) {
                           return parts()[static_cast<size_t>(param.param.part)].name +
                                  std::to_string(param.param.index);
                         });

}  // namespace
}  // namespace xgauge::pose_cases
