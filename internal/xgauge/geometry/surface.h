// The analytic surfaces that carry the faces of a B-rep solid (planes,
// cylinders, cones, spheres, tori), as implicit functions of a point in the
// part frame (mm), and how a face move changes them: a translation, or a
// growth along the surface's own normal direction (a plane's offset, a
// cylinder's or sphere's radius, a torus's tube radius, a cone's radius at
// every station). A face on any other surface (B-spline, Bezier, surface of
// revolution or extrusion, offset surface) has kind kOther: it can be
// translated as a whole, never slid along.
#pragma once

#include "xgauge/core/transform.h"

#include <string_view>

namespace xgauge {

enum class SurfaceKind { kPlane, kCylinder, kCone, kSphere, kTorus, kOther };

// "plane", "cylinder", "cone", "sphere", "torus", "other".
std::string_view surfaceKindName(SurfaceKind kind);

struct Surface {
  SurfaceKind kind = SurfaceKind::kOther;
  // plane: a point on it; cylinder and torus: a point on the axis (the
  // torus's centre); cone: the point on the axis where the radius is
  // `radius`; sphere: the centre.
  Vec3 origin = Vec3::Zero();
  // plane: the unit normal; cylinder, cone, torus: the unit axis direction.
  Vec3 axis = Vec3::UnitZ();
  // cylinder, sphere; cone: at `origin` (negative: the far nappe, see
  // semi_angle); torus: the centre circle's (negative: a tube that crosses
  // the axis, as a dome, taken from the circle's far side).
  double radius = 0.0;
  double minor_radius = 0.0;  // torus: the tube's
  // cone: radians in (-pi/2, pi/2), not 0: the radius grows by tan(semi_angle)
  // per mm along `axis`. Set with setSemiAngle(), which also keeps its
  // cosine and tangent (value() and gradient() run per vertex and step).
  double semi_angle = 0.0;
  double cos_semi_angle = 1.0, tan_semi_angle = 0.0;
  void setSemiAngle(double radians);

  // An implicit function, 0 on the surface, whose gradient has unit length
  // on it: the signed distance for planes (along `axis`), cylinders, spheres
  // and tori (positive away from the axis, centre or tube centre line); the
  // perpendicular distance for cones (positive away from the axis). Not
  // defined for kOther (XG_CHECK).
  double value(const Vec3& p) const;
  // Its gradient at p; zero where undefined (on an axis, a centre).
  Vec3 gradient(const Vec3& p) const;
  // Both at once (the placement's inner loop): value() returned, gradient()
  // into `gradient`.
  double valueAndGradient(const Vec3& p, Vec3& gradient) const;

  // The surface translated by `t_mm` and grown by `growth_mm` along the
  // direction value() increases (a plane moves along `axis`, a cylinder's or
  // sphere's radius and a torus's tube radius grow, a cone's radius grows by
  // growth / cos(semi_angle) at every station: offset by `growth_mm`).
  Surface moved(const Vec3& t_mm, double growth_mm) const;

  // Whether the two describe the same point set, within `tolerance_mm` over
  // a part of about `size_mm` (axes parallel within tolerance / size).
  bool sameAs(const Surface& other, double tolerance_mm, double size_mm) const;

  // A cone's diameter in the plane through `station` perpendicular to its
  // axis (mm). Cylinder: its diameter anywhere.
  double diameterAt(const Vec3& station) const;
};

}  // namespace xgauge
