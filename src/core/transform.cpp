#include "xgauge/core/transform.h"

#include "xgauge/core/error.h"

#include <cmath>

namespace xgauge {

Pose Pose::fromEulerDeg(const Vec3& angles_deg, const Vec3& translation_mm) {
  const Vec3 a = angles_deg * kDegToRad;
  Pose pose;
  pose.rotation = (Eigen::AngleAxisd(a.z(), Vec3::UnitZ()) *
                   Eigen::AngleAxisd(a.y(), Vec3::UnitY()) *
                   Eigen::AngleAxisd(a.x(), Vec3::UnitX()))
                      .toRotationMatrix();
  pose.translation_mm = translation_mm;
  return pose;
}

Pose Pose::fromMatrix(const Mat4& m) {
  Pose pose;
  pose.rotation = m.topLeftCorner<3, 3>();
  pose.translation_mm = m.topRightCorner<3, 1>();
  const double orthogonality = (pose.rotation * pose.rotation.transpose() - Mat3::Identity())
                                   .cwiseAbs()
                                   .maxCoeff();
  if (orthogonality > 1e-9 || pose.rotation.determinant() < 0)
    fail("pose matrix is not a rotation (R R^T differs from I by {:.3g})", orthogonality);
  if (m.row(3).cwiseAbs().head<3>().maxCoeff() != 0.0 || m(3, 3) != 1.0)
    fail("pose matrix's last row must be 0 0 0 1");
  return pose;
}

Mat4 Pose::matrix() const {
  Mat4 m = Mat4::Identity();
  m.topLeftCorner<3, 3>() = rotation;
  m.topRightCorner<3, 1>() = translation_mm;
  return m;
}

Vec3 Pose::eulerDeg() const {
  // R = Rz Ry Rx: R(2,0) = -sin(ry).
  const Mat3& r = rotation;
  const double ry = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  double rx, rz;
  if (std::abs(r(2, 0)) < 1.0 - 1e-12) {
    rx = std::atan2(r(2, 1), r(2, 2));
    rz = std::atan2(r(1, 0), r(0, 0));
  } else {  // gimbal lock: put everything into rz
    rx = 0.0;
    rz = std::atan2(-r(0, 1), r(1, 1));
  }
  return Vec3(rx, ry, rz) * kRadToDeg;
}

std::array<double, 16> Pose::rowMajor() const {
  std::array<double, 16> out{};
  const Mat4 m = matrix();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) out[static_cast<size_t>(4 * i + j)] = m(i, j);
  return out;
}

}  // namespace xgauge
