// libFuzzer target: xgauge::readStl (internal/xgauge/geometry/stl.h), binary
// and ASCII, on arbitrary bytes written to a scratch file. Expected outcomes:
// a closed, outward mesh (checkClosedMesh passes, as the header promises), or
// xgauge::Error. Anything else is a finding.
#include "fuzz_common.h"

#include "xgauge/core/error.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/stl.h"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  xgauge_fuzz::quietLogging();
  xgauge_fuzz::scratchDir();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = xgauge_fuzz::writeScratch("input.stl", data, size);
  try {
    const xgauge::TriangleMesh mesh = xgauge::readStl(path);
    const xgauge::MeshCheck check = xgauge::checkClosedMesh(mesh);
    if (!check.ok()) std::fprintf(stderr, "checkClosedMesh: %s\n", check.message.c_str());
    FUZZ_ASSERT(check.ok(), "readStl returned a mesh that fails checkClosedMesh");
  } catch (const xgauge::Error&) {
    // Bad input reported as documented.
  }
  return 0;
}
