// Simulated defects: material missing from the part, so that what a
// measurement reports about a flaw (its residual regions) can be checked
// against a flaw whose place is known exactly.
//
// Recipe key `defects` (optional, every shot): an array of
//   {"type": "void", "centre_mm": [x, y, z], "diameter_mm": d}
// a spherical void (a gas pore) with its centre in the PART frame (mm, the
// part model's coordinates) and d in 0.05 ... 20 mm. Each void must lie
// entirely inside the part at its true dimensions, and voids must not overlap.
//
// Physics: a void removes material, so every ray loses the length of its
// chord through the sphere from its path through the part:
//   I = T(path_part - sum of chords).
// The renderer's mesh stays the part's; the voids are carved afterwards from
// the pixels whose sample rays cross them (carveVoids), which leaves every
// other pixel bit-identical to a render without defects.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/transform.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/image/image.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

struct Defect {
  std::string type = "void";  // the only kind so far
  Vec3 centre_part_mm = Vec3::Zero();
  double diameter_mm = 0.0;
  double radiusMm() const { return 0.5 * diameter_mm; }
};

// A void placed for one render: centre in world coordinates (mm).
struct WorldSphere {
  Vec3 centre_mm = Vec3::Zero();
  double radius_mm = 0.0;
};

// Reads the recipe's `defects` array and checks each void against the part
// (`part_mesh`: the part at its true dimensions, part frame). Throws Error
// located at the offending entry: an unknown type, a value out of range, a
// void not entirely inside the part (see voidOutsidePart), or two voids that
// overlap. Unknown keys are left for ConfigNode::finish() to report.
std::vector<Defect> readDefects(const ConfigNode& defects, const TriangleMesh& part_mesh);

// Why a sphere (part frame) is not entirely inside the part, or nullopt when
// it is. Sufficient test: the centre is inside the solid and the radius is
// smaller than the distance from the centre to the nearest triangle.
std::optional<std::string> voidOutsidePart(const TriangleMesh& part_mesh, const Vec3& centre_mm,
                                           double radius_mm);

// Whether a point lies inside the closed mesh (or, for a CSG part, inside the
// boolean combination of its pieces): generalized winding number, so the
// answer does not depend on a ray direction. Undefined on the surface.
bool insideMesh(const TriangleMesh& mesh, const Vec3& point_mm);

// Distance (mm) from a point to the nearest triangle of the mesh; for a CSG
// part, of any piece (at most the distance to the part's surface).
double distanceToTrianglesMm(const TriangleMesh& mesh, const Vec3& point_mm);

// Closest point of triangle (a, b, c) to p (Ericson, Real-Time Collision
// Detection, 5.1.5).
Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// Length (mm) of the part of the segment from `from` to `to` inside the
// sphere: 2 sqrt(r^2 - d^2) for a segment passing at distance d < r from the
// centre with both ends outside, 0 for a miss or a tangent.
double segmentSphereChordMm(const Vec3& from, const Vec3& to, const Vec3& centre_mm,
                            double radius_mm);

// Pixels whose shadow a sphere (world) may fall on: a conservative rectangle
// (one pixel of margin) clipped to the detector; empty when it misses.
PixelRect sphereFootprint(const Machine& machine, const WorldSphere& sphere);

// Carves `voids` (world, inside `mesh`) out of `intensity`, an image that
// renderIntensity(machine, mesh, transmission, {samples_per_axis}) rendered
// over the whole detector. Every pixel with at least one sample ray
// (renderer.h's sample grid) crossing a void is recomputed as the mean over
// its samples of T(max(0, path - chords)); every other pixel is left as it
// is. Deterministic; the voids must not overlap (their chords are summed).
void carveVoids(const Machine& machine, const WorldMesh& mesh, std::span<const WorldSphere> voids,
                const TransmissionTable& transmission, int samples_per_axis, Image& intensity);

}  // namespace xgauge
