// Embree 3 backend: a float BVH finds the face, ray_detail::refine recomputes
// the hit on it in double precision.
//
// Precision. Embree stores vertices and rays in float. The mesh is translated
// to its bounding-box centre and each ray's float origin is moved (in double)
// to where it enters the mesh's bounding sphere, so every float coordinate is
// exact to about 2^-24·R (R = the bounding-sphere radius), whatever the
// scene's position or scale (1e-3 mm and 1e3 mm scenes behave alike) or the
// camera's distance. RTC_SCENE_FLAG_ROBUST makes Embree's float test
// watertight along shared edges, but measured rays aimed exactly at a vertex
// still slipped through the whole fan in float (~1 % of them). So every vertex
// also carries a tiny guard sphere (radius kGuard·R, far above the float error):
// a ray that reaches a guard sphere first is settled by the double-precision
// watertight test on the faces around that vertex. A triangle hit is settled by
// ray_detail::resolve (the face, else the faces sharing a vertex with it, in
// double). The face returned can differ from the double-precision first hit
// only when two faces that share no vertex are within ~1e-7·R of each other
// along the ray (a thin wall, a near-touching fold); t, point and barycentrics
// are always exact in double on the face returned. Not guarded: a face thinner
// than a few 2^-24·R across (a needle or sliver between vertices the guards do
// not reach) can be missed whole, the float ray passing beside it; the ray then
// goes on to whatever lies behind. Measured (ray_index_test,
// DegenerateAndSliverFacesGiveNoNaN): a needle 1e-6 across (3.5e-7·R) is missed
// by 17 % of the rays aimed at it, which brute force and CGAL hit.
//
// t range. tnear is t_min rounded down to float; tfar is t_max widened by
// kFloatSlack so a hit with double t <= t_max is not lost to float rounding.
// The refined t decides: above t_max is a miss; below t_min re-casts with that
// face filtered out (one extra cast, typically when a ray starts on the
// surface it just left). A ray's skip_face is filtered out of its first cast
// already (context filter keyed by the ray id), so a ray leaving a face it
// names does not need that extra cast.
#include "ray_index_internal.hpp"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace clearfit::ray_detail {
namespace {

constexpr double kFloatSlack = 0x1p-16;  // 256 float ulps: well above Embree's t error
constexpr double kGuard = 0x1p-16;       // vertex guard radius / R (float error ~ 2^-24·R)
constexpr unsigned kTriangles = 0, kGuards = 1;  // Embree geometry ids

float round_down(double x) {
  float f = static_cast<float>(x);
  return f > x ? std::nextafter(f, -INFINITY) : f;
}
float round_up(double x) {
  float f = static_cast<float>(x);
  return f < x ? std::nextafter(f, INFINITY) : f;
}

// A ray in Embree's frame: origin relative to the mesh centre, moved to
// t = shift (the later of t_min and the bounding-sphere entry; Embree needs
// tnear >= 0); t_embree = t - shift.
struct FloatRay {
  float org[3], dir[3], tnear, tfar;
  double shift;
  bool active;
};

class EmbreeIndex final : public RayIndex {
 public:
  EmbreeIndex(const Mesh& m, CornerNormals normals, const EmbreeOptions& options)
      : RayIndex(m, std::move(normals)), options_(options), around_(m) {
    auto [lo, hi] = bounding_box(m);
    center_ = 0.5 * (lo + hi);
    radius_ = 0.5 * (hi - lo).norm();
    guard_ = kGuard * radius_;
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("Embree: rtcNewDevice failed (error " +
                                           std::to_string(rtcGetDeviceError(nullptr)) + ")");
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(scene_, options.high_quality_build ? RTC_BUILD_QUALITY_HIGH
                                                               : RTC_BUILD_QUALITY_MEDIUM);
    if (m.num_faces() > 0) {
      RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                            RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                            m.vertices.size()));
      auto* f = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0,
                                                               RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                               m.faces.size()));
      if (v && f) {
        for (size_t i = 0; i < m.vertices.size(); ++i)
          for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(m.vertices[i][k] - center_[k]);
        for (size_t i = 0; i < m.faces.size(); ++i)
          for (int k = 0; k < 3; ++k) f[3 * i + k] = static_cast<unsigned>(m.faces[i][k]);
      }
      rtcCommitGeometry(geometry);
      rtcAttachGeometryByID(scene_, geometry, kTriangles);
      rtcReleaseGeometry(geometry);
    }
    if (m.num_faces() > 0 && options.vertex_guards) {
      RTCGeometry guards = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
      auto* g = static_cast<float*>(rtcSetNewGeometryBuffer(guards, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                            4 * sizeof(float), m.vertices.size()));
      if (g)
        for (size_t i = 0; i < m.vertices.size(); ++i) {
          for (int k = 0; k < 3; ++k) g[4 * i + k] = static_cast<float>(m.vertices[i][k] - center_[k]);
          g[4 * i + 3] = static_cast<float>(guard_);
        }
      rtcCommitGeometry(guards);
      rtcAttachGeometryByID(scene_, guards, kGuards);
      rtcReleaseGeometry(guards);
    }
    rtcCommitScene(scene_);
    if (RTCError e = rtcGetDeviceError(device_); e != RTC_ERROR_NONE) {
      release();
      throw std::runtime_error("Embree: building the scene failed (error " + std::to_string(e) + ")");
    }
  }
  ~EmbreeIndex() override { release(); }
  EmbreeIndex(const EmbreeIndex&) = delete;
  EmbreeIndex& operator=(const EmbreeIndex&) = delete;
  using RayIndex::intersect;

  void intersect(std::span<const Ray> rays, std::span<RayHit> hits) const override {
    check_rays(rays, hits);
    const size_t block = options_.mode == EmbreeOptions::Mode::stream ? 256 : 64;
    auto trace = [&](size_t b, size_t e) {
      switch (options_.mode) {
        case EmbreeOptions::Mode::single: trace_single(rays, hits, b, e); break;
        case EmbreeOptions::Mode::packet16: trace_packets(rays, hits, b, e); break;
        case EmbreeOptions::Mode::stream: trace_stream(rays, hits, b, e); break;
      }
    };
    if (rays.size() <= block) return trace(0, rays.size());  // one block (a map's chunk): no task to spawn
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), block),
                      [&](const auto& range) { trace(range.begin(), range.end()); });
  }
  RayBackend backend() const override { return RayBackend::embree; }

 private:
  void release() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
    scene_ = nullptr;
    device_ = nullptr;
  }

  FloatRay prepare(const Ray& r) const {
    FloatRay f{};
    const Vec3 o = r.origin - center_;
    const Vec3& d = r.direction;
    // Bounding sphere (padded past the guards): |o + t d| = R'.
    const double R = radius_ * (1 + kFloatSlack) + 2 * guard_;
    const double a = d.squaredNorm(), b = o.dot(d), disc = b * b - a * (o.squaredNorm() - R * R);
    const double t_enter = (-b - std::sqrt(std::max(disc, 0.0))) / a, t_exit = (-b + std::sqrt(std::max(disc, 0.0))) / a;
    f.active = scene_has_faces() && disc >= 0 && r.t_min <= r.t_max && !std::isinf(r.t_min) &&
               r.t_min <= t_exit && r.t_max >= t_enter;
    if (!f.active) {
      f.tnear = 1, f.tfar = 0;  // Embree skips rays with tnear > tfar
      return f;
    }
    f.shift = std::max(r.t_min, t_enter);
    const Vec3 start = o + f.shift * d;
    for (int k = 0; k < 3; ++k) {
      f.org[k] = static_cast<float>(start[k]);
      f.dir[k] = static_cast<float>(d[k]);
    }
    f.tnear = std::max(0.0f, round_down(r.t_min - f.shift));
    const double t_far = r.t_max - f.shift;
    f.tfar = std::isinf(t_far) ? INFINITY : round_up(t_far + kFloatSlack * (2 * R / std::sqrt(a) + std::abs(t_far)));
    return f;
  }

  // The double-precision first hit in [t_min, t_max] among the faces around
  // vertex v, or face -1.
  RayHit fan_hit(const Ray& r, int v) const {
    const Mesh& m = mesh();
    int best = -1;
    double best_t = std::numeric_limits<double>::infinity();
    TriangleTest best_tt;
    for (int i = around_.offset[v]; i < around_.offset[v + 1]; ++i) {
      const int g = around_.faces[i];
      if (g == r.skip_face) continue;
      const TriangleTest tt = test_triangle(r.origin, r.direction, m.corner(g, 0), m.corner(g, 1), m.corner(g, 2));
      if (!tt.inside()) continue;
      const double t = tt.t();
      if (t >= r.t_min && t <= r.t_max && (t < best_t || (t == best_t && g < best))) best = g, best_t = t, best_tt = tt;
    }
    return best < 0 ? RayHit{} : refine_tested(*this, r, best, best_tt, std::nullopt);
  }

  // Turns Embree's answer for ray r into the refined hit. Re-casts (single,
  // same t range) ignoring, through a context filter, each face whose refined
  // t falls below t_min and each guard sphere whose fan the ray misses in
  // double. Faces are skipped by id, not by moving tnear, so nothing beyond
  // t_min is lost to float rounding.
  RayHit finish(const Ray& r, const FloatRay& f, unsigned geom, unsigned prim, float u, float v) const {
    SkipContext skip;
    rtcInitIntersectContext(&skip.context);
    skip.context.filter = &SkipContext::filter;
    if (r.skip_face >= 0) skip.ids[skip.count++] = {kTriangles, static_cast<unsigned>(r.skip_face)};
    while (f.active && geom != RTC_INVALID_GEOMETRY_ID) {
      if (geom == kGuards) {
        if (RayHit hit = fan_hit(r, static_cast<int>(prim))) return hit;
      } else {
        RayHit hit = resolve(*this, around_, r, static_cast<int>(prim), std::array<double, 3>{1.0 - u - v, u, v});
        if (hit.face != r.skip_face) {  // else: rounding near the face the ray leaves; re-cast past `prim`
          if (hit.t > r.t_max) return {};
          if (hit.t >= r.t_min) return hit;
        }
      }
      if (skip.count == SkipContext::kCapacity) return {};  // only for a ray lying in a fan of coplanar faces
      skip.ids[skip.count++] = {geom, prim};
      RTCRayHit rh = to_rayhit(f);
      rtcIntersect1(scene_, &skip.context, &rh);
      geom = rh.hit.geomID, prim = rh.hit.primID, u = rh.hit.u, v = rh.hit.v;
    }
    return {};
  }

  struct SkipContext {
    static constexpr int kCapacity = 64;
    RTCIntersectContext context;  // first member: Embree hands filters this pointer
    std::array<std::pair<unsigned, unsigned>, kCapacity> ids;
    int count = 0;
    static void filter(const RTCFilterFunctionNArguments* args) {
      const auto* self = reinterpret_cast<const SkipContext*>(args->context);
      for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const std::pair<unsigned, unsigned> id{RTCHitN_geomID(args->hit, args->N, i), RTCHitN_primID(args->hit, args->N, i)};
        if (std::find(self->ids.begin(), self->ids.begin() + self->count, id) != self->ids.begin() + self->count)
          args->valid[i] = 0;
      }
    }
  };

  // The first cast's context: with a filter dropping each ray's skip_face
  // (looked up by ray id = index from `rays`) when some ray of the batch has one.
  struct FirstCastContext {
    RTCIntersectContext context;  // first member: Embree hands filters this pointer
    const Ray* rays = nullptr;
    static void filter(const RTCFilterFunctionNArguments* args) {
      const auto* self = reinterpret_cast<const FirstCastContext*>(args->context);
      for (unsigned i = 0; i < args->N; ++i)
        if (args->valid[i] == -1 && RTCHitN_geomID(args->hit, args->N, i) == kTriangles &&
            static_cast<int>(RTCHitN_primID(args->hit, args->N, i)) == self->rays[RTCRayN_id(args->ray, args->N, i)].skip_face)
          args->valid[i] = 0;
    }
  };
  FirstCastContext first_cast_context(const Ray* rays, size_t n) const {
    FirstCastContext c;
    c.context = context();
    if (std::any_of(rays, rays + n, [](const Ray& r) { return r.skip_face >= 0; })) {
      c.rays = rays;
      c.context.filter = &FirstCastContext::filter;
    }
    return c;
  }

  static RTCRayHit to_rayhit(const FloatRay& f) {
    RTCRayHit rh{};
    set_rayhit(rh, f);
    return rh;
  }
  // Sets every field Embree reads, in place: building a whole RTCRayHit and
  // copying it into a stream's array stalled on store forwarding (a wide load
  // of narrow stores), 8 % of an exact map's CPU.
  static void set_rayhit(RTCRayHit& rh, const FloatRay& f) {
    rh.ray.org_x = f.org[0], rh.ray.org_y = f.org[1], rh.ray.org_z = f.org[2];
    rh.ray.dir_x = f.dir[0], rh.ray.dir_y = f.dir[1], rh.ray.dir_z = f.dir[2];
    rh.ray.tnear = f.tnear, rh.ray.tfar = f.tfar;
    rh.ray.time = 0, rh.ray.flags = 0;
    rh.ray.mask = ~0u;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  }

  RTCIntersectContext context() const {
    RTCIntersectContext c;
    rtcInitIntersectContext(&c);
    c.flags = options_.mode == EmbreeOptions::Mode::single ? RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT
                                                           : RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    return c;
  }

  void trace_single(std::span<const Ray> rays, std::span<RayHit> hits, size_t b, size_t e) const {
    for (size_t i = b; i < e; ++i) {
      FirstCastContext c = first_cast_context(&rays[i], 1);
      const FloatRay f = prepare(rays[i]);
      RTCRayHit rh = to_rayhit(f);
      if (f.active) rtcIntersect1(scene_, &c.context, &rh);
      hits[i] = finish(rays[i], f, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v);
    }
  }

  void trace_packets(std::span<const Ray> rays, std::span<RayHit> hits, size_t b, size_t e) const {
    RTCRayHit16 p;
    alignas(64) int valid[16];
    FloatRay f[16];
    for (size_t first = b; first < e; first += 16) {
      const size_t n = std::min<size_t>(16, e - first);
      FirstCastContext c = first_cast_context(&rays[first], n);
      for (size_t k = 0; k < 16; ++k) {
        f[k] = k < n ? prepare(rays[first + k]) : FloatRay{};
        valid[k] = f[k].active ? -1 : 0;
        p.ray.org_x[k] = f[k].org[0], p.ray.org_y[k] = f[k].org[1], p.ray.org_z[k] = f[k].org[2];
        p.ray.dir_x[k] = f[k].dir[0], p.ray.dir_y[k] = f[k].dir[1], p.ray.dir_z[k] = f[k].dir[2];
        p.ray.tnear[k] = f[k].tnear, p.ray.tfar[k] = f[k].tfar;
        p.ray.time[k] = 0, p.ray.mask[k] = ~0u, p.ray.id[k] = static_cast<unsigned>(k), p.ray.flags[k] = 0;
        p.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        p.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect16(valid, scene_, &c.context, &p);
      for (size_t k = 0; k < n; ++k)
        hits[first + k] = finish(rays[first + k], f[k], p.hit.geomID[k], p.hit.primID[k], p.hit.u[k],
                                 p.hit.v[k]);
    }
  }

  void trace_stream(std::span<const Ray> rays, std::span<RayHit> hits, size_t b, size_t e) const {
    FirstCastContext c = first_cast_context(&rays[b], e - b);
    std::vector<FloatRay> f(e - b);
    std::vector<RTCRayHit> rh(e - b);
    for (size_t i = b; i < e; ++i) {
      f[i - b] = prepare(rays[i]);
      set_rayhit(rh[i - b], f[i - b]);
      rh[i - b].ray.id = static_cast<unsigned>(i - b);
    }
    rtcIntersect1M(scene_, &c.context, rh.data(), static_cast<unsigned>(rh.size()), sizeof(RTCRayHit));
    for (size_t i = b; i < e; ++i) {
      const RTCRayHit& r = rh[i - b];
      hits[i] = finish(rays[i], f[i - b], r.hit.geomID, r.hit.primID, r.hit.u, r.hit.v);
    }
  }

  bool scene_has_faces() const { return mesh().num_faces() > 0; }

  EmbreeOptions options_;
  VertexFaces around_;
  Vec3 center_;
  double radius_ = 0, guard_ = 0;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace

std::unique_ptr<RayIndex> make_embree(const Mesh& mesh, CornerNormals normals, const EmbreeOptions& options) {
  return std::make_unique<EmbreeIndex>(mesh, std::move(normals), options);
}

}  // namespace clearfit::ray_detail
