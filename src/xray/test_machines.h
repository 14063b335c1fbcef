// Test helpers: the reference parts' folder, a square test detector, posed
// meshes and random poses.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <Eigen/Geometry>

#include <random>
#include <string>
#include <vector>

namespace xgauge::testing {

inline const std::string kParts = std::string(XGAUGE_SOURCE_DIR) + "/parts/";

// size x size pixels of `pitch_mm`, source 1000 mm away, principal point at
// the centre.
inline Machine squareMachine(int size, double pitch_mm) {
  Machine m;
  m.source_detector_distance_mm = 1000.0;
  m.columns = m.rows = size;
  m.pitch_u_mm = m.pitch_v_mm = pitch_mm;
  m.cx_px = m.cy_px = 0.5 * size;
  return m;
}

// `mesh` (with its CSG, if any) at `pose`; the world vertices live in `storage`.
inline WorldMesh posed(const TriangleMesh& mesh, const Pose& pose, std::vector<Vec3>& storage) {
  poseVertices(pose, mesh.vertices, storage);
  return {storage, mesh.triangles, mesh.csg.get()};
}

// A random rotation about `centre` (part frame), the centre then placed at
// (x, y, z_mid) with x, y, z - z_mid uniform in [-spread, spread].
inline Pose randomPose(std::mt19937_64& rng, const Vec3& centre, double z_mid, double spread_mm) {
  std::normal_distribution<double> gauss;
  Eigen::Quaterniond q(gauss(rng), gauss(rng), gauss(rng), gauss(rng));
  q.normalize();
  std::uniform_real_distribution<double> offset(-spread_mm, spread_mm);
  Pose pose;
  pose.rotation = q.toRotationMatrix();
  pose.translation_mm =
      Vec3(offset(rng), offset(rng), z_mid + offset(rng)) - pose.rotation * centre;
  return pose;
}

}  // namespace xgauge::testing
