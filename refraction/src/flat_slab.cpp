#include "flat_slab.hpp"

#include <cmath>

namespace clearfit::refraction_detail {

FlatSlab::Plane FlatSlab::make_plane(const Mesh& mesh, const std::vector<int>& faces, const Vec3& normal,
                                     double offset) {
  Plane p;
  p.normal = normal;
  p.offset = offset;
  p.origin = offset * normal;
  p.u = normal.unitOrthogonal();
  p.v = normal.cross(p.u);
  p.chart.faces = faces;
  p.chart.uv.assign(mesh.vertices.size(), Vec2::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (int f : faces)
    for (int vtx : mesh.faces[f]) {
      const Vec3 d = mesh.vertices[vtx] - p.origin;
      p.chart.uv[vtx] = Vec2(d.dot(p.u), d.dot(p.v));
    }
  return p;  // the locator refers to p.chart: made once the plane is in place
}

std::unique_ptr<FlatSlab> FlatSlab::detect(const Mesh& mesh, const ContactSurface& contact, const CornerNormals& normals) {
  if (contact.faces.empty() || mesh.num_faces() == 0) return nullptr;
  auto [lo, hi] = bounding_box(mesh);
  const double size = std::max((hi - lo).norm(), 1e-300);
  const double tol = 1e-9 * size, cos_tol = 1 - 1e-12;
  // The contact plane: the first non-degenerate contact face.
  Vec3 nc = Vec3::Zero();
  for (int f : contact.faces)
    if (!(nc = mesh.face_normal(f)).isZero()) break;
  if (nc.isZero()) return nullptr;
  const double dc = nc.dot(mesh.corner(contact.faces[0], 0));
  for (int f : contact.faces)
    for (int k = 0; k < 3; ++k) {
      if (std::abs(nc.dot(mesh.corner(f, k)) - dc) > tol) return nullptr;
      if (normals.corner[f][k].dot(nc) < cos_tol) return nullptr;
    }
  // The outer plane: the non-contact faces facing the other way.
  std::vector<int> outer;
  double d_outer = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (contact.is_contact[f]) continue;
    const Vec3 n = mesh.face_normal(f);
    if (n.dot(-nc) < cos_tol) continue;
    const double d = n.dot(mesh.corner(f, 0));
    if (outer.empty()) d_outer = d;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(n.dot(mesh.corner(f, k)) - d_outer) > tol) return nullptr;
      if (normals.corner[f][k].dot(n) < cos_tol) return nullptr;
    }
    outer.push_back(f);
  }
  if (outer.empty()) return nullptr;
  const double thickness = d_outer + dc;  // contact: nc·x = dc; outer: -nc·x = d_outer
  if (!(thickness > tol)) return nullptr;
  // Convexity: every vertex on the inner side of every face's plane. Faces
  // are first merged into their distinct planes (a slab has few), so the
  // check costs vertices × planes, not vertices × faces.
  std::vector<std::pair<Vec3, double>> planes;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Vec3 n = mesh.face_normal(f);
    if (n.isZero()) continue;
    const double d = n.dot(mesh.corner(f, 0));
    bool known = false;
    for (const auto& [pn, pd] : planes)
      if (pn.dot(n) >= cos_tol && std::abs(pd - d) <= tol) {
        known = true;
        break;
      }
    if (known) continue;
    if (planes.size() >= 1024) return nullptr;  // a slab has a handful of planes
    planes.emplace_back(n, d);
  }
  for (const auto& [n, d] : planes)
    for (const Vec3& v : mesh.vertices)
      if (n.dot(v) - d > tol) return nullptr;
  auto slab = std::unique_ptr<FlatSlab>(new FlatSlab());
  slab->mesh_ = &mesh;
  slab->thickness_ = thickness;
  slab->contact_ = make_plane(mesh, contact.faces, nc, dc);
  slab->outer_ = make_plane(mesh, outer, -nc, d_outer);
  for (Plane* p : {&slab->contact_, &slab->outer_}) p->locator = std::make_unique<ChartLocator>(mesh, p->chart);
  return slab;
}

std::optional<RayHit> FlatSlab::hit_plane(const Ray& ray, const Plane& plane) const {
  const double dn = ray.direction.dot(plane.normal);
  // Entering through the outer plane: from its outer side, going in. Leaving
  // through the contact plane: going out. Anything else goes to the index.
  if (&plane == &outer_ ? !(dn < 0 && ray.origin.dot(plane.normal) > plane.offset) : !(dn > 0)) return std::nullopt;
  const double t = (plane.offset - ray.origin.dot(plane.normal)) / dn;
  if (!(t >= ray.t_min && t <= ray.t_max)) return std::nullopt;
  const Vec3 x = ray.origin + t * ray.direction;
  const Vec3 d = x - plane.origin;
  const auto loc = plane.locator->locate(Vec2(d.dot(plane.u), d.dot(plane.v)));
  if (!loc) return std::nullopt;
  RayHit h;
  h.face = loc->face;
  h.t = t;
  h.point = x;  // the closed-form point (the located face's plane is the same plane)
  h.bary = loc->bary;
  h.geometric_normal = plane.normal;
  h.shading_normal = plane.normal;
  h.front_facing = dn < 0;
  return h;
}

}  // namespace clearfit::refraction_detail
