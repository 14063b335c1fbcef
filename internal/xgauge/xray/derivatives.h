// Derivatives of a radiograph with respect to whatever moves the part's
// vertices (dimensions, poses), and a gradient checker that compares them
// with central differences of rendered images (in the manner of Ceres'
// GradientChecker), for the tests and for anyone writing a part model.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/image.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <functional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// The intensity image and its derivatives with respect to P parameters that
// move the mesh's vertices (docs/method.md, "Derivatives of the radiograph").
//
// `velocities` holds d(world vertex i)/d(theta_k) at index k * V + i (V
// vertices, parameter-major), so the caller chains the renderer to anything
// that moves vertices: dimensions through the part model, poses.
//
// What is differentiated is the image exactly as renderIntensity samples it:
// pixel = mean over its samples of I(x_s), x_s = |P_s - S| sum_t sigma_t
// lambda_t (lambda_t: the depth fraction where the sample's ray meets
// triangle t's plane). lambda_t = det(A, B, C) / (r . N), A, B, C the
// triangle's vertices relative to the source, N = A x B + B x C + C x A, r
// the ray, so d lambda = (dD - lambda r . dN) / (r . N) in closed form. The
// path through a closed surface is a continuous function of the ray (it
// falls to zero at a silhouette, and across an edge between two faces both
// faces are at the same depth), so a projected edge that passes a sample
// changes no sample value by a jump: the sampled image is continuous in the
// vertices and these interior terms are its whole derivative wherever it is
// differentiable. Where it is not (a sample on an edge or a silhouette, a
// face seen exactly edge-on), this is one of the one-sided derivatives.
//
// With options.edge_samples_per_axis = m, the pixels renderIntensity refines
// (the same bend test) are the means of their m x m samples, values and
// derivatives: the derivatives of the refined image, which comes with them
// bit for bit. Which pixels are refined is held fixed (it changes only where
// a bend crosses the threshold).
struct IntensityDerivatives {
  Image intensity;                   // as renderIntensity
  std::vector<Image> per_parameter;  // d intensity / d theta_k over the region
};
void renderIntensityDerivatives(const Machine& machine, const WorldMesh& mesh,
                                const TransmissionTable& transmission, const RenderOptions& options,
                                std::span<const Vec3> velocities, int parameters,
                                IntensityDerivatives& out);

// World vertices for a parameter vector; false where it cannot be built
// (the reason is not needed here).
using VertexMap = std::function<bool(std::span<const double> theta, std::vector<Vec3>& world)>;

// d(world vertex)/d(theta_k) for k in `indices`, by central differences of
// the vertex map alone (one-sided where theta +- step cannot be built), into
// `velocities` in renderIntensityDerivatives' layout. Costs no render: a part
// model's vertex expressions and a pose are cheap, and most are linear in
// the dimensions, where the difference is exact. False when neither side
// of some parameter can be built.
bool vertexVelocities(const VertexMap& map, std::span<const double> theta,
                      std::span<const int> indices, std::span<const double> steps,
                      std::vector<Vec3>& velocities);

// One parameter's comparison of the analytic derivative image with the
// central difference (f(theta + h) - f(theta - h)) / 2h of rendered images.
// A pixel is "well conditioned" when that difference with step h agrees with
// the one with step h / 2 to 1e-6 of the column's largest value: otherwise a
// sample's ray crossed an edge, a silhouette or a vertex within the step, the
// image has a kink there and no finite difference tells its derivative.
struct GradientColumn {
  std::string name;
  double scale = 0.0;           // largest |central difference| over the image
  double worst = 0.0;           // max |analytic - difference| / scale, well-conditioned pixels
  double norm_error = 0.0;      // |analytic - difference|_2 / |difference|_2, same pixels
  double norm_error_all = 0.0;  // the same over every pixel
  long pixels = 0;              // pixels compared
  long kinked = 0;              // pixels left out as not well conditioned
};

struct GradientCheck {
  std::vector<GradientColumn> columns;
  // A column whose differences stay below this (intensity per mm or deg) is
  // a parameter that moves nothing in this view (a feature off the detector
  // or hidden in a symmetry): what its difference shows is rounding.
  static constexpr double kMovesNothing = 1e-6;
  // The largest `worst` over the columns that move something.
  double worst() const;
};

// One column's comparison: the central differences with steps h (`coarse`)
// and h / 2 (`fine`) against `analytic(m)` for each of their values m; a
// value is well conditioned where the two differences agree to
// `agreement` of the column's largest |coarse|. Shared by the render's and
// the fit's gradient checks (measure/gradient_check.h).
GradientColumn compareWithDifferences(std::string name, std::span<const double> coarse,
                                      std::span<const double> fine,
                                      const std::function<double(size_t)>& analytic,
                                      double agreement);

// Checks a part model's image derivatives at one pose: the parameters are
// every dimension (model order) then the pose's rx, ry, rz (deg; R = Rz Ry Rx)
// and its translation x, y, z (mm); `steps` gives h per parameter (empty: 3e-4
// mm or deg: small enough that few samples meet an edge within the step, large
// enough that rounding stays far below the derivatives). Throws Error when the part cannot be built
// at these values or leaves the beam.
GradientCheck checkPartGradients(const Machine& machine, const PartModel& part,
                                 std::span<const double> dimensions, const Vec3& rotation_deg,
                                 const Vec3& translation_mm, const ExponentialSum& material,
                                 const RenderOptions& options, std::span<const double> steps = {});

}  // namespace xgauge
