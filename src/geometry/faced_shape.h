// The shape of a STEP solid whose faces the part's dimensions move
// (face_moves.h): tessellated once at nominal values, every vertex placed on
// its moved surfaces for any values, with no new tessellation.
//
// Each vertex lies on the surfaces of the faces whose triangles meet there
// (one inside a face, two on an edge, three or more at a corner). For any
// scalars it is placed where each of those surfaces, moved, has the value
// it had at the vertex at nominal values (so nominal values give the
// tessellation's vertices exactly):
// - planes only, moved along their normals (offsets and translations): one
//   linear solve, a pseudo-inverse fixed at load;
// - any analytic surface: Gauss-Newton from a start that follows the curved
//   surfaces' own moves (a translated hole carries its vertices with it, a
//   grown cylinder moves them out along its radius, so that a circle stays
//   divided as the tessellation divided it), each step the least-norm
//   correction (the pseudo-inverse of the surfaces' gradients, which also
//   holds where a fillet meets a face tangentially); quadratic convergence,
//   at most kMaxNewtonSteps steps, to 1e-12 mm;
// - on a freeform face (which can only be translated as a whole): carried
//   by its translation.
// Deterministic: each vertex is a pure function of the scalars, so the loops
// over vertices and triangles run on every core (oneTBB) with the same
// numbers on any number of them.
//
// Folds (Shape::placementProblem): a triangle turning over against its
// nominal normal, or a vertex whose surfaces no longer meet (a hole grown
// out of its plate, a corner of four planes split by moving one of them,
// a vertex that would have to slide along a freeform face), named with the
// face and the dimensions that move it.
#pragma once

#include "face_moves.h"
#include "shape.h"

#include <memory>
#include <span>

namespace xgauge {

inline constexpr int kMaxNewtonSteps = 12;

// Throws Error, located at the "surfaces" entry, when an expressed surface
// does not pass through its faces at nominal values (within
// kNominalAgreementMm).
std::unique_ptr<const Shape> buildFacedShape(std::shared_ptr<const FacedStep> faced,
                                             std::span<const double> nominal_scalars);

}  // namespace xgauge
