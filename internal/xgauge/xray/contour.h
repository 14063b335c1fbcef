// The outline of a posed part as the source sees it: the mesh edges between
// a triangle that faces the source and one that faces away (the contour
// generator of the surface), projected onto the detector. Reports draw it
// over the measured radiograph, so that where the fitted part sits is seen
// at a glance; walls along the beam (a groove's sides) are contours too.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <array>
#include <vector>

namespace xgauge {

using Segment2 = std::array<Vec2, 2>;

// The contour edges of `mesh` (closed; world frame, every vertex inside the
// beam) in the continuous pixel coordinates of `machine`, in the mesh's edge
// order (deterministic). An edge used by one triangle only (an open mesh)
// counts as a contour.
std::vector<Segment2> projectedContour(const Machine& machine, const WorldMesh& mesh);

}  // namespace xgauge
