// Dimensions on the faces of STEP solids (issue 58): what placing every
// vertex for one evaluation costs, against a 1024^2 render of the same part
// at the same values, timed in the same run.
//
//   build/bench/step_faces_bench
//
// Parts: examples/step/prism_a.json and bracket.json (planes and
// cylinders), and examples/screw/screw.json (Debian's screw.step: cones, a
// domed torus, 51,000 triangles), each with every dimension moved off
// nominal so that every face a dimension moves is placed (planes by the
// fixed pseudo-inverse, curved faces by Gauss-Newton). The render: 1024 x
// 1024 pixels of 0.4 mm, one sample per pixel, the part about half the
// panel across, on every core (the fit's renders), into a preallocated
// image; the placement (its loops over vertices and triangles) on every
// core as well. Each figure is the median of repeated calls.
#include "xgauge/core/parallel.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/renderer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace xgauge {
namespace {

double medianMs(int repeats, const std::function<void()>& work) {
  std::vector<double> ms;
  for (int k = 0; k < repeats; ++k) {
    const auto start = std::chrono::steady_clock::now();
    work();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

void benchPart(const std::filesystem::path& file) {
  const PartModel part = PartModel::load(file);
  // Every dimension moved by a twentieth of the way to its max.
  std::vector<double> values = part.nominalValues();
  for (size_t i = 0; i < values.size(); ++i) {
    const Dimension& d = part.dimensions()[i];
    values[i] = d.nominal + 0.05 * (d.max - d.nominal);
  }
  if (const auto bad = part.invalidity(values)) {
    std::printf("%s: %s\n", file.string().c_str(), bad->c_str());
    return;
  }
  std::vector<Vec3> vertices;
  part.evaluate(values, vertices);
  const double place_ms = medianMs(101, [&] { part.evaluate(values, vertices); });

  // The part about half of a 409.6 mm panel across.
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = 1024;
  machine.pitch_u_mm = machine.pitch_v_mm = 0.4;
  machine.cx_px = machine.cy_px = 512.0;
  const TriangleMesh mesh = part.mesh(values);
  const BoundingBox box = boundingBox(mesh);
  const double magnification = 0.5 * 409.6 / box.diagonal();
  Pose pose = Pose::fromEulerDeg({30, -40, 15}, Vec3::Zero());
  pose.translation_mm = Vec3(0, 0, 1000.0 * (1.0 - 1.0 / magnification)) -
                        pose.rotation * (0.5 * (box.min_mm + box.max_mm));
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  const TransmissionTable table = TransmissionTable::forMaterial(
      ExponentialSum({{0.55, 0.035}, {0.35, 0.075}, {0.10, 0.25}}), 2.0 * box.diagonal());
  Image image(machine.columns, machine.rows);
  const RenderOptions options;
  const WorldMesh posed{world, mesh.triangles, mesh.csg.get()};
  renderIntensity(machine, posed, table, options, image);
  const double render_ms =
      medianMs(15, [&] { renderIntensity(machine, posed, table, options, image); });
  std::printf("%-26s %9zu %9zu %12.3f %12.2f %9.4f\n", file.filename().string().c_str(),
              mesh.triangles.size(), mesh.vertices.size(), place_ms, render_ms,
              place_ms / render_ms);
}

}  // namespace
}  // namespace xgauge

int main() {
  const std::filesystem::path root = XGAUGE_SOURCE_DIR;
  std::printf("render and placement on every core (%u)\n", std::thread::hardware_concurrency());
  std::printf("%-26s %9s %9s %12s %12s %9s\n", "part", "triangles", "vertices", "placement ms",
              "1024^2 ms", "ratio");
  for (const char* part : {"examples/step/prism_a.json", "examples/step/bracket.json",
                           "examples/screw/screw.json"}) {
    try {
      xgauge::benchPart(root / part);
    } catch (const std::exception& e) {
      std::printf("%s: %s\n", part, e.what());
    }
  }
  return 0;
}
