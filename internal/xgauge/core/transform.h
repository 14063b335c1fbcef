// Vectors and rigid transforms (Eigen). Frames follow docs/conventions.md: a part pose
// maps part coordinates to world coordinates, x_world = R * x_part + t.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <numbers>

namespace xgauge {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;

constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// A rigid transform world_from_part.
//
// Euler convention (used in every file a person reads or writes): angles
// (rx, ry, rz) in degrees are rotations about the fixed world axes applied in
// the order x, then y, then z:  R = Rz(rz) * Ry(ry) * Rx(rx).
// Result files always carry the full 4x4 matrix as well.
struct Pose {
  Mat3 rotation = Mat3::Identity();
  Vec3 translation_mm = Vec3::Zero();

  static Pose fromEulerDeg(const Vec3& angles_deg, const Vec3& translation_mm);
  // Throws xgauge::Error if the upper-left 3x3 is not a rotation (1e-9) or
  // the last row is not (0, 0, 0, 1).
  static Pose fromMatrix(const Mat4& world_from_part);

  Vec3 apply(const Vec3& part_point) const { return rotation * part_point + translation_mm; }
  Mat4 matrix() const;
  // (rx, ry, rz) in degrees with ry in [-90, 90]; exact round trip through
  // fromEulerDeg away from gimbal lock.
  Vec3 eulerDeg() const;
  // Row-major 4x4, for result files.
  std::array<double, 16> rowMajor() const;
};

}  // namespace xgauge
