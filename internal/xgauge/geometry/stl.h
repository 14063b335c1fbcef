// Reading STL files (binary and ASCII) into a closed, outward, indexed mesh.
//
// Coordinates are read as millimetres in part coordinates. Facet normals are
// ignored: orientation comes from the vertex order (counter-clockwise seen
// from outside), as the format specifies.
//
// The facets are welded into an indexed mesh and checked closed and outward
// by closedMeshFromSoup (mesh.h), which the STEP reader shares: an inward
// mesh is flipped with a warning, and every other problem throws Error naming
// the file (and the line, for ASCII syntax).
#pragma once

#include "xgauge/geometry/mesh.h"

#include <filesystem>
#include <string>

namespace xgauge {

// `sha256`, when given, receives the SHA-256 of the bytes read.
TriangleMesh readStl(const std::filesystem::path& path, std::string* sha256 = nullptr);

}  // namespace xgauge
