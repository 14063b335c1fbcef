#include "xgauge/core/transform.h"
#include "xgauge/core/error.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

TEST(Pose, EulerConventionIsZYXAboutFixedAxes) {
  // 90 degrees about x maps part y to world z.
  const Pose px = Pose::fromEulerDeg({90, 0, 0}, Vec3::Zero());
  EXPECT_TRUE(px.apply(Vec3::UnitY()).isApprox(Vec3::UnitZ(), 1e-15));
  // x first, then z: part y -> (x) world z -> (z about world z) stays z.
  const Pose pxz = Pose::fromEulerDeg({90, 0, 90}, Vec3::Zero());
  EXPECT_TRUE(pxz.apply(Vec3::UnitY()).isApprox(Vec3::UnitZ(), 1e-15));
  // part x -> (x) x -> (z 90) world y.
  EXPECT_TRUE(pxz.apply(Vec3::UnitX()).isApprox(Vec3::UnitY(), 1e-15));
}

TEST(Pose, EulerRoundTrip) {
  const Vec3 angles(12.5, -33.0, 171.25);
  const Pose pose = Pose::fromEulerDeg(angles, Vec3(1, 2, 3));
  EXPECT_LT((pose.eulerDeg() - angles).cwiseAbs().maxCoeff(), 1e-12);
  const Pose again = Pose::fromMatrix(pose.matrix());
  EXPECT_LT((again.matrix() - pose.matrix()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(pose.rowMajor()[3], 1.0);
  EXPECT_EQ(pose.rowMajor()[7], 2.0);
  EXPECT_EQ(pose.rowMajor()[15], 1.0);
}

TEST(Pose, RejectsNonRotation) {
  Mat4 m = Mat4::Identity();
  m(0, 0) = 2.0;
  EXPECT_THROW(Pose::fromMatrix(m), Error);
  m = Mat4::Identity();
  m(0, 0) = -1.0;  // reflection
  EXPECT_THROW(Pose::fromMatrix(m), Error);
}

}  // namespace
}  // namespace xgauge
