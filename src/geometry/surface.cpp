#include "xgauge/geometry/surface.h"

#include "xgauge/core/error.h"

#include <cmath>

namespace xgauge {
namespace {

// p's component across `axis` (a unit vector) from the axis line through `origin`.
Vec3 radial(const Vec3& p, const Vec3& origin, const Vec3& axis) {
  const Vec3 d = p - origin;
  return d - d.dot(axis) * axis;
}

Vec3 unitOrZero(const Vec3& v) {
  const double n = v.norm();
  return n > 0.0 ? Vec3(v / n) : Vec3::Zero();
}

// Distance of point q from the line through `origin` along unit `axis`.
double distanceFromAxis(const Vec3& q, const Vec3& origin, const Vec3& axis) {
  return radial(q, origin, axis).norm();
}

}  // namespace

std::string_view surfaceKindName(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::kPlane:
      return "plane";
    case SurfaceKind::kCylinder:
      return "cylinder";
    case SurfaceKind::kCone:
      return "cone";
    case SurfaceKind::kSphere:
      return "sphere";
    case SurfaceKind::kTorus:
      return "torus";
    case SurfaceKind::kOther:
      return "other";
  }
  return "other";
}

void Surface::setSemiAngle(double radians) {
  semi_angle = radians;
  cos_semi_angle = std::cos(radians);
  tan_semi_angle = std::tan(radians);
}

// One definition of each surface's value and gradient (valueAndGradient()).
double Surface::value(const Vec3& p) const {
  Vec3 g;
  return valueAndGradient(p, g);
}

Vec3 Surface::gradient(const Vec3& p) const {
  Vec3 g;
  valueAndGradient(p, g);
  return g;
}

double Surface::valueAndGradient(const Vec3& p, Vec3& g) const {
  switch (kind) {
    case SurfaceKind::kPlane:
      g = axis;
      return axis.dot(p - origin);
    case SurfaceKind::kCylinder: {
      const Vec3 r = radial(p, origin, axis);
      g = unitOrZero(r);
      return r.norm() - radius;
    }
    case SurfaceKind::kCone: {
      const double h = (p - origin).dot(axis);
      const Vec3 r = radial(p, origin, axis);
      const double rho = r.norm();
      g = cos_semi_angle * unitOrZero(r) - cos_semi_angle * tan_semi_angle * axis;
      return (rho - (radius + h * tan_semi_angle)) * cos_semi_angle;
    }
    case SurfaceKind::kSphere:
      g = unitOrZero(p - origin);
      return (p - origin).norm() - radius;
    case SurfaceKind::kTorus: {
      // From the nearest point of the centre circle towards p.
      const Vec3 out = unitOrZero(radial(p, origin, axis));
      if (out.isZero()) {
        g = Vec3::Zero();
        return std::hypot(radius, (p - origin).dot(axis)) - minor_radius;
      }
      const Vec3 tube = p - (origin + radius * out);
      g = unitOrZero(tube);
      return tube.norm() - minor_radius;
    }
    case SurfaceKind::kOther:
      break;
  }
  XG_CHECK(false, "valueAndGradient() of a surface without an implicit form");
  return 0.0;
}

Surface Surface::moved(const Vec3& t_mm, double growth_mm) const {
  Surface s = *this;
  s.origin += t_mm;
  switch (kind) {
    case SurfaceKind::kPlane:
      s.origin += growth_mm * axis;
      break;
    case SurfaceKind::kCylinder:
    case SurfaceKind::kSphere:
      s.radius += growth_mm;
      break;
    case SurfaceKind::kCone:
      s.radius += growth_mm / cos_semi_angle;
      break;
    case SurfaceKind::kTorus:
      s.minor_radius += growth_mm;
      break;
    case SurfaceKind::kOther:
      XG_CHECK(growth_mm == 0.0, "a freeform surface cannot grow");
      break;
  }
  return s;
}

bool Surface::sameAs(const Surface& other, double tolerance_mm, double size_mm) const {
  if (kind != other.kind || kind == SurfaceKind::kOther) return false;
  const double angle_tolerance = tolerance_mm / std::max(size_mm, 1.0);
  const bool parallel = axis.cross(other.axis).norm() <= angle_tolerance;
  const bool same_direction = axis.dot(other.axis) > 0.0;
  switch (kind) {
    case SurfaceKind::kPlane:
      return parallel && std::abs(axis.dot(other.origin - origin)) <= tolerance_mm;
    case SurfaceKind::kCylinder:
      return parallel && std::abs(radius - other.radius) <= tolerance_mm &&
             distanceFromAxis(other.origin, origin, axis) <= tolerance_mm;
    case SurfaceKind::kSphere:
      return std::abs(radius - other.radius) <= tolerance_mm &&
             (origin - other.origin).norm() <= tolerance_mm;
    case SurfaceKind::kTorus:
      return parallel && std::abs(radius - other.radius) <= tolerance_mm &&
             std::abs(minor_radius - other.minor_radius) <= tolerance_mm &&
             (origin - other.origin).norm() <= tolerance_mm;
    case SurfaceKind::kCone: {
      if (!parallel || distanceFromAxis(other.origin, origin, axis) > tolerance_mm) return false;
      // The radius at two stations along this cone's axis, from each cone.
      const double other_slope = (same_direction ? 1.0 : -1.0) * std::tan(other.semi_angle);
      const double shift = (origin - other.origin).dot(axis);
      for (const double h : {0.0, std::max(size_mm, 1.0)}) {
        const double mine = radius + h * std::tan(semi_angle);
        const double theirs = other.radius + (shift + h) * other_slope;
        if (std::abs(mine - theirs) > tolerance_mm) return false;
      }
      return true;
    }
    case SurfaceKind::kOther:
      break;
  }
  return false;
}

double Surface::diameterAt(const Vec3& station) const {
  switch (kind) {
    case SurfaceKind::kCylinder:
      return 2.0 * radius;
    case SurfaceKind::kCone:
      return 2.0 * (radius + (station - origin).dot(axis) * tan_semi_angle);
    default:
      break;
  }
  XG_CHECK(false, "diameterAt() of a surface that is neither a cylinder nor a cone");
  return 0.0;
}

}  // namespace xgauge
