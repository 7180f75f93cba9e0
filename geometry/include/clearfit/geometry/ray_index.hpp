#pragma once
// First-hit ray queries against a mesh. One small interface; Embree (default)
// and CGAL's AABB tree behind it, plus a brute-force loop for tests.
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/geometry/normals.hpp>
#include <limits>
#include <memory>
#include <span>

namespace clearfit {

struct Ray {
  Vec3 origin;
  Vec3 direction;   ///< need not be unit length; t is in units of |direction|
  double t_min = 0.0;
  double t_max = std::numeric_limits<double>::infinity();
  /// A face the query ignores (-1: none): the face a ray leaves, e.g. the
  /// entry face of a refracted ray, so that rounding cannot re-hit it.
  int skip_face = -1;
};

/// A hit, recomputed in double precision on the face the index found.
struct RayHit {
  int face = -1;                   ///< mesh face index; -1 = miss
  double t = 0;                    ///< origin + t * direction = point
  Vec3 point = Vec3::Zero();       ///< part frame, mm
  std::array<double, 3> bary{};    ///< weights of corners 0,1,2 of the face (sum 1)
  Vec3 geometric_normal = Vec3::Zero();   ///< unit, right-hand (outward if oriented); a face flat to rounding: its corner normals
  Vec3 shading_normal = Vec3::Zero();     ///< unit, interpolated corner normal
  bool front_facing = false;       ///< direction · geometric_normal < 0
  explicit operator bool() const { return face >= 0; }
};

enum class RayBackend { embree, cgal_aabb, brute_force };
std::string_view to_string(RayBackend backend);

class RayIndex {
 public:
  virtual ~RayIndex() = default;
  /// First hit along each ray with t in [t_min, t_max] on a face other than its
  /// skip_face; hits[i].face = -1 on a miss.
  /// Ties (edges, vertices) go to the lowest face index with the least double t.
  /// Thread-safe; parallel over the batch (TBB). Throws std::invalid_argument if
  /// the spans differ in size or a ray has a non-finite origin/direction, a zero
  /// direction, a NaN t_min/t_max or t_min = -inf. t_min > t_max is a miss.
  virtual void intersect(std::span<const Ray> rays, std::span<RayHit> hits) const = 0;
  RayHit intersect(const Ray& ray) const;
  virtual RayBackend backend() const = 0;
  const Mesh& mesh() const { return *mesh_; }
  const CornerNormals& normals() const { return normals_; }
  /// Unit right-hand normal of face f, zero for a face flat to rounding (kept
  /// from construction: every refined hit needs its face's).
  const Vec3& face_normal(int f) const { return face_normals_[static_cast<std::size_t>(f)]; }

 protected:
  RayIndex(const Mesh& mesh, CornerNormals normals);
  /// Double-precision hit of `ray` with `face` (watertight test of Woop et al.
  /// 2013), filling every RayHit field; no t-range check. If the double test
  /// misses the face (the ray passes just outside it, or lies in its plane), the
  /// barycentrics are clamped to the face and t is that of the ray point
  /// closest to the clamped point. Never NaN; a face of zero area (to rounding)
  /// takes its corner normals as its geometric normal.
  RayHit refine_hit(const Ray& ray, int face) const;

 private:
  const Mesh* mesh_;
  CornerNormals normals_;
  std::vector<Vec3> face_normals_;
};

/// The mesh must outlive the index and not change. `normals` default: compute_corner_normals(mesh);
/// if given it must have one entry per face (else std::invalid_argument).
/// Every backend returns double-precision hits that equal the brute-force loop's
/// (the same face, the same t) except, for Embree, where two faces sharing no
/// vertex lie within ~1e-7 of the mesh's bounding radius of each other along the
/// ray (float search; see ray_index_embree.cpp). Embree is the default: per
/// thread 3-4x faster than the CGAL tree on camera rays, 1.3-1.7x on random
/// rays (bench/ray_index_bench.cpp, 20k-1M triangles).
std::unique_ptr<RayIndex> make_ray_index(const Mesh& mesh, RayBackend backend = RayBackend::embree,
                                         const CornerNormals* normals = nullptr);

}  // namespace clearfit
