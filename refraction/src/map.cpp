#include "chart_locator.hpp"
#include "flat_slab.hpp"
#include "npy.hpp"
#include "quadratic_fit.hpp"

#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/refraction/map.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>

namespace clearfit {

const char* to_string(PixelStatus s) {
  switch (s) {
    case PixelStatus::valid: return "valid";
    case PixelStatus::outside: return "outside";
    case PixelStatus::miss: return "miss";
    case PixelStatus::no_ray: return "no_ray";
    case PixelStatus::contact_first: return "contact_first";
    case PixelStatus::back_face: return "back_face";
    case PixelStatus::entry_tir: return "entry_tir";
    case PixelStatus::exits_elsewhere: return "exits_elsewhere";
    case PixelStatus::contact_tir: return "contact_tir";
  }
  return "?";
}

void MapOptions::validate() const {
  indices.validate();
  auto fail = [](const std::string& what) { throw std::invalid_argument("MapOptions::" + what); };
  if (grid_step < 2 || grid_step > 256 || (grid_step & (grid_step - 1)) != 0)
    fail("grid_step = " + std::to_string(grid_step) + ": must be a power of two in [2, 256]");
  if (!(tolerance_um > 0) || !std::isfinite(tolerance_um))
    fail("tolerance_um = " + std::to_string(tolerance_um) + ": must be a finite number > 0");
}

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr float fnan = std::numeric_limits<float>::quiet_NaN();

// Ray directions depend only on the camera's intrinsics: unprojected once per
// camera per process, lazily, only for the pixels a map actually traces
// (mrcal's unprojection is iterative and costs more than the ray casts).
class CameraRays {
 public:
  explicit CameraRays(const CameraModel& camera)
      : camera_(camera), rays_(static_cast<std::size_t>(camera.width) * camera.height), known_(rays_.size(), 0) {}
  /// Unprojects those of `pixels` (pixel indices) not unprojected before.
  /// Afterwards ray(p) of each of them may be read from any thread.
  void ensure(std::span<const std::uint32_t> pixels) {
    std::lock_guard lock(mutex_);
    std::vector<std::uint32_t> missing;
    for (std::uint32_t p : pixels)
      if (!known_[p]) missing.push_back(p);
    fill(missing);
  }
  /// The same for every pixel of rows y0..y1, columns x0..x1 (inclusive).
  void ensure(int x0, int y0, int x1, int y1) {
    std::lock_guard lock(mutex_);
    std::vector<std::uint32_t> missing;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        if (const auto p = static_cast<std::uint32_t>(y * camera_.width + x); !known_[p]) missing.push_back(p);
    fill(missing);
  }
  /// Unit ray of pixel index p (zero if the lens cannot unproject it); p must be ensured.
  const Vec3& ray(std::uint32_t p) const { return rays_[p]; }

 private:
  void fill(const std::vector<std::uint32_t>& missing) {
    if (missing.empty()) return;
    std::vector<Vec2> q(missing.size());
    for (std::size_t i = 0; i < missing.size(); ++i) q[i] = Vec2(missing[i] % camera_.width, missing[i] / camera_.width);
    std::vector<Vec3> r(missing.size());
    camera_.unproject(q, r);
    for (std::size_t i = 0; i < missing.size(); ++i) {
      rays_[missing[i]] = r[i].allFinite() ? Vec3(r[i].normalized()) : Vec3::Zero();
      known_[missing[i]] = 1;
    }
  }
  std::mutex mutex_;
  CameraModel camera_;
  std::vector<Vec3> rays_;
  std::vector<char> known_;
};

std::shared_ptr<CameraRays> camera_rays(const CameraModel& camera) {
  static std::mutex mutex;
  static std::map<std::uint64_t, std::shared_ptr<CameraRays>> cache;
  std::lock_guard lock(mutex);
  const std::uint64_t key = camera.intrinsics_hash();
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  if (cache.size() >= 4) cache.clear();
  return cache.emplace(key, std::make_shared<CameraRays>(camera)).first->second;
}

// Pixel bound of the part's image: the box around the projected vertices,
// widened by a margin for lens curvature between vertices. nullopt: no bound
// (some vertex is behind the camera or does not project).
struct PixelBox {
  int x0, y0, x1, y1;  // inclusive
};
std::optional<PixelBox> part_bound(const Mesh& mesh, const CameraModel& camera, const Rigid3& cam_from_part) {
  // Projected in parallel chunks; a vertex behind the camera or one the lens
  // cannot project gives no bound (NaN poisons the chunk's box).
  struct Bounds {
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    bool ok = true;
  };
  const Bounds b = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, mesh.vertices.size(), 4096), Bounds{},
      [&](const tbb::blocked_range<std::size_t>& r, Bounds acc) {
        if (!acc.ok) return acc;
        std::vector<Vec3> in_cam(r.size());
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          in_cam[i - r.begin()] = cam_from_part.apply(mesh.vertices[i]);
          if (!(in_cam[i - r.begin()].z() > 0)) return Bounds{.ok = false};
        }
        for (const Vec2& p : camera.project(in_cam)) {
          if (!p.allFinite()) return Bounds{.ok = false};
          acc.x0 = std::min(acc.x0, p.x()), acc.y0 = std::min(acc.y0, p.y());
          acc.x1 = std::max(acc.x1, p.x()), acc.y1 = std::max(acc.y1, p.y());
        }
        return acc;
      },
      [](const Bounds& a, const Bounds& c) {
        if (!a.ok || !c.ok) return Bounds{.ok = false};
        return Bounds{std::min(a.x0, c.x0), std::min(a.y0, c.y0), std::max(a.x1, c.x1), std::max(a.y1, c.y1), true};
      });
  if (!b.ok || mesh.vertices.empty()) return std::nullopt;
  const double x0 = b.x0, y0 = b.y0, x1 = b.x1, y1 = b.y1;
  const double margin = 4.0 + 0.01 * std::max(x1 - x0, y1 - y0);
  auto clampi = [](double v, int hi) { return static_cast<int>(std::clamp(v, -1.0, static_cast<double>(hi) + 1)); };
  PixelBox box{clampi(std::ceil(x0 - margin), camera.width - 1), clampi(std::ceil(y0 - margin), camera.height - 1),
               clampi(std::floor(x1 + margin), camera.width - 1), clampi(std::floor(y1 + margin), camera.height - 1)};
  box.x0 = std::max(box.x0, 0), box.y0 = std::max(box.y0, 0);
  box.x1 = std::min(box.x1, camera.width - 1), box.y1 = std::min(box.y1, camera.height - 1);
  return box;
}

// Smallest t at which a ray leaving a point computed on `face` can no longer
// re-hit that face's plane through rounding: the point (computed as
// origin + t·d of the incoming ray) is off the plane by at most a few ulp of
// the largest magnitude involved (its coordinates, the face's vertices, the
// incoming ray's origin and length); along a direction making cosine `cos_n`
// with the plane's normal that becomes a distance / cos_n.
double leave_surface_t(const Mesh& mesh, int face, const Vec3& point, double cos_n, double incoming_scale) {
  double scale = std::max(point.cwiseAbs().maxCoeff(), incoming_scale);
  for (int k = 0; k < 3; ++k) scale = std::max(scale, mesh.corner(face, k).cwiseAbs().maxCoeff());
  const double err = 16 * std::numeric_limits<double>::epsilon() * scale;
  return err / std::max(cos_n, 1e-6);
}

// The two stages of a trace, shared by the batch map and single rays.
class Tracer {
 public:
  Tracer(const TraceScene& scene, const MapOptions& opt)
      : scene_(scene), n_(opt.indices), smooth_(opt.normals == MapOptions::Normals::smooth),
        index_matched_(opt.fast_paths && opt.indices.n_medium == opt.indices.n_part) {
    if (opt.fast_paths)
      slab_ = refraction_detail::FlatSlab::detect(*scene.mesh, *scene.contact, scene.index->normals());
  }
  bool index_matched() const { return index_matched_; }
  bool flat_slab() const { return slab_ != nullptr; }
  std::string fast_path() const {
    std::string s = index_matched_ ? "index-matched" : "";
    if (slab_) s += s.empty() ? "flat-slab" : "+flat-slab";
    return s.empty() ? "none" : s;
  }

  /// Classifies the first hit; returns true and fills `second` when the ray
  /// goes on into the part.
  bool enter(const Ray& first, const RayHit& h, SkinSample& s, Ray& second) const {
    if (first.direction.isZero() || !first.direction.allFinite() || !first.origin.allFinite())
      return fail(s, PixelStatus::no_ray);
    if (!h) return fail(s, PixelStatus::miss);
    if (!h.front_facing) return fail(s, PixelStatus::back_face);
    if (scene_.contact->is_contact[h.face]) return fail(s, PixelStatus::contact_first);
    const Vec3 d = first.direction.normalized();
    Vec3 nrm = smooth_ ? h.shading_normal : h.geometric_normal;
    if (nrm.dot(d) >= 0) nrm = h.geometric_normal;  // shading normal turned away near a silhouette
    s.entry_point = h.point;
    s.entry_face = h.face;
    s.entry_normal = nrm;
    s.incidence_deg = optics::angle_between(-d, nrm) * kRadToDeg;
    Vec3 d2 = d;
    s.transmittance = 1;
    if (!index_matched_) {
      const optics::Transmission t = optics::transmit(d, nrm, n_.n_medium, n_.n_part);
      if (t.tir) return fail(s, PixelStatus::entry_tir);
      s.transmittance = optics::fresnel(t, n_.n_medium, n_.n_part).T;
      d2 = t.direction;
    }
    s.refracted_dir = d2;
    second.origin = h.point;
    second.direction = d2;
    const double incoming = first.origin.cwiseAbs().maxCoeff() + std::abs(h.t) * first.direction.norm();
    second.t_min = leave_surface_t(*scene_.mesh, h.face, h.point, std::abs(d2.dot(h.geometric_normal)), incoming);
    second.t_max = std::numeric_limits<double>::infinity();
    second.skip_face = h.face;  // a ray cannot meet the plane it leaves again
    return true;
  }

  /// Classifies the hit of the refracted ray.
  void reach(const RayHit& h, SkinSample& s) const {
    if (!h || !scene_.contact->is_contact[h.face]) { fail(s, PixelStatus::exits_elsewhere); return; }
    const Vec3& d2 = s.refracted_dir;
    Vec3 nrm = smooth_ ? h.shading_normal : h.geometric_normal;
    if (nrm.dot(d2) <= 0) nrm = h.geometric_normal;
    s.contact_deg = optics::angle_between(d2, nrm) * kRadToDeg;
    if (n_.n_part != n_.n_skin) {
      const optics::Transmission t = optics::transmit(d2, nrm, n_.n_part, n_.n_skin);
      if (t.tir) { fail(s, PixelStatus::contact_tir); return; }
      s.transmittance *= optics::fresnel(t, n_.n_part, n_.n_skin).T;
    }
    s.status = PixelStatus::valid;
    s.skin_point = h.point;
    s.face = h.face;
    s.bary = h.bary;
  }

  /// Exact trace of a batch of rays: chunks of kChunk rays in parallel, each
  /// cast twice in one go (no batch-sized temporaries).
  void trace(std::span<const Ray> first, std::span<SkinSample> out) const {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, first.size(), kChunk), [&](const auto& r) {
      for (std::size_t b = r.begin(); b < r.end(); b += kChunk) {
        const std::size_t n = std::min(kChunk, r.end() - b);
        trace_chunk(first.subspan(b, n), out.subspan(b, n));
      }
    });
  }

  /// Exact trace of a few rays (up to a few hundred) at once: first cast,
  /// refraction, second cast, all on the calling thread but for the ray
  /// index's own parallelism.
  void trace_chunk(std::span<const Ray> first, std::span<SkinSample> out) const {
    Scratch w;  // per call: a nested parallel_for in intersect() may run another chunk on this thread
    const std::size_t n = first.size();
    w.hit.resize(n);
    w.which.clear();
    // Rays without a usable direction (the lens could not unproject) are not cast.
    for (std::size_t i = 0; i < n; ++i) {
      w.hit[i] = RayHit{};
      if (first[i].direction.isZero() || !first[i].direction.allFinite() || !first[i].origin.allFinite()) continue;
      if (slab_)  // closed form where the ray enters through the outer plane; the rest go to the index
        if (auto h = slab_->enter(first[i])) {
          w.hit[i] = *h;
          continue;
        }
      w.which.push_back(static_cast<std::uint32_t>(i));
    }
    cast(first, w);
    w.second.resize(n);
    w.which.clear();
    for (std::size_t i = 0; i < n; ++i) {
      out[i] = SkinSample{};
      if (!enter(first[i], w.hit[i], out[i], w.second[i])) continue;
      if (slab_)
        if (auto h = slab_->reach(w.second[i])) {
          reach(*h, out[i]);
          continue;
        }
      w.which.push_back(static_cast<std::uint32_t>(i));
    }
    cast(w.second, w);
    for (std::uint32_t i : w.which) reach(w.hit[i], out[i]);
  }

 private:
  static constexpr std::size_t kChunk = 256;
  struct Scratch {
    std::vector<RayHit> hit, cast_hit;
    std::vector<Ray> second, cast_ray;
    std::vector<std::uint32_t> which;
  };
  // Casts rays[which[k]] into w.hit[which[k]].
  void cast(std::span<const Ray> rays, Scratch& w) const {
    if (w.which.empty()) return;
    if (w.which.size() == rays.size()) {
      scene_.index->intersect(rays, std::span<RayHit>(w.hit.data(), rays.size()));
      return;
    }
    w.cast_ray.resize(w.which.size());
    w.cast_hit.resize(w.which.size());
    for (std::size_t k = 0; k < w.which.size(); ++k) w.cast_ray[k] = rays[w.which[k]];
    scene_.index->intersect(w.cast_ray, w.cast_hit);
    for (std::size_t k = 0; k < w.which.size(); ++k) w.hit[w.which[k]] = w.cast_hit[k];
  }
  static bool fail(SkinSample& s, PixelStatus why) {
    s.status = why;
    return false;
  }
  const TraceScene& scene_;
  optics::Indices n_;
  bool smooth_, index_matched_;
  std::unique_ptr<refraction_detail::FlatSlab> slab_;
};

void check_scene(const TraceScene& scene) {
  if (!scene.mesh || !scene.contact || !scene.index)
    throw std::invalid_argument("refraction: TraceScene needs mesh, contact and index");
  if (static_cast<int>(scene.contact->is_contact.size()) != scene.mesh->num_faces())
    throw std::invalid_argument("refraction: the contact surface belongs to another mesh");
  if (scene.contact->faces.empty())
    throw InputError(scene.mesh->source, "contact surface", "has no faces", "choose the faces the skin touches");
}

// Sets the n pixels from p on to `why` with every field NaN / -1, a field at a time.
void reset_span(RefractionMap& map, std::size_t p, std::size_t n, PixelStatus why = PixelStatus::outside) {
  constexpr double dnan = std::numeric_limits<double>::quiet_NaN();
  std::fill_n(map.status.begin() + p, n, why);
  std::fill_n(map.skin_point.begin() + p, n, Vec3(dnan, dnan, dnan));
  std::fill_n(map.face.begin() + p, n, -1);
  std::fill_n(map.bary.begin() + p, n, Eigen::Vector2f(fnan, fnan));
  std::fill_n(map.chart_uv.begin() + p, n, Eigen::Vector2f(fnan, fnan));
  std::fill_n(map.incidence_deg.begin() + p, n, fnan);
  std::fill_n(map.contact_deg.begin() + p, n, fnan);
  std::fill_n(map.transmittance.begin() + p, n, fnan);
}

// The same for one pixel, status outside.
void reset(RefractionMap& map, std::size_t p) { reset_span(map, p, 1); }

// Writes every per-pixel field of the map from one sample.
void store(RefractionMap& map, const TraceScene& scene, std::size_t p, const SkinSample& s) {
  reset(map, p);
  map.status[p] = s.status;
  map.incidence_deg[p] = static_cast<float>(s.incidence_deg);
  if (s.status != PixelStatus::valid) return;
  map.skin_point[p] = s.skin_point;
  map.face[p] = s.face;
  map.bary[p] = Eigen::Vector2f(static_cast<float>(s.bary[1]), static_cast<float>(s.bary[2]));
  map.contact_deg[p] = static_cast<float>(s.contact_deg);
  map.transmittance[p] = static_cast<float>(s.transmittance);
  if (scene.chart && !scene.chart->uv.empty()) {
    const auto& f = scene.mesh->faces[s.face];
    const Vec2 uv = s.bary[0] * scene.chart->uv[f[0]] + s.bary[1] * scene.chart->uv[f[1]] + s.bary[2] * scene.chart->uv[f[2]];
    map.chart_uv[p] = uv.cast<float>();
  }
}

// Barycentric weights of `point` projected onto the plane of `face`.
std::array<double, 3> plane_bary(const Mesh& mesh, int face, const Vec3& point) {
  const Vec3 a = mesh.corner(face, 0), e1 = mesh.corner(face, 1) - a, e2 = mesh.corner(face, 2) - a;
  const Vec3 d = point - a;
  const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), det = d11 * d22 - d12 * d12;
  const double b1 = det > 0 ? (d22 * d.dot(e1) - d12 * d.dot(e2)) / det : 0;
  const double b2 = det > 0 ? (d11 * d.dot(e2) - d12 * d.dot(e1)) / det : 0;
  return {1 - b1 - b2, b1, b2};
}

struct Cell {
  int x0, y0, x1, y1;  // corner pixels (inclusive)
};
// Cells up to this size (pixels) that a validity boundary crosses go to the
// boundary resolver instead of being split further.
constexpr int kResolveCell = 8;

}  // namespace

void trace_skin_rays(const TraceScene& scene, std::span<const Ray> rays, std::span<SkinSample> out,
                     const MapOptions& options) {
  options.validate();
  check_scene(scene);
  if (rays.size() != out.size()) throw std::invalid_argument("trace_skin_rays: rays and out differ in size");
  std::vector<Ray> first(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) first[i] = Ray{rays[i].origin, rays[i].direction};
  Tracer(scene, options).trace(first, out);
}

SkinSample trace_skin_ray(const TraceScene& scene, const Vec3& origin, const Vec3& direction, const MapOptions& options) {
  const Ray ray{origin, direction};
  SkinSample s;
  trace_skin_rays(scene, std::span<const Ray>(&ray, 1), std::span<SkinSample>(&s, 1), options);
  return s;
}

RefractionMap compute_refraction_map(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                                     const MapOptions& options) {
  const auto t_start = Clock::now();
  options.validate();
  check_scene(scene);
  camera.validate();
  const Mesh& mesh = *scene.mesh;

  const int W = camera.width, H = camera.height;
  const std::size_t N = static_cast<std::size_t>(W) * H;
  RefractionMap map;
  map.width = W;
  map.height = H;
  // Sized here, filled in parallel below (every pixel gets reset() once).
  map.status.resize(N);
  map.skin_point.resize(N);
  map.face.resize(N);
  map.bary.resize(N);
  map.chart_uv.resize(N);
  map.incidence_deg.resize(N);
  map.contact_deg.resize(N);
  map.transmittance.resize(N);
  MapStats& st = map.stats;
  st.pixels = static_cast<long long>(N);
  st.mode = options.mode == MapOptions::Mode::exact ? "exact" : options.mode == MapOptions::Mode::grid ? "grid" : "adaptive";

  bool any_in_front = false;
  for (const Vec3& v : mesh.vertices) any_in_front |= cam_from_part.apply(v).z() > 0;
  if (!any_in_front)
    throw InputError("", "pose (cam_from_part)",
                     "puts the whole part behind the camera (every vertex has z <= 0 in the camera frame)",
                     "check the pose's direction and units (mm)");

  const std::shared_ptr<CameraRays> rays = camera_rays(camera);
  auto t0 = Clock::now();
  PixelBox box{0, 0, W - 1, H - 1};
  if (options.cull)
    if (auto b = part_bound(mesh, camera, cam_from_part)) box = *b;
  st.cull_ms = ms_since(t0);

  t0 = Clock::now();
  const Tracer tracer(scene, options);
  st.fast_path = tracer.fast_path();
  const Rigid3 part_from_cam = cam_from_part.inverse();
  const bool box_empty = box.x0 > box.x1 || box.y0 > box.y1;
  if (options.mode == MapOptions::Mode::exact) {
    // One pass over 16x16 tiles in parallel: per tile reset the pixels outside
    // the box, trace those in it (rays from the per-camera cache, two casts)
    // and store them; nothing image-sized besides the map itself.
    if (!box_empty) {
      const auto tu = Clock::now();
      rays->ensure(box.x0, box.y0, box.x1, box.y1);
      st.unproject_ms += ms_since(tu);
    }
    constexpr int T = 16;
    const int tiles_x = (W + T - 1) / T, tiles_y = (H + T - 1) / T;
    tbb::parallel_for(0, tiles_x * tiles_y, [&](int t) {
      const int tx0 = t % tiles_x * T, ty0 = t / tiles_x * T, tx1 = std::min(tx0 + T, W), ty1 = std::min(ty0 + T, H);
      std::array<std::uint32_t, T * T> pixel;
      std::array<Ray, T * T> first;
      std::array<SkinSample, T * T> out;
      std::size_t n = 0;
      for (int y = ty0; y < ty1; ++y)
        for (int x = tx0; x < tx1; ++x) {
          const auto p = static_cast<std::uint32_t>(map.index(x, y));
          if (box_empty || x < box.x0 || x > box.x1 || y < box.y0 || y > box.y1) {
            reset(map, p);
            continue;
          }
          pixel[n] = p;
          first[n].origin = part_from_cam.translation;
          first[n].direction = part_from_cam.rotation * rays->ray(p);
          ++n;
        }
      if (n == 0) return;
      tracer.trace_chunk(std::span(first.data(), n), std::span(out.data(), n));
      for (std::size_t i = 0; i < n; ++i) store(map, scene, pixel[i], out[i]);
    });
    if (!box_empty) st.traced = static_cast<long long>(box.x1 - box.x0 + 1) * (box.y1 - box.y0 + 1);
  } else {  // pixels in the box are written when traced or filled
    tbb::parallel_for(0, H, [&](int y) {
      if (box_empty || y < box.y0 || y > box.y1) return reset_span(map, map.index(0, y), W);
      reset_span(map, map.index(0, y), box.x0);
      reset_span(map, map.index(box.x1 + 1, y), W - 1 - box.x1);
    });
  }
  std::vector<char> traced(options.mode == MapOptions::Mode::exact ? 0 : N, 0);
  // Exact trace of the listed pixels that are not traced yet.
  auto trace_pixels = [&](const std::vector<std::uint32_t>& pixels_in) {
    // Distinct untraced pixels, in the callers' order (cell by cell: nearby
    // pixels go into the same chunk, so the casts stay coherent).
    std::vector<std::uint32_t> pixels;
    pixels.reserve(pixels_in.size());
    for (std::uint32_t p : pixels_in)
      if (!traced[p]) traced[p] = 5, pixels.push_back(p);  // 5: queued
    const auto tu = Clock::now();
    rays->ensure(pixels);
    st.unproject_ms += ms_since(tu);
    // Chunks of up to 256 rays in parallel: rays, two casts, store (distinct
    // pixels: no races); nothing batch-sized besides the pixel list.
    constexpr std::size_t kChunk = 256;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pixels.size(), kChunk), [&](const auto& r) {
      for (std::size_t b = r.begin(); b < r.end(); b += kChunk) {
        const std::size_t n = std::min(kChunk, r.end() - b);
        std::array<Ray, kChunk> first;
        std::array<SkinSample, kChunk> out;
        for (std::size_t i = 0; i < n; ++i) {
          first[i].origin = part_from_cam.translation;
          first[i].direction = part_from_cam.rotation * rays->ray(pixels[b + i]);
        }
        tracer.trace_chunk(std::span(first.data(), n), std::span(out.data(), n));
        for (std::size_t i = 0; i < n; ++i) {
          store(map, scene, pixels[b + i], out[i]);
          traced[pixels[b + i]] = 1;
        }
      }
    });
    st.traced += static_cast<long long>(pixels.size());
  };

  if (!box_empty) {
    if (options.mode != MapOptions::Mode::exact) {
      // Quadtree over pixel cells with up to nine nodes each (corners, edge
      // midpoints, centre), all traced exactly; the interior is filled by
      // tensor-product quadratic (Lagrange) interpolation of the nodes. Two
      // check pixels (1/4 and 3/4 of the diagonal) are traced too; adaptive
      // splits the cell into its quadrants (whose corners are nodes already)
      // unless the interpolation is within tolerance there. Each level's
      // nodes and checks are traced in one batch. Small cells that a validity
      // boundary crosses go to resolve_boundary() instead of being split.
      const bool adaptive = options.mode == MapOptions::Mode::adaptive;
      const double tol_mm = options.tolerance_um * 1e-3;
      const std::vector<int>& component = scene.contact->component;
      const int S = options.grid_step;
      std::vector<Cell> cells;
      for (int y = box.y0; y < box.y1 || y == box.y0; y += S)
        for (int x = box.x0; x < box.x1 || x == box.x0; x += S)
          cells.push_back({x, y, std::min(x + S, box.x1), std::min(y + S, box.y1)});
      auto idx = [&](int x, int y) { return static_cast<std::uint32_t>(map.index(x, y)); };
      double worst = 0;
      std::vector<std::uint32_t> retrace;
      // The interpolant: with a chart, chart coordinates are interpolated
      // (smooth: no surface sag) and put back on the mesh by point location,
      // so the point lies on the surface. Without one: the skin points
      // themselves, with the face of the heaviest node. nullopt: the location
      // fell outside the chart.
      std::optional<refraction_detail::ChartLocator> locator;
      if (scene.chart && !scene.chart->uv.empty()) locator.emplace(mesh, *scene.chart);
      struct Interp {
        Vec3 point;
        int face;
        std::array<double, 3> bary;
        Vec2 uv;
      };
      struct Nodes {
        int n = 0;
        std::uint32_t pixel[9];
        int ax[3], ay[3], nx = 0, ny = 0;
      };
      auto nodes_of = [&](const Cell& c) {
        Nodes q;
        auto axis = [](int a0, int a1, int* at) {
          if (a1 == a0) return at[0] = a0, 1;
          if (a1 - a0 == 1) return at[0] = a0, at[1] = a1, 2;
          return at[0] = a0, at[1] = (a0 + a1) / 2, at[2] = a1, 3;
        };
        q.nx = axis(c.x0, c.x1, q.ax);
        q.ny = axis(c.y0, c.y1, q.ay);
        for (int j = 0; j < q.ny; ++j)
          for (int i = 0; i < q.nx; ++i) q.pixel[q.n++] = idx(q.ax[i], q.ay[j]);
        return q;
      };
      // Lagrange weights of the nodes at pixel (x, y).
      auto weights = [](const Nodes& q, int x, int y) {
        std::array<double, 9> w{};
        double wx[3], wy[3];
        for (int i = 0; i < q.nx; ++i) {
          wx[i] = 1;
          for (int k = 0; k < q.nx; ++k)
            if (k != i) wx[i] *= double(x - q.ax[k]) / (q.ax[i] - q.ax[k]);
        }
        for (int j = 0; j < q.ny; ++j) {
          wy[j] = 1;
          for (int k = 0; k < q.ny; ++k)
            if (k != j) wy[j] *= double(y - q.ay[k]) / (q.ay[j] - q.ay[k]);
        }
        for (int j = 0; j < q.ny; ++j)
          for (int i = 0; i < q.nx; ++i) w[j * q.nx + i] = wx[i] * wy[j];
        return w;
      };
      auto interpolate = [&](const Nodes& q, const std::array<double, 9>& w) -> std::optional<Interp> {
        int heaviest = 0;
        for (int k = 0; k < q.n; ++k)
          if (w[k] > w[heaviest]) heaviest = k;
        if (locator) {
          Vec2 uv = Vec2::Zero();
          for (int k = 0; k < q.n; ++k) uv += w[k] * map.chart_uv[q.pixel[k]].cast<double>();
          const auto hit = locator->locate(uv);
          if (!hit) return std::nullopt;
          return Interp{hit->point, hit->face, hit->bary, uv};
        }
        Interp r{Vec3::Zero(), map.face[q.pixel[heaviest]], {}, Vec2::Constant(std::numeric_limits<double>::quiet_NaN())};
        for (int k = 0; k < q.n; ++k) r.point += w[k] * map.skin_point[q.pixel[k]];
        r.bary = plane_bary(mesh, r.face, r.point);
        return r;
      };
      // Writes the interpolated fields of pixel p (weights w of the nodes).
      auto write_interp = [&](std::uint32_t p, const Nodes& q, const std::array<double, 9>& w, const Interp& r) {
        map.status[p] = PixelStatus::valid;
        map.skin_point[p] = r.point;
        map.face[p] = r.face;
        map.bary[p] = Eigen::Vector2f(static_cast<float>(r.bary[1]), static_cast<float>(r.bary[2]));
        map.chart_uv[p] = r.uv.cast<float>();
        float inc = 0, con = 0, T = 0;
        for (int k = 0; k < q.n; ++k) {
          const float wk = static_cast<float>(w[k]);
          inc += wk * map.incidence_deg[q.pixel[k]];
          con += wk * map.contact_deg[q.pixel[k]];
          T += wk * map.transmittance[q.pixel[k]];
        }
        map.incidence_deg[p] = inc;
        map.contact_deg[p] = con;
        map.transmittance[p] = std::clamp(T, 0.0f, 1.0f);
      };
      // Fills the untraced pixels of an accepted cell through the chart
      // (point location per pixel); pixels the location misses are marked
      // for an exact trace (traced = 3). Returns the pixels filled.
      auto fill_located = [&](const Cell& c, const Nodes& q, int xe, int ye) {
        long long count = 0;
        for (int y = c.y0; y <= ye; ++y)
          for (int x = c.x0; x <= xe; ++x) {
            const std::uint32_t p = idx(x, y);
            if (traced[p]) continue;
            const auto w = weights(q, x, y);
            const auto r = interpolate(q, w);
            if (!r) {
              traced[p] = 3;
              continue;
            }
            traced[p] = 2;
            write_interp(p, q, w, *r);
            ++count;
          }
        return count;
      };
      // The same without a chart: the skin points themselves, each on the face
      // of the heaviest node. Prepared per cell, then written row by row
      // across all cells of a level (long runs along the rows write at about
      // twice the memory bandwidth of cell by cell). Gives interpolate()'s
      // result up to rounding.
      struct DirectFill {
        // Per node's face: corner 0 and the two vectors whose dot products
        // with (point - corner 0) give the barycentric weights of corners 1, 2.
        struct Frame {
          Vec3 a, g1, g2;
          int face;
        };
        using Val = Eigen::Matrix<double, 6, 1>;  // skin point, incidence, contact, transmittance
        Nodes q;
        int x0, y0, xe, ye;
        std::array<Frame, 9> frame;
        std::array<Val, 9> node_val;
        double wx0[3][3];      // x weights at x0, x0 + 1, x0 + 2
        int ix_from[3], ix_n;  // heaviest node column: column ix_of[k] from x0 + ix_from[k] on
        int ix_of[3];
      };
      auto lagrange = [](const int* at, int n, int v, double* w) {
        int best = 0;
        for (int i = 0; i < n; ++i) {
          w[i] = 1;
          for (int k = 0; k < n; ++k)
            if (k != i) w[i] *= double(v - at[k]) / (at[i] - at[k]);
          if (w[i] > w[best]) best = i;
        }
        return best;
      };
      auto prepare_direct = [&](const Cell& c, DirectFill& f) {
        f.q = nodes_of(c);
        const Nodes& q = f.q;
        f.x0 = c.x0, f.y0 = c.y0;
        f.xe = c.x1 == box.x1 ? c.x1 : c.x1 - 1, f.ye = c.y1 == box.y1 ? c.y1 : c.y1 - 1;
        for (int k = 0; k < q.n; ++k) {
          DirectFill::Frame& fr = f.frame[k];
          const std::uint32_t n = q.pixel[k];
          fr.face = map.face[n];
          fr.a = mesh.corner(fr.face, 0);
          const Vec3 e1 = mesh.corner(fr.face, 1) - fr.a, e2 = mesh.corner(fr.face, 2) - fr.a;
          const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), det = d11 * d22 - d12 * d12;
          const double inv = det > 0 ? 1 / det : 0;
          fr.g1 = (d22 * e1 - d12 * e2) * inv;
          fr.g2 = (d11 * e2 - d12 * e1) * inv;
          f.node_val[k] << map.skin_point[n], map.incidence_deg[n], map.contact_deg[n], map.transmittance[n];
        }
        for (int k = 0; k < 3; ++k) lagrange(q.ax, q.nx, f.x0 + k, f.wx0[k]);
        f.ix_n = 0;
        for (int x = f.x0; x <= f.xe; ++x) {
          double w[3];
          const int ix = lagrange(q.ax, q.nx, x, w);
          if (f.ix_n == 0 || f.ix_of[f.ix_n - 1] != ix) f.ix_from[f.ix_n] = x - f.x0, f.ix_of[f.ix_n++] = ix;
        }
      };
      // Row y of a prepared cell. Along a row the interpolant is a polynomial
      // of degree nx - 1 <= 2 in x: values at x0, x0 + 1, x0 + 2, then forward
      // differences.
      auto fill_direct_row = [&](const DirectFill& f, int y) {
        using Val = DirectFill::Val;
        const Nodes& q = f.q;
        double wy[3];
        const int jy = lagrange(q.ay, q.ny, y, wy);
        Val row[3];
        for (int i = 0; i < q.nx; ++i) {
          row[i].setZero();
          for (int j = 0; j < q.ny; ++j) row[i] += wy[j] * f.node_val[j * q.nx + i];
        }
        Val v[3];
        for (int k = 0; k < 3; ++k) {
          v[k].setZero();
          for (int i = 0; i < q.nx; ++i) v[k] += f.wx0[k][i] * row[i];
        }
        // Forward differences of the values and, per run of one heaviest node
        // column, of the two barycentric weights (linear in the point).
        using Val8 = Eigen::Matrix<double, 8, 1>;
        Val8 value, d1, d2;
        value << v[0], 0, 0;
        d1 << v[1] - v[0], 0, 0;
        d2 << v[2] - 2 * v[1] + v[0], 0, 0;
        const std::uint32_t row_start = idx(f.x0, y);
        long long count = 0;
        const int n = f.xe - f.x0 + 1;
        for (int seg = 0; seg < f.ix_n; ++seg) {
          const DirectFill::Frame& fr = f.frame[jy * q.nx + f.ix_of[seg]];
          const int xi_end = seg + 1 < f.ix_n ? f.ix_from[seg + 1] : n;
          value[6] = (value.head<3>() - fr.a).dot(fr.g1), value[7] = (value.head<3>() - fr.a).dot(fr.g2);
          d1[6] = d1.head<3>().dot(fr.g1), d1[7] = d1.head<3>().dot(fr.g2);
          d2[6] = d2.head<3>().dot(fr.g1), d2[7] = d2.head<3>().dot(fr.g2);
          for (int xi = f.ix_from[seg]; xi < xi_end; ++xi, value += d1, d1 += d2) {
            const std::uint32_t p = row_start + static_cast<std::uint32_t>(xi);
            if (traced[p]) continue;
            traced[p] = 2;
            map.status[p] = PixelStatus::valid;
            map.skin_point[p] = value.head<3>();
            map.face[p] = fr.face;
            map.bary[p] = Eigen::Vector2f(static_cast<float>(value[6]), static_cast<float>(value[7]));
            map.chart_uv[p] = Eigen::Vector2f(fnan, fnan);
            map.incidence_deg[p] = static_cast<float>(value[3]);
            map.contact_deg[p] = static_cast<float>(value[4]);
            map.transmittance[p] = std::clamp(static_cast<float>(value[5]), 0.0f, 1.0f);
            ++count;
          }
        }
        return count;
      };
      // Row y of a cell that is uniformly invalid for reason `why`: runs of
      // untraced pixels, a field at a time.
      auto fill_invalid_row = [&](int x0, int xe, int y, PixelStatus why) {
        for (int x = x0; x <= xe;) {
          if (traced[idx(x, y)]) {
            ++x;
            continue;
          }
          int run = 1;
          while (x + run <= xe && !traced[idx(x + run, y)]) ++run;
          reset_span(map, idx(x, y), run, why);
          std::fill_n(traced.begin() + idx(x, y), run, 2);
          x += run;
        }
      };
      auto done = [](const Cell& c) { return c.x1 - c.x0 <= 2 && c.y1 - c.y0 <= 2; };  // every pixel is a node
      // Small cells that a validity boundary crosses are not split down to
      // single pixels. Their untraced pixels (traced = 4, pending) take the
      // status of the nearest node as a guess; then, in rounds, every pending
      // pixel that is guessed valid or has a 4-neighbour of another status is
      // traced, until no pending pixel borders a different status. The
      // boundary is then traced on both sides, pixel-exact, and the pending
      // pixels left are invalid for the same reason as all their neighbours.
      auto resolve_boundary = [&](const std::vector<Cell>& cells_in) {
        if (cells_in.empty()) return;
        std::vector<std::vector<std::uint32_t>> per_cell(cells_in.size());
        tbb::parallel_for(std::size_t(0), cells_in.size(), [&](std::size_t ci) {
          const Cell& c = cells_in[ci];
          const Nodes q = nodes_of(c);
          const int xe = c.x1 == box.x1 ? c.x1 : c.x1 - 1, ye = c.y1 == box.y1 ? c.y1 : c.y1 - 1;
          auto nearest = [](const int* at, int n, int v) {
            int best = 0;
            for (int i = 1; i < n; ++i)
              if (std::abs(v - at[i]) < std::abs(v - at[best])) best = i;
            return best;
          };
          for (int y = c.y0; y <= ye; ++y)
            for (int x = c.x0; x <= xe; ++x)
              if (const std::uint32_t p = idx(x, y); !traced[p]) {
                traced[p] = 4;
                map.status[p] = map.status[q.pixel[nearest(q.ay, q.ny, y) * q.nx + nearest(q.ax, q.nx, x)]];
                per_cell[ci].push_back(p);
              }
        });
        std::vector<std::uint32_t> pending;
        for (const auto& v : per_cell) pending.insert(pending.end(), v.begin(), v.end());
        // Validity boundaries are resolved; where two invalid reasons meet
        // (a miss beside a ray that enters but exits elsewhere, say) the
        // pixels keep their nearest node's reason unless exact_reasons: no
        // skin point depends on it.
        auto borders_other = [&](std::uint32_t p) {
          const int x = static_cast<int>(p % W), y = static_cast<int>(p / W);
          const PixelStatus s = map.status[p];
          auto other = [&](std::uint32_t n) {
            return options.exact_reasons ? map.status[n] != s
                                         : (map.status[n] == PixelStatus::valid) != (s == PixelStatus::valid);
          };
          return (x > box.x0 && other(p - 1)) || (x < box.x1 && other(p + 1)) || (y > box.y0 && other(p - W)) ||
                 (y < box.y1 && other(p + W));
        };
        std::vector<char> pick;
        while (!pending.empty()) {
          pick.assign(pending.size(), 0);
          tbb::parallel_for(std::size_t(0), pending.size(), [&](std::size_t i) { pick[i] = borders_other(pending[i]); });
          std::vector<std::uint32_t> round;
          for (std::size_t i = 0; i < pending.size(); ++i)
            if (pick[i]) round.push_back(pending[i]), traced[pending[i]] = 0;
          if (round.empty()) break;
          trace_pixels(round);
          std::erase_if(pending, [&](std::uint32_t p) { return traced[p] == 1; });
        }
        // The pending pixels left inside the valid region: a least-squares
        // quadratic in (x, y) through the exactly traced valid pixels around
        // the cell (its valid nodes, its checks, the valid side of the traced
        // boundary, the neighbours' nodes), used only where it fits every one
        // of them within the tolerance and they lie on one contact component;
        // otherwise those pixels are traced.
        std::vector<std::vector<std::uint32_t>> untrusted(cells_in.size());
        std::vector<double> fit_err(cells_in.size(), 0);
        std::atomic<long long> fitted{0};
        tbb::parallel_for(std::size_t(0), cells_in.size(), [&](std::size_t ci) {
          std::vector<std::uint32_t> todo;
          for (std::uint32_t p : per_cell[ci])
            if (traced[p] == 4 && map.status[p] == PixelStatus::valid) todo.push_back(p);
          if (todo.empty()) return;
          const Cell& c = cells_in[ci];
          constexpr int kMargin = 4;
          const int wx0 = std::max(box.x0, c.x0 - kMargin), wx1 = std::min(box.x1, c.x1 + kMargin);
          const int wy0 = std::max(box.y0, c.y0 - kMargin), wy1 = std::min(box.y1, c.y1 + kMargin);
          std::vector<std::uint32_t> known;
          for (int y = wy0; y <= wy1; ++y)
            for (int x = wx0; x <= wx1; ++x)
              if (const std::uint32_t p = idx(x, y); traced[p] == 1 && map.status[p] == PixelStatus::valid) known.push_back(p);
          bool ok = known.size() >= 12;
          const int comp = ok ? component[map.face[known[0]]] : -1;
          for (std::size_t k = 0; ok && k < known.size(); ++k) ok = component[map.face[known[k]]] == comp;
          constexpr int kCols = 8;  // skin point, incidence, contact, transmittance, chart uv
          using Fit = refraction_detail::QuadraticFit<kCols>;
          auto values = [&](std::uint32_t p) {
            Fit::Row r;
            const Eigen::Vector2d uv = locator ? Eigen::Vector2d(map.chart_uv[p].cast<double>()) : Eigen::Vector2d::Zero();
            r << map.skin_point[p].transpose(), map.incidence_deg[p], map.contact_deg[p], map.transmittance[p], uv.transpose();
            return r;
          };
          Fit fit(0.5 * (c.x0 + c.x1), 0.5 * (c.y0 + c.y1), 1.0 / std::max(1, c.x1 - c.x0));
          if (ok) {
            std::vector<Fit::Row> known_values(known.size());
            for (std::size_t k = 0; k < known.size(); ++k) {
              known_values[k] = values(known[k]);
              fit.add(static_cast<int>(known[k] % W), static_cast<int>(known[k] / W), known_values[k]);
            }
            ok = fit.solve();
            double err = 0;
            for (std::size_t k = 0; ok && k < known.size(); ++k) {
              const std::uint32_t p = known[k];
              const Fit::Row r = fit.at(static_cast<int>(p % W), static_cast<int>(p / W)) - known_values[k];
              err = std::max({err, r.head<3>().norm(), r.tail<2>().norm()});
            }
            ok = ok && std::isfinite(err) && err <= tol_mm;
            fit_err[ci] = ok ? err : 0;
          }
          if (!ok) {
            untrusted[ci] = std::move(todo);
            return;
          }
          long long n = 0;
          for (std::uint32_t p : todo) {
            const int x = static_cast<int>(p % W), y = static_cast<int>(p / W);
            const Fit::Row v = fit.at(x, y);
            Interp r;
            if (locator) {
              const Vec2 uv(v[6], v[7]);
              const auto hit = locator->locate(uv);
              if (!hit) {
                untrusted[ci].push_back(p);
                continue;
              }
              r = Interp{hit->point, hit->face, hit->bary, uv};
            } else {
              // On the face of the nearest traced valid pixel: the 5x5
              // neighbourhood first, else any known pixel.
              std::uint32_t near = known[0];
              int best = std::numeric_limits<int>::max();
              for (int dy = -2; dy <= 2; ++dy)
                for (int dx = -2; dx <= 2; ++dx) {
                  const int xx = x + dx, yy = y + dy;
                  if (xx < box.x0 || xx > box.x1 || yy < box.y0 || yy > box.y1) continue;
                  const std::uint32_t k = idx(xx, yy);
                  if (traced[k] == 1 && map.status[k] == PixelStatus::valid && dx * dx + dy * dy < best)
                    best = dx * dx + dy * dy, near = k;
                }
              if (best == std::numeric_limits<int>::max())
                for (std::uint32_t k : known) {
                  const int dx = static_cast<int>(k % W) - x, dy = static_cast<int>(k / W) - y;
                  if (dx * dx + dy * dy < best) best = dx * dx + dy * dy, near = k;
                }
              r.point = v.head<3>().transpose();
              r.face = map.face[near];
              r.uv = Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
              r.bary = plane_bary(mesh, r.face, r.point);
            }
            map.status[p] = PixelStatus::valid;
            map.skin_point[p] = r.point;
            map.face[p] = r.face;
            map.bary[p] = Eigen::Vector2f(static_cast<float>(r.bary[1]), static_cast<float>(r.bary[2]));
            map.chart_uv[p] = r.uv.cast<float>();
            map.incidence_deg[p] = static_cast<float>(v[3]);
            map.contact_deg[p] = static_cast<float>(v[4]);
            map.transmittance[p] = std::clamp(static_cast<float>(v[5]), 0.0f, 1.0f);
            traced[p] = 2;
            ++n;
          }
          fitted += n;
        });
        st.interpolated += fitted;
        for (double e : fit_err) worst = std::max(worst, e);
        std::vector<std::uint32_t> rest;
        for (auto& v : untrusted)
          for (std::uint32_t p : v) rest.push_back(p), traced[p] = 0;
        trace_pixels(rest);
        std::erase_if(pending, [&](std::uint32_t p) { return traced[p] != 4; });
        tbb::parallel_for(std::size_t(0), pending.size(), [&](std::size_t i) {
          const std::uint32_t p = pending[i];
          const PixelStatus s = map.status[p];
          reset(map, p);
          map.status[p] = s;
          traced[p] = 2;
        });
      };
      // Two check pixels, at a quarter and three quarters of the cell's diagonal.
      auto check_xy = [](const Cell& c, int k) {
        const int dx = (c.x1 - c.x0) / 4, dy = (c.y1 - c.y0) / 4;
        return k == 0 ? std::pair{c.x0 + dx, c.y0 + dy} : std::pair{c.x1 - dx, c.y1 - dy};
      };
      std::vector<Cell> boundary;
      bool first_level = true;
      while (!cells.empty()) {
        // A split cell's children have the parent's nodes as corners: a child
        // whose corners differ (status or contact component) is crossed by a
        // boundary whatever its checks say, so they are not traced.
        auto corners_differ = [&](const Cell& c) {
          const std::uint32_t k[4] = {idx(c.x0, c.y0), idx(c.x1, c.y0), idx(c.x0, c.y1), idx(c.x1, c.y1)};
          const PixelStatus s0 = map.status[k[0]];
          for (std::uint32_t p : k) {
            if (map.status[p] != s0) return true;
            if (s0 == PixelStatus::valid && component[map.face[p]] != component[map.face[k[0]]]) return true;
          }
          return false;
        };
        std::vector<std::uint32_t> batch;
        for (const Cell& c : cells) {
          const Nodes q = nodes_of(c);
          batch.insert(batch.end(), q.pixel, q.pixel + q.n);
          if (!done(c) && (first_level || !corners_differ(c)))
            for (int k = 0; k < 2; ++k) batch.push_back(idx(check_xy(c, k).first, check_xy(c, k).second));
        }
        first_level = false;
        trace_pixels(batch);
        // Decide every cell (in parallel), then fill the accepted ones. A pixel
        // belongs to the cell with x0 <= x < x1 and y0 <= y < y1 (or on the
        // box's last column/row), so parallel fills never touch the same pixel.
        // 0 done, 1 accept valid, 2 accept invalid, 3 split, 4 to the boundary resolver
        std::vector<char> decision(cells.size(), 0);
        std::vector<double> cell_err(cells.size(), 0);
        tbb::parallel_for(std::size_t(0), cells.size(), [&](std::size_t ci) {
          const Cell& c = cells[ci];
          if (done(c)) return;
          const Nodes q = nodes_of(c);
          const std::uint32_t checks[2] = {idx(check_xy(c, 0).first, check_xy(c, 0).second),
                                           idx(check_xy(c, 1).first, check_xy(c, 1).second)};
          const PixelStatus first = map.status[q.pixel[0]];
          bool all_valid = true, same_invalid = true;
          for (int k = 0; k < q.n; ++k) {
            const PixelStatus st_k = map.status[q.pixel[k]];
            all_valid &= st_k == PixelStatus::valid;
            same_invalid &= st_k != PixelStatus::valid && st_k == first;
          }
          if (all_valid) {
            const int comp = component[map.face[q.pixel[0]]];
            for (int k = 0; k < q.n; ++k) all_valid &= component[map.face[q.pixel[k]]] == comp;
          }
          decision[ci] = 3;
          if (all_valid && map.status[checks[0]] == PixelStatus::valid && map.status[checks[1]] == PixelStatus::valid) {
            double err = 0;
            for (int k = 0; k < 2; ++k) {
              const auto [cx, cy] = check_xy(c, k);
              const auto guess = interpolate(q, weights(q, cx, cy));
              err = std::max(err, guess ? (guess->point - map.skin_point[checks[k]]).norm() : 1e300);
            }
            if (err < 1e300 && (!adaptive || err <= tol_mm)) decision[ci] = 1, cell_err[ci] = err;
          } else if (same_invalid && map.status[checks[0]] == first && map.status[checks[1]] == first) {
            decision[ci] = 2;  // uniformly invalid for the same reason
          } else if (c.x1 - c.x0 <= kResolveCell && c.y1 - c.y0 <= kResolveCell) {
            decision[ci] = 4;  // a small cell that a validity boundary crosses
          }
        });
        std::vector<Cell> next;
        for (std::size_t ci = 0; ci < cells.size(); ++ci) {
          const Cell& c = cells[ci];
          if (decision[ci] == 1) worst = std::max(worst, cell_err[ci]);
          if (decision[ci] == 4) boundary.push_back(c);
          if (decision[ci] != 3) continue;
          const int xm = (c.x0 + c.x1) / 2, ym = (c.y0 + c.y1) / 2;
          const bool sx = c.x1 - c.x0 > 1, sy = c.y1 - c.y0 > 1;
          if (sx && sy) next.insert(next.end(), {{c.x0, c.y0, xm, ym}, {xm, c.y0, c.x1, ym}, {c.x0, ym, xm, c.y1}, {xm, ym, c.x1, c.y1}});
          else if (sx) next.insert(next.end(), {{c.x0, c.y0, xm, c.y1}, {xm, c.y0, c.x1, c.y1}});
          else next.insert(next.end(), {{c.x0, c.y0, c.x1, ym}, {c.x0, ym, c.x1, c.y1}});
        }
        // Fill the accepted cells: row by row across cells (without a chart),
        // or cell by cell through the chart's point location.
        std::atomic<long long> filled{0};
        std::vector<std::size_t> accepted;
        for (std::size_t ci = 0; ci < cells.size(); ++ci)
          if (decision[ci] == 1 || decision[ci] == 2) accepted.push_back(ci);
        if (locator) {
          tbb::parallel_for(std::size_t(0), accepted.size(), [&](std::size_t k) {
            const Cell& c = cells[accepted[k]];
            const int xe = c.x1 == box.x1 ? c.x1 : c.x1 - 1, ye = c.y1 == box.y1 ? c.y1 : c.y1 - 1;
            if (decision[accepted[k]] == 1) {
              filled += fill_located(c, nodes_of(c), xe, ye);
            } else {
              const PixelStatus why = map.status[nodes_of(c).pixel[0]];
              for (int y = c.y0; y <= ye; ++y) fill_invalid_row(c.x0, xe, y, why);
            }
          });
        } else if (!accepted.empty()) {
          std::sort(accepted.begin(), accepted.end(), [&](std::size_t a, std::size_t b) {
            return std::pair(cells[a].y0, cells[a].x0) < std::pair(cells[b].y0, cells[b].x0);
          });
          std::vector<DirectFill> prepared(accepted.size());
          tbb::parallel_for(std::size_t(0), accepted.size(), [&](std::size_t k) {
            if (decision[accepted[k]] == 1) prepare_direct(cells[accepted[k]], prepared[k]);
          });
          // Bands: runs of accepted cells with the same first row; one task per row of a band.
          struct RowTask {
            std::size_t begin, end;
            int y;
          };
          std::vector<RowTask> tasks;
          for (std::size_t k = 0; k < accepted.size();) {
            std::size_t e = k;
            int last = cells[accepted[k]].y0;
            while (e < accepted.size() && cells[accepted[e]].y0 == cells[accepted[k]].y0) {
              const Cell& c = cells[accepted[e]];
              last = std::max(last, c.y1 == box.y1 ? c.y1 : c.y1 - 1);
              ++e;
            }
            for (int y = cells[accepted[k]].y0; y <= last; ++y) tasks.push_back({k, e, y});
            k = e;
          }
          tbb::parallel_for(std::size_t(0), tasks.size(), [&](std::size_t t) {
            long long n = 0;
            const RowTask& task = tasks[t];
            for (std::size_t k = task.begin; k < task.end; ++k) {
              const Cell& c = cells[accepted[k]];
              const int xe = c.x1 == box.x1 ? c.x1 : c.x1 - 1, ye = c.y1 == box.y1 ? c.y1 : c.y1 - 1;
              if (task.y > ye) continue;
              if (decision[accepted[k]] == 1) n += fill_direct_row(prepared[k], task.y);
              else fill_invalid_row(c.x0, xe, task.y, map.status[nodes_of(c).pixel[0]]);
            }
            filled += n;
          });
        }
        st.interpolated += filled;
        for (std::size_t ci = 0; locator && ci < cells.size(); ++ci) {
          if (decision[ci] != 1) continue;
          const Cell& c = cells[ci];
          for (int y = c.y0; y <= c.y1; ++y)
            for (int x = c.x0; x <= c.x1; ++x)
              if (traced[idx(x, y)] == 3) traced[idx(x, y)] = 0, retrace.push_back(idx(x, y));
        }
        trace_pixels(retrace);
        retrace.clear();
        cells = std::move(next);
      }
      resolve_boundary(boundary);
      st.max_error_um = worst * 1e3;
    }
  }
  st.trace_ms = ms_since(t0) - st.unproject_ms;

  {
    using Counts = std::array<long long, kPixelStatusCount>;
    const Counts counts = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, N, 1 << 16), Counts{},
        [&](const tbb::blocked_range<std::size_t>& r, Counts c) {
          for (std::size_t i = r.begin(); i < r.end(); ++i) ++c[static_cast<int>(map.status[i])];
          return c;
        },
        [](Counts a, const Counts& b) {
          for (int k = 0; k < kPixelStatusCount; ++k) a[k] += b[k];
          return a;
        });
    for (int k = 0; k < kPixelStatusCount; ++k) st.by_status[k] = counts[k];
  }
  st.coverage = static_cast<double>(st.by_status[0]) / static_cast<double>(std::max<long long>(1, st.pixels));
  st.total_ms = ms_since(t_start);
  return map;
}

void write_skin_points_npy(const RefractionMap& map, const std::filesystem::path& path) {
  npy::write_float32(path, {static_cast<std::size_t>(map.height), static_cast<std::size_t>(map.width), 3},
                     [&](std::size_t y, float* out) {
                       for (int x = 0; x < map.width; ++x)
                         for (int k = 0; k < 3; ++k)
                           out[3 * x + k] = static_cast<float>(map.skin_point[map.index(x, static_cast<int>(y))][k]);
                     });
}

}  // namespace clearfit
