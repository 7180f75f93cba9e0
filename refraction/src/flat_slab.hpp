#pragma once
// The flat-slab fast path: a part whose contact surface and outer surface are
// parallel planes and which is convex. Both intersections of a camera ray then
// have closed forms (ray-plane), located on the faces by 2D point location;
// rays whose closed-form points fall outside the planar faces go to the ray
// index as usual.
#include "chart_locator.hpp"

#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/ray_index.hpp>

#include <memory>
#include <optional>

namespace clearfit::refraction_detail {

class FlatSlab {
 public:
  /// nullopt unless: every contact face lies in one plane and every other face
  /// either lies in one parallel plane facing the other way (the outer
  /// surface) or is a side face; the corner normals of both planes equal the
  /// plane normals; and the part is convex (every vertex on the inner side of
  /// every face plane). Tolerances are relative to the part's size (1e-9).
  static std::unique_ptr<FlatSlab> detect(const Mesh& mesh, const ContactSurface& contact, const CornerNormals& normals);

  /// First hit of the ray if it enters through the outer plane's faces
  /// (closed form); nullopt means "ask the ray index".
  std::optional<RayHit> enter(const Ray& ray) const { return hit_plane(ray, outer_); }
  /// The refracted ray's hit on the contact plane's faces; nullopt: ask the index.
  std::optional<RayHit> reach(const Ray& ray) const { return hit_plane(ray, contact_); }
  double thickness_mm() const { return thickness_; }

 private:
  struct Plane {
    Vec3 normal;        // outward unit normal of the faces
    double offset = 0;  // normal · x = offset on the plane
    Vec3 origin, u, v;  // in-plane frame for the 2D location
    Chart chart;        // the faces' vertices in (u, v)
    std::unique_ptr<ChartLocator> locator;
  };
  std::optional<RayHit> hit_plane(const Ray& ray, const Plane& plane) const;
  static Plane make_plane(const Mesh& mesh, const std::vector<int>& faces, const Vec3& normal, double offset);

  const Mesh* mesh_ = nullptr;
  Plane outer_, contact_;
  double thickness_ = 0;
};

}  // namespace clearfit::refraction_detail
