#pragma once
// The stages of compute_refraction_map (map.cpp), in the order the data flows:
//   1. rays:    pixel -> unit ray in the camera frame, once per camera per
//               process (CameraRays), and the part's pixel bound (part_bound);
//   2. trace:   ray -> skin sample, two casts and two refractions (Tracer);
//   3. store:   sample -> the map's per-pixel arrays (store, reset_span);
//   4. fill:    every pixel of the bound, either traced one by one
//               (trace_exact, map_exact.cpp) or by the quadtree of
//               interpolated cells with its boundary resolver (refine_quadtree,
//               quadtree.hpp).
#include <clearfit/camera/pixel_unprojector.hpp>
#include <clearfit/refraction/map.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace clearfit::refraction_detail {

class FlatSlab;

using Clock = std::chrono::steady_clock;
inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr float fnan = std::numeric_limits<float>::quiet_NaN();

// ---- 1. rays ---------------------------------------------------------------

// Ray directions depend only on the camera's intrinsics: unprojected once per
// camera per process, lazily, only for the pixels a map actually traces
// (mrcal's unprojection is iterative and costs more than the ray casts).
class CameraRays {
 public:
  explicit CameraRays(const CameraModel& camera)
      : camera_(camera), unprojector_(camera), rays_(static_cast<std::size_t>(camera.width) * camera.height),
        known_(rays_.size(), 0) {}
  /// Unprojects those of `pixels` (pixel indices) not unprojected before.
  /// Afterwards ray(p) of each of them may be read from any thread.
  void ensure(std::span<const std::uint32_t> pixels);
  /// The same for every pixel of rows y0..y1, columns x0..x1 (inclusive).
  void ensure(int x0, int y0, int x1, int y1);
  /// Unit rays of arbitrary (sub-pixel) points, not cached; NaN where the lens cannot unproject.
  void unproject(std::span<const Vec2> points, std::span<Vec3> rays) const { unprojector_.unproject(points, rays); }
  /// Unit ray of pixel index p (zero if the lens cannot unproject it); p must be ensured.
  const Vec3& ray(std::uint32_t p) const { return rays_[p]; }

 private:
  void fill(const std::vector<std::uint32_t>& missing);
  std::mutex mutex_;
  CameraModel camera_;
  PixelUnprojector unprojector_;  // coarse grid + Newton: about 4x less CPU than mrcal_unproject per pixel
  std::vector<Vec3> rays_;
  std::vector<char> known_;
};

/// The process-wide rays of this camera (a few cameras are kept).
std::shared_ptr<CameraRays> camera_rays(const CameraModel& camera);

// Pixel bound of the part's image: the box around the projected vertices,
// widened by a margin for lens curvature between vertices. nullopt: no bound
// (some vertex is behind the camera or does not project).
struct PixelBox {
  int x0, y0, x1, y1;  // inclusive
  bool empty() const { return x0 > x1 || y0 > y1; }
  bool contains(int x, int y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};
std::optional<PixelBox> part_bound(const Mesh& mesh, const CameraModel& camera, const Rigid3& cam_from_part);

// ---- 2. trace --------------------------------------------------------------

/// Throws unless the scene has a mesh, an index and a contact surface of that mesh with faces.
void check_scene(const TraceScene& scene);

// The two stages of a trace, shared by the batch map and single rays.
class Tracer {
 public:
  Tracer(const TraceScene& scene, const MapOptions& opt);
  ~Tracer();
  bool index_matched() const { return index_matched_; }
  bool flat_slab() const { return slab_ != nullptr; }
  std::string fast_path() const;

  /// Classifies the first hit; returns true and fills `second` when the ray
  /// goes on into the part.
  bool enter(const Ray& first, const RayHit& h, SkinSample& s, Ray& second) const;
  /// Classifies the hit of the refracted ray.
  void reach(const RayHit& h, SkinSample& s) const;
  /// Exact trace of a batch of rays: chunks of kChunk rays in parallel, each
  /// cast twice in one go (no batch-sized temporaries).
  void trace(std::span<const Ray> first, std::span<SkinSample> out) const;
  /// Exact trace of a few rays (up to a few hundred) at once: first cast,
  /// refraction, second cast, all on the calling thread but for the ray
  /// index's own parallelism.
  void trace_chunk(std::span<const Ray> first, std::span<SkinSample> out) const;

 private:
  static constexpr std::size_t kChunk = 256;
  struct Scratch {
    std::vector<RayHit> hit, cast_hit;
    std::vector<Ray> second, cast_ray;
    std::vector<std::uint32_t> which;
  };
  // Casts rays[which[k]] into w.hit[which[k]].
  void cast(std::span<const Ray> rays, Scratch& w) const;
  static bool fail(SkinSample& s, PixelStatus why) {
    s.status = why;
    return false;
  }
  const TraceScene& scene_;
  optics::Indices n_;
  bool smooth_, index_matched_;
  std::unique_ptr<FlatSlab> slab_;
};

// ---- 3. store --------------------------------------------------------------

/// Sizes every per-pixel array of `map` to width x height without filling them.
void allocate(RefractionMap& map, int width, int height);
/// Sets the n pixels from p on to `why` with every field NaN / -1, a field at a time.
void reset_span(RefractionMap& map, std::size_t p, std::size_t n, PixelStatus why = PixelStatus::outside);
/// The same for one pixel, status outside.
inline void reset(RefractionMap& map, std::size_t p) { reset_span(map, p, 1); }
/// Writes every per-pixel field of the map from one sample.
void store(RefractionMap& map, const TraceScene& scene, std::size_t p, const SkinSample& s);
/// Barycentric weights of `point` projected onto the plane of `face`.
std::array<double, 3> plane_bary(const Mesh& mesh, int face, const Vec3& point);
/// Counts the pixels by status into map.stats (by_status, coverage).
void count_statuses(RefractionMap& map);

// ---- 4. fill ---------------------------------------------------------------

/// What every filling stage reads: the scene, the options, the tracer, the
/// camera's rays and the part's pixel bound; and the map it writes.
struct MapRun {
  const TraceScene& scene;
  const MapOptions& options;
  const Tracer& tracer;
  CameraRays& rays;
  Rigid3 part_from_cam;
  PixelBox box;
  RefractionMap& map;
  /// The camera ray of pixel p in the part frame (p must be ensured).
  Ray first_ray(std::uint32_t p) const {
    Ray r;
    r.origin = part_from_cam.translation;
    r.direction = part_from_cam.rotation * rays.ray(p);
    return r;
  }
};

/// Exact mode: every pixel of the bound traced, the rest reset to outside.
void trace_exact(const MapRun& run);
/// Grid and adaptive modes: the pixels outside the bound reset, the rest
/// traced or interpolated by the quadtree (quadtree.hpp).
void refine_quadtree(const MapRun& run);

// ---- 5. outline -------------------------------------------------------------

/// map.seen_fraction: 0 / 1 from the status, and on the outline (a pixel whose 8 neighbours do not all
/// share its status) the share of a 4 × 4 grid of rays over the pixel's square that sees the skin.
void measure_seen_fraction(const MapRun& run);

}  // namespace clearfit::refraction_detail
