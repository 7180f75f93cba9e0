#pragma once
// Private to the ray index: the backends' factories and the double-precision
// ray/triangle test they share. Not installed, not included by other modules.
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/geometry/ray_index_embree.hpp>

#include <array>
#include <optional>
#include <vector>

namespace clearfit::ray_detail {

/// Watertight ray/triangle test (Woop, Benthin, Wald, "Watertight Ray/Triangle
/// Intersection", JCGT 2013) in double precision. The edge functions of an edge
/// shared by two faces are computed from the same sheared vertex coordinates, so
/// they are exact negatives of each other: a ray through an edge or a vertex
/// hits at least one face around it (no leaks). `u,v,w` are the scaled
/// barycentrics of corners 0,1,2 and `det = u+v+w`; t = t_scaled / det.
/// Needs -ffp-contract=off (the default under -std=c++20 without GNU extensions).
struct TriangleTest {
  double u = 0, v = 0, w = 0, det = 0, t_scaled = 0;
  /// Inside (edges and corners included) and not parallel to the plane.
  bool inside() const {
    return det != 0 && !((u < 0 || v < 0 || w < 0) && (u > 0 || v > 0 || w > 0));
  }
  double t() const { return t_scaled / det; }
};
TriangleTest test_triangle(const Vec3& origin, const Vec3& direction, const Vec3& a, const Vec3& b,
                           const Vec3& c);

/// Refines a hit on `face` in double precision, filling every RayHit field.
/// If the double test hits, t and the barycentrics are its exact values.
/// Otherwise (the backend found the face in lower precision just outside an
/// edge, or the ray lies in the face's plane) the barycentrics `hint` (or those
/// of the plane hit, or the centroid) are clamped to the face, and t is the
/// ray parameter of the point of the ray closest to that point of the face.
/// Never NaN for a finite ray; a face of zero area (to rounding) takes its corner normals as its geometric normal.
RayHit refine(const RayIndex& index, const Ray& ray, int face,
              const std::optional<std::array<double, 3>>& hint);
/// The same with the face's test_triangle of this ray already computed.
RayHit refine_tested(const RayIndex& index, const Ray& ray, int face, const TriangleTest& tt,
                     const std::optional<std::array<double, 3>>& hint);

/// The faces around each vertex (CSR): faces[offset[v] .. offset[v+1]).
struct VertexFaces {
  std::vector<int> offset, faces;
  explicit VertexFaces(const Mesh& mesh);
};

/// The hit of a backend that found `face` in lower precision (Embree: float;
/// CGAL: exact predicates but rounded sort keys). If the double test hits
/// `face`, refines on it. Otherwise the ray passed within rounding of an edge or
/// vertex: the faces sharing a vertex with `face` are tested in double and the
/// first one hit at t >= t_min is refined (else the last one hit before t_min,
/// which the caller rejects and re-casts past); if none is hit in double either,
/// `face` is kept with clamped barycentrics (see refine). The result may lie
/// outside [t_min, t_max]; the caller decides.
RayHit resolve(const RayIndex& index, const VertexFaces& around, const Ray& ray, int face,
               const std::optional<std::array<double, 3>>& hint);

/// Throws std::invalid_argument if the spans differ in size or a ray has a
/// non-finite origin/direction, a zero direction, a NaN t_min/t_max or t_min = -inf.
void check_rays(std::span<const Ray> rays, std::span<RayHit> hits);

std::unique_ptr<RayIndex> make_brute_force(const Mesh& mesh, CornerNormals normals);
std::unique_ptr<RayIndex> make_cgal_aabb(const Mesh& mesh, CornerNormals normals);

std::unique_ptr<RayIndex> make_embree(const Mesh& mesh, CornerNormals normals,
                                      const EmbreeOptions& options = {});

}  // namespace clearfit::ray_detail
