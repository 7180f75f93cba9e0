// Stage 1 of the refraction map: pixel -> ray (cached per camera) and the
// part's pixel bound.
#include "map_stages.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <map>

namespace clearfit::refraction_detail {

void CameraRays::ensure(std::span<const std::uint32_t> pixels) {
  std::lock_guard lock(mutex_);
  std::vector<std::uint32_t> missing;
  for (std::uint32_t p : pixels)
    if (!known_[p]) missing.push_back(p);
  fill(missing);
}

void CameraRays::ensure(int x0, int y0, int x1, int y1) {
  std::lock_guard lock(mutex_);
  std::vector<std::uint32_t> missing;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      if (const auto p = static_cast<std::uint32_t>(y * camera_.width + x); !known_[p]) missing.push_back(p);
  fill(missing);
}

void CameraRays::fill(const std::vector<std::uint32_t>& missing) {
  if (missing.empty()) return;
  std::vector<Vec2> q(missing.size());
  for (std::size_t i = 0; i < missing.size(); ++i) q[i] = Vec2(missing[i] % camera_.width, missing[i] / camera_.width);
  std::vector<Vec3> r(missing.size());
  unprojector_.unproject(q, r);
  for (std::size_t i = 0; i < missing.size(); ++i) {
    rays_[missing[i]] = r[i].allFinite() ? Vec3(r[i].normalized()) : Vec3::Zero();
    known_[missing[i]] = 1;
  }
}

std::shared_ptr<CameraRays> camera_rays(const CameraModel& camera) {
  static std::mutex mutex;
  static std::map<std::uint64_t, std::shared_ptr<CameraRays>> cache;
  std::lock_guard lock(mutex);
  const std::uint64_t key = camera.intrinsics_hash();
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  if (cache.size() >= 4) cache.clear();
  return cache.emplace(key, std::make_shared<CameraRays>(camera)).first->second;
}

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

}  // namespace clearfit::refraction_detail
