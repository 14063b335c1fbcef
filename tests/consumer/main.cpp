// Consumer of the installed xgauge library (see CMakeLists.txt): loads a
// cuboid part model, builds its mesh at the nominal dimensions and checks
// what has a closed-form answer: a closed outward mesh, the volume
// size_x * size_y * size_z and the bounding box +-size/2. Exit status 0 when
// every check passes.
#include "xgauge/core/error.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/version.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

namespace {

int failures = 0;

void check(bool ok, const std::string& what) {
  std::printf("%s: %s\n", ok ? "ok" : "FAILED", what.c_str());
  if (!ok) ++failures;
}

bool near(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b)); }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s parts/cuboid.json\n", argv[0]);
    return 2;
  }
  try {
    std::printf("xgauge %s (package version %s)\n", XGAUGE_VERSION_STRING, XGAUGE_PACKAGE_VERSION);
    check(std::strcmp(XGAUGE_VERSION_STRING, XGAUGE_PACKAGE_VERSION) == 0,
          "xgauge/version.h matches the CMake package version");

    const xgauge::PartModel part = xgauge::PartModel::load(argv[1]);
    const std::vector<double> nominal = part.nominalValues();
    const double size_x = nominal.at(static_cast<size_t>(part.dimensionIndex("size_x")));
    const double size_y = nominal.at(static_cast<size_t>(part.dimensionIndex("size_y")));
    const double size_z = nominal.at(static_cast<size_t>(part.dimensionIndex("size_z")));
    const xgauge::TriangleMesh mesh = part.mesh(nominal);
    check(mesh.vertices.size() == 8 && mesh.triangles.size() == 12, "8 vertices, 12 triangles");

    const xgauge::MeshCheck closed = xgauge::checkClosedMesh(mesh);
    check(closed.ok(), "closed outward mesh " + closed.message);

    const double volume = xgauge::signedVolume(mesh), expected = size_x * size_y * size_z;
    std::printf("volume %.6f mm^3, expected %.6f\n", volume, expected);
    check(near(volume, expected), "volume = size_x * size_y * size_z");

    const xgauge::BoundingBox box = xgauge::boundingBox(mesh);
    const xgauge::Vec3 half(size_x / 2, size_y / 2, size_z / 2);
    bool box_ok = true;
    for (int i = 0; i < 3; ++i) box_ok = box_ok && near(box.max_mm[i], half[i]) && near(box.min_mm[i], -half[i]);
    check(box_ok, "bounding box = +-size/2");

    // Bad input is reported as xgauge::Error.
    bool threw = false;
    try {
      (void)part.dimensionIndex("no_such_dimension");
    } catch (const xgauge::Error&) {
      threw = true;
    }
    check(threw, "unknown dimension throws xgauge::Error");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  std::printf("%s\n", failures == 0 ? "all checks passed" : "some checks FAILED");
  return failures == 0 ? 0 : 1;
}
