// Reading STL files (binary and ASCII) into a closed, outward, indexed mesh.
//
// Coordinates are read as millimetres in part coordinates. Facet normals are
// ignored: orientation comes from the vertex order (counter-clockwise seen
// from outside), as the format specifies.
//
// Welding: vertices with identical coordinates become one vertex; then
// vertices whose coordinates all differ by at most kStlWeldTolerance times the
// bounding box diagonal are merged as well (ASCII writers that rounded one
// point two ways). Triangles that collapse in welding (a repeated vertex) are
// dropped with a warning. The welded mesh must pass checkClosedMesh; one that
// is closed and consistent but faces inward is flipped with a warning. Every
// other problem throws Error naming the file (and the line, for ASCII syntax).
#pragma once

#include "xgauge/geometry/mesh.h"

#include <filesystem>

namespace xgauge {

inline constexpr double kStlWeldTolerance = 1e-9;

TriangleMesh readStl(const std::filesystem::path& path);

}  // namespace xgauge
