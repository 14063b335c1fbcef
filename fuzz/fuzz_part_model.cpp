// libFuzzer target: the part-model loader (internal/xgauge/geometry/part_model.h).
// The bytes are parsed as a JSON config and loaded with PartModel::fromConfig
// as if they were <scratch>/part.json; the scratch folder also holds the
// tetrahedron tetra.stl, so {"shape": {"type": "stl", "file": "tetra.stl"}}
// loads. The model is then evaluated at its nominal values (mesh(), which
// validates and evaluates, and tryEvaluate), a copy is evaluated too, and
// each dimension's bounds go through invalidity() and tryEvaluate().
// Expected outcomes: a model whose nominal mesh is closed and outward (as the
// header promises), or xgauge::Error. Anything else is a finding.
#include "fuzz_common.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/part_model.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace {

// A binary STL tetrahedron with corners (0,0,0), (1,0,0), (0,1,0), (0,0,1),
// counter-clockwise seen from outside.
void writeTetrahedron() {
  const float corners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::string bytes(80, ' ');
  const uint32_t count = 4;
  bytes.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& face : faces) {
    const float normal[3] = {0, 0, 0};
    bytes.append(reinterpret_cast<const char*>(normal), sizeof normal);
    for (const int corner : face) bytes.append(reinterpret_cast<const char*>(corners[corner]), 12);
    bytes.append(2, '\0');
  }
  xgauge_fuzz::writeScratch("tetra.stl", reinterpret_cast<const uint8_t*>(bytes.data()),
                            bytes.size());
}

void checkNominalMesh(const xgauge::PartModel& model) {
  const std::vector<double> nominal = model.nominalValues();
  FUZZ_ASSERT(nominal.size() == model.dimensions().size(), "one nominal value per dimension");
  const xgauge::TriangleMesh mesh = model.mesh(nominal);  // validate + evaluate
  FUZZ_ASSERT(mesh.vertices.size() == model.vertexCount(), "vertexCount() vertices");
  const xgauge::MeshCheck check = xgauge::checkClosedMesh(mesh);
  if (!check.ok()) std::fprintf(stderr, "checkClosedMesh: %s\n", check.message.c_str());
  FUZZ_ASSERT(check.ok(), "the nominal mesh is not closed and outward");
  std::vector<xgauge::Vec3> out;
  const auto problem = model.tryEvaluate(nominal, out);
  FUZZ_ASSERT(!problem, "tryEvaluate fails at nominal values where mesh() succeeded");
  FUZZ_ASSERT(out.size() == model.vertexCount(), "tryEvaluate gives vertexCount() vertices");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  xgauge_fuzz::quietLogging();
  writeTetrahedron();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path path = xgauge_fuzz::scratchDir() / "part.json";
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const xgauge::ConfigNode root = xgauge::ConfigNode::parse(text, path.string());
    const xgauge::PartModel model = xgauge::PartModel::fromConfig(root, path);
    checkNominalMesh(model);
    const xgauge::PartModel copy = model;  // compiles its own expressions
    checkNominalMesh(copy);

    // Each dimension at its bounds: infeasible points are answers, not errors.
    std::vector<xgauge::Vec3> out;
    const auto& dimensions = model.dimensions();
    for (size_t i = 0; i < dimensions.size() && i < 8; ++i) {
      for (const double bound : {dimensions[i].min, dimensions[i].max}) {
        std::vector<double> values = model.nominalValues();
        values[i] = bound;
        (void)model.invalidity(values);
        if (!model.tryEvaluate(values, out))
          FUZZ_ASSERT(out.size() == model.vertexCount(), "tryEvaluate gives vertexCount() vertices");
      }
    }
  } catch (const xgauge::Error& e) {
    (void)e.where().str();
  }
  return 0;
}
