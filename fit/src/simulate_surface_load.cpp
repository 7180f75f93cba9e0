// Where a pressure source given in the part frame lands on the 3D contact
// surface (simulate.hpp, SurfaceLoad). Sources given on the chart keep chart
// distances; sources given in the part frame press along the contact normal
// at their centre, so their closed form is evaluated with 3D distances on the
// surface points the texels stand for, never with chart distances (an LSCM
// chart of a bump's face, wall and plate shrinks the face by ~0.6).
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/simulate.hpp>

#include <cmath>

namespace clearfit::sim {

namespace {
/// Faces turned more than this from the load direction carry nothing (cos 60°).
constexpr double kMinFacing = 0.5;
/// A rigid indenter reaches surface points within this share of its contact
/// radius of its plane (the sagitta of a 2.5 mm punch on a 32 mm band is 4 %).
constexpr double kPlaneTolerance = 0.1;
}  // namespace

SurfaceLoad SurfaceLoad::at(const PressureSource& source, const SurfacePoint& centre, const Vec3& normal) {
  SurfaceLoad l;
  l.source = &source;
  l.centre = centre.point;
  l.normal = normal.normalized();
  return l;
}

double SurfaceLoad::pressure_kpa(const Vec3& point, const Vec3& face_normal) const {
  if (face_normal.dot(normal) < kMinFacing * face_normal.norm()) return 0;  // a wall seen edge-on by the load
  const Vec3 d = point - centre;
  const double height = d.dot(normal);
  const double axial = (d - height * normal).norm();
  switch (source->kind) {
    case PressureSource::Kind::gaussian: return source->pressure_kpa(d.norm());
    case PressureSource::Kind::punch:
      if (std::abs(height) > kPlaneTolerance * source->radius_mm) return 0;  // behind the punch face (a plate around a bump)
      return source->pressure_kpa(axial);
    case PressureSource::Kind::hertz: {
      const double a = contact::HertzSphere{source->sphere_radius_mm, source->force_n, source->e_star_kpa}.contact_radius_mm();
      if (std::abs(height) > kPlaneTolerance * a) return 0;
      return source->pressure_kpa(axial);
    }
  }
  return 0;
}

}  // namespace clearfit::sim
