// CGAL AABB-tree backend: CGAL builds the bounding-box hierarchy (EPICK
// kernel); the closest-hit search over it is ours (see ClosestHit).
// The only translation unit that includes CGAL's AABB headers.
#include "ray_index_internal.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

namespace clearfit::ray_detail {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangles = std::vector<K::Triangle_3>;
using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

K::Point_3 point(const Vec3& p) { return {p.x(), p.y(), p.z()}; }

class CgalIndex final : public RayIndex {
 public:
  CgalIndex(const Mesh& m, CornerNormals normals) : RayIndex(m, std::move(normals)) {
    for (const Vec3& v : m.vertices) scale_ = std::max(scale_, v.lpNorm<Eigen::Infinity>());
    // Every face, collinear ones included: the tree only bounds them (the search and the
    // triangle test are ours, in double), and the double test can hit a collinear face at its
    // corners, where it plugs the gap between neighbours whose edges meet it there (a point
    // computed on an edge: left out, a ray aimed at such a corner passed between them).
    for (int f = 0; f < m.num_faces(); ++f) {
      K::Triangle_3 tri(point(m.corner(f, 0)), point(m.corner(f, 1)), point(m.corner(f, 2)));
      triangles_.push_back(tri);
      face_of_.push_back(f);
    }
    tree_.insert(triangles_.cbegin(), triangles_.cend());
    tree_.build();  // now, not lazily inside concurrent queries
  }
  using RayIndex::intersect;

  void intersect(std::span<const Ray> rays, std::span<RayHit> hits) const override {
    check_rays(rays, hits);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 64), [&](const auto& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) hits[i] = cast(rays[i]);
    });
  }
  RayBackend backend() const override { return RayBackend::cgal_aabb; }

 private:
  // Closest-hit traversal of CGAL's tree, nearest box first, pruned by the
  // best t so far. CGAL's own first_intersection was measured to return the
  // exit face for ~1 % of rays aimed exactly at a vertex (its constructions
  // are inexact), so each candidate face gets the double-precision watertight
  // test instead: the result equals the brute-force loop's, ties included.
  struct ClosestHit {
    using Priority = double;
    const CgalIndex& index;
    const Ray& ray;
    double pad;  // box padding: far above the rounding of the slab test and of the triangle test
    int best = -1;
    double best_t = std::numeric_limits<double>::infinity();

    bool go_further() const { return true; }
    void intersection(const Ray&, const Primitive& p) {
      const int f = index.face_of_[p.id() - index.triangles_.cbegin()];
      if (f == ray.skip_face) return;
      const Mesh& m = index.mesh();
      const TriangleTest tt = test_triangle(ray.origin, ray.direction, m.corner(f, 0), m.corner(f, 1), m.corner(f, 2));
      if (!tt.inside()) return;
      const double t = tt.t();
      if (t >= ray.t_min && t <= ray.t_max && (t < best_t || (t == best_t && f < best))) best = f, best_t = t;
    }
    // Slab test against the padded box: (intersects within [t_min, min(t_max, best_t)], -entry t).
    template <class Node>
    std::pair<bool, double> do_intersect_with_priority(const Ray&, const Node& node) const {
      const CGAL::Bbox_3& box = node.bbox();
      double t_enter = ray.t_min, t_exit = std::min(ray.t_max, best_t);
      for (int k = 0; k < 3; ++k) {
        const double lo = box.min(k) - pad, hi = box.max(k) + pad, o = ray.origin[k], d = ray.direction[k];
        if (d == 0) {
          if (o < lo || o > hi) return {false, 0};
          continue;
        }
        double t0 = (lo - o) / d, t1 = (hi - o) / d;
        if (t0 > t1) std::swap(t0, t1);
        t_enter = std::max(t_enter, t0), t_exit = std::min(t_exit, t1);
      }
      return {t_enter <= t_exit, -t_enter};
    }
    template <class Node>
    bool do_intersect(const Ray& r, const Node& node) const { return do_intersect_with_priority(r, node).first; }
  };

  RayHit cast(const Ray& ray) const {
    if (!(ray.t_min <= ray.t_max) || std::isinf(ray.t_min)) return {};
    ClosestHit search{*this, ray, 0x1p-40 * (scale_ + ray.origin.lpNorm<Eigen::Infinity>())};
    tree_.traversal_with_priority(ray, search);
    return search.best < 0 ? RayHit{} : refine_hit(ray, search.best);
  }

  double scale_ = 0;  // largest vertex coordinate magnitude
  Triangles triangles_;
  std::vector<int> face_of_;
  Tree tree_;
};

}  // namespace

std::unique_ptr<RayIndex> make_cgal_aabb(const Mesh& mesh, CornerNormals normals) {
  return std::make_unique<CgalIndex>(mesh, std::move(normals));
}

}  // namespace clearfit::ray_detail
