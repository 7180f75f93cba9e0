// Stage 5 of the refraction map: the seen fraction of the pixels on the outline of the seen region.
#include "map_stages.hpp"

#include <tbb/parallel_for.h>

namespace clearfit::refraction_detail {

namespace {

constexpr int kSub = 4;  // rays per side of a pixel's square

/// The pixels whose 8 neighbours (inside the image) do not all share their seen-or-not.
std::vector<std::uint32_t> outline_pixels(const RefractionMap& map) {
  std::vector<std::uint32_t> out;
  auto seen = [&](int x, int y) { return map.status[map.index(x, y)] == PixelStatus::valid; };
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const bool s = seen(x, y);
      bool mixed = false;
      for (int dy = -1; dy <= 1 && !mixed; ++dy)
        for (int dx = -1; dx <= 1 && !mixed; ++dx) {
          const int xx = x + dx, yy = y + dy;
          mixed = xx >= 0 && yy >= 0 && xx < map.width && yy < map.height && seen(xx, yy) != s;
        }
      if (mixed) out.push_back(static_cast<std::uint32_t>(map.index(x, y)));
    }
  return out;
}

}  // namespace

void measure_seen_fraction(const MapRun& run) {
  RefractionMap& map = run.map;
  map.seen_fraction.resize(map.status.size());
  for (std::size_t k = 0; k < map.status.size(); ++k) map.seen_fraction[k] = map.status[k] == PixelStatus::valid ? 1.f : 0.f;
  const std::vector<std::uint32_t> outline = outline_pixels(map);
  constexpr std::size_t kPerPixel = kSub * kSub;
  constexpr std::size_t kBatch = 256;  // outline pixels per task
  tbb::parallel_for(std::size_t{0}, (outline.size() + kBatch - 1) / kBatch, [&](std::size_t b) {
    const std::size_t p0 = b * kBatch, p1 = std::min(outline.size(), p0 + kBatch);
    std::vector<Vec2> points;
    points.reserve((p1 - p0) * kPerPixel);
    for (std::size_t i = p0; i < p1; ++i) {
      const int x = static_cast<int>(outline[i] % map.width), y = static_cast<int>(outline[i] / map.width);
      for (int v = 0; v < kSub; ++v)
        for (int u = 0; u < kSub; ++u) points.emplace_back(x + (u + 0.5) / kSub - 0.5, y + (v + 0.5) / kSub - 0.5);
    }
    std::vector<Vec3> dirs(points.size());
    run.rays.unproject(points, dirs);
    std::vector<Ray> first(points.size());
    for (std::size_t j = 0; j < points.size(); ++j) {
      first[j].origin = run.part_from_cam.translation;
      first[j].direction = dirs[j].allFinite() ? Vec3(run.part_from_cam.rotation * dirs[j]) : Vec3::Zero();
    }
    std::vector<SkinSample> out(points.size());
    for (std::size_t j = 0; j < points.size(); j += kBatch)
      run.tracer.trace_chunk(std::span(first).subspan(j, std::min(kBatch, points.size() - j)),
                             std::span(out).subspan(j, std::min(kBatch, points.size() - j)));
    for (std::size_t i = p0; i < p1; ++i) {
      int seen = 0;
      for (std::size_t j = 0; j < kPerPixel; ++j) seen += out[(i - p0) * kPerPixel + j].status == PixelStatus::valid;
      map.seen_fraction[outline[i]] = static_cast<float>(seen) / kPerPixel;
    }
  });
}

}  // namespace clearfit::refraction_detail
