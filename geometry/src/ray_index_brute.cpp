// Brute-force backend: every ray against every face with the double-precision
// watertight test. O(rays × faces); the reference the other backends are tested against.
#include "ray_index_internal.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace clearfit::ray_detail {
namespace {

class BruteForceIndex final : public RayIndex {
 public:
  BruteForceIndex(const Mesh& mesh, CornerNormals normals) : RayIndex(mesh, std::move(normals)) {}
  using RayIndex::intersect;

  void intersect(std::span<const Ray> rays, std::span<RayHit> hits) const override {
    check_rays(rays, hits);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 8), [&](const auto& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) hits[i] = cast(rays[i]);
    });
  }
  RayBackend backend() const override { return RayBackend::brute_force; }

 private:
  // Smallest t in [t_min, t_max] off the skip face; ties go to the lower face index.
  RayHit cast(const Ray& ray) const {
    int best = -1;
    double best_t = std::numeric_limits<double>::infinity();
    const Mesh& m = mesh();
    for (int f = 0; f < m.num_faces(); ++f) {
      if (f == ray.skip_face) continue;
      const TriangleTest tt = test_triangle(ray.origin, ray.direction, m.corner(f, 0), m.corner(f, 1), m.corner(f, 2));
      if (!tt.inside()) continue;
      const double t = tt.t();
      if (t >= ray.t_min && t <= ray.t_max && t < best_t) best = f, best_t = t;
    }
    return best < 0 ? RayHit{} : refine_hit(ray, best);
  }
};

}  // namespace

std::unique_ptr<RayIndex> make_brute_force(const Mesh& mesh, CornerNormals normals) {
  return std::make_unique<BruteForceIndex>(mesh, std::move(normals));
}

}  // namespace clearfit::ray_detail
