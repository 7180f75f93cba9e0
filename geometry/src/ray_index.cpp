// The backend-independent half of the ray index: the double-precision
// triangle test, hit refinement, argument checks and the factory.
#include <clearfit/geometry/ray_index.hpp>

#include "ray_index_internal.hpp"
#include "reliable_normal.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace clearfit {

std::string_view to_string(RayBackend backend) {
  switch (backend) {
    case RayBackend::embree: return "embree";
    case RayBackend::cgal_aabb: return "cgal_aabb";
    case RayBackend::brute_force: return "brute_force";
  }
  return "unknown";
}

RayIndex::RayIndex(const Mesh& mesh, CornerNormals normals)
    : mesh_(&mesh), normals_(std::move(normals)), face_normals_(mesh.faces.size()) {
  for (int f = 0; f < mesh.num_faces(); ++f) face_normals_[static_cast<std::size_t>(f)] = detail::reliable_normal(mesh, f);
}

RayHit RayIndex::intersect(const Ray& ray) const {
  RayHit hit;
  intersect(std::span<const Ray>(&ray, 1), std::span<RayHit>(&hit, 1));
  return hit;
}

RayHit RayIndex::refine_hit(const Ray& ray, int face) const {
  return ray_detail::refine(*this, ray, face, std::nullopt);
}

namespace {
// The corner normals a new index keeps: `normals` (checked against the mesh) or the mesh's own.
CornerNormals normals_for_index(const Mesh& mesh, const CornerNormals* normals) {
  mesh.check_consistent();
  if (normals && normals->corner.size() != mesh.faces.size())
    throw std::invalid_argument("make_ray_index: normals has " + std::to_string(normals->corner.size()) +
                                " faces, the mesh " + std::to_string(mesh.faces.size()));
  return normals ? *normals : compute_corner_normals(mesh);
}
}  // namespace

std::unique_ptr<RayIndex> make_embree_ray_index(const Mesh& mesh, const EmbreeOptions& options,
                                                const CornerNormals* normals) {
  return ray_detail::make_embree(mesh, normals_for_index(mesh, normals), options);
}

std::unique_ptr<RayIndex> make_ray_index(const Mesh& mesh, RayBackend backend,
                                         const CornerNormals* normals) {
  CornerNormals n = normals_for_index(mesh, normals);
  switch (backend) {
    case RayBackend::embree: return ray_detail::make_embree(mesh, std::move(n));
    case RayBackend::cgal_aabb: return ray_detail::make_cgal_aabb(mesh, std::move(n));
    case RayBackend::brute_force: return ray_detail::make_brute_force(mesh, std::move(n));
  }
  throw std::invalid_argument("make_ray_index: unknown backend");
}

namespace ray_detail {

TriangleTest test_triangle(const Vec3& o, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Shear/scale so that the ray runs along +z from the origin; kz is the
  // dominant axis, kx/ky swapped when d[kz] < 0 to keep the winding.
  int kz = 0;
  d.cwiseAbs().maxCoeff(&kz);
  int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
  if (d[kz] < 0) std::swap(kx, ky);
  const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
  const Vec3 A = a - o, B = b - o, C = c - o;
  const double ax = A[kx] - sx * A[kz], ay = A[ky] - sy * A[kz];
  const double bx = B[kx] - sx * B[kz], by = B[ky] - sy * B[kz];
  const double cx = C[kx] - sx * C[kz], cy = C[ky] - sy * C[kz];
  TriangleTest r;
  r.u = cx * by - cy * bx;
  r.v = ax * cy - ay * cx;
  r.w = bx * ay - by * ax;
  r.det = r.u + r.v + r.w;
  r.t_scaled = r.u * (sz * A[kz]) + r.v * (sz * B[kz]) + r.w * (sz * C[kz]);
  return r;
}

RayHit refine(const RayIndex& index, const Ray& ray, int face,
              const std::optional<std::array<double, 3>>& hint) {
  const Mesh& mesh = index.mesh();
  return refine_tested(index, ray, face,
                       test_triangle(ray.origin, ray.direction, mesh.corner(face, 0), mesh.corner(face, 1), mesh.corner(face, 2)),
                       hint);
}

RayHit refine_tested(const RayIndex& index, const Ray& ray, int face, const TriangleTest& tt,
                     const std::optional<std::array<double, 3>>& hint) {
  const Mesh& mesh = index.mesh();
  const Vec3 &a = mesh.corner(face, 0), &b = mesh.corner(face, 1), &c = mesh.corner(face, 2);
  const Vec3 &o = ray.origin, &d = ray.direction;
  RayHit hit;
  hit.face = face;
  if (tt.inside()) {
    hit.t = tt.t();
    hit.bary = {tt.u / tt.det, tt.v / tt.det, tt.w / tt.det};  // all >= 0 here
  } else {
    // Found by a float or exact-predicate test just outside an edge, or a ray
    // in the face's plane: clamp to the face, take the closest ray point.
    std::array<double, 3> w = hint ? *hint
                              : tt.det != 0 ? std::array<double, 3>{tt.u / tt.det, tt.v / tt.det, tt.w / tt.det}
                                            : std::array<double, 3>{1.0, 1.0, 1.0};
    double sum = 0;
    for (double& x : w) sum += (x = std::isfinite(x) && x > 0 ? x : 0.0);
    for (double& x : w) x = sum > 0 ? x / sum : 1.0 / 3.0;
    const Vec3 q = w[0] * a + w[1] * b + w[2] * c;
    hit.t = (q - o).dot(d) / d.squaredNorm();
    hit.bary = w;
  }
  hit.point = o + hit.t * d;
  hit.shading_normal = index.normals().interpolate(face, hit.bary[0], hit.bary[1], hit.bary[2]);
  // A face of zero area, exactly or to rounding (a vertex computed on an edge), has no side of its own:
  // its right-hand normal is zero or rounding noise of either sign. The double test can still hit it (at
  // its edges and corners, where the sheared coordinates round off the line), and it is the first hit
  // there when its index is the lowest, so it takes its corner normals (a neighbour's, compute_corner_normals)
  // for its orientation. Found by scripts/numerical-sweep.sh: a slab split at points on its edges gave
  // back_face for a ray aimed exactly at such a point (ray 20871 of the sixth 40000-ray run).
  hit.geometric_normal = index.face_normal(face);
  if (hit.geometric_normal.isZero(0)) hit.geometric_normal = hit.shading_normal;
  hit.front_facing = d.dot(hit.geometric_normal) < 0;
  return hit;
}

VertexFaces::VertexFaces(const Mesh& mesh) : offset(mesh.vertices.size() + 1, 0) {
  for (const auto& f : mesh.faces)
    for (int v : f) ++offset[v + 1];
  for (size_t v = 0; v + 1 < offset.size(); ++v) offset[v + 1] += offset[v];
  faces.resize(offset.back());
  std::vector<int> fill(offset.begin(), offset.end() - 1);
  for (int f = 0; f < mesh.num_faces(); ++f)
    for (int v : mesh.faces[f]) faces[fill[v]++] = f;
}

RayHit resolve(const RayIndex& index, const VertexFaces& around, const Ray& ray, int face,
               const std::optional<std::array<double, 3>>& hint) {
  const Mesh& mesh = index.mesh();
  auto test = [&](int f) {
    return test_triangle(ray.origin, ray.direction, mesh.corner(f, 0), mesh.corner(f, 1), mesh.corner(f, 2));
  };
  const TriangleTest own = test(face);
  if (own.inside()) return refine_tested(index, ray, face, own, std::nullopt);
  int after = -1, before = -1;  // first hit at t >= t_min; last hit below t_min
  TriangleTest tt_after, tt_before;
  double t_after = std::numeric_limits<double>::infinity(), t_before = -t_after;
  for (int v : mesh.faces[face])
    for (int i = around.offset[v]; i < around.offset[v + 1]; ++i) {
      const int g = around.faces[i];
      if (g == face) continue;
      const TriangleTest tt = test(g);
      if (!tt.inside()) continue;
      const double t = tt.t();
      if (t >= ray.t_min && g != ray.skip_face) {  // the skip face only as a hit to reject (re-cast past)
        if (t < t_after || (t == t_after && g < after)) after = g, t_after = t, tt_after = tt;
      } else if (t > t_before) {
        before = g, t_before = t, tt_before = tt;
      }
    }
  if (after >= 0) return refine_tested(index, ray, after, tt_after, std::nullopt);
  if (before >= 0) return refine_tested(index, ray, before, tt_before, std::nullopt);
  return refine_tested(index, ray, face, own, hint);
}

void check_rays(std::span<const Ray> rays, std::span<RayHit> hits) {
  if (rays.size() != hits.size())
    throw std::invalid_argument("RayIndex::intersect: " + std::to_string(rays.size()) + " rays but " +
                                std::to_string(hits.size()) + " hits");
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    const char* problem = !r.origin.allFinite()                  ? "a non-finite origin"
                          : !r.direction.allFinite()             ? "a non-finite direction"
                          : r.direction.isZero(0)                ? "a zero direction"
                          : std::isnan(r.t_min) || std::isnan(r.t_max) ? "a NaN t_min or t_max"
                          : r.t_min == -std::numeric_limits<double>::infinity() ? "t_min = -inf"
                                                                 : nullptr;
    if (problem)
      throw std::invalid_argument("RayIndex::intersect: ray " + std::to_string(i) + " has " + problem);
  }
}

}  // namespace ray_detail
}  // namespace clearfit
