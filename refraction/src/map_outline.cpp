// Stage 5 of the refraction map: the seen fraction of the pixels on the outline of the seen region.
#include "map_stages.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace clearfit {

namespace refraction_detail {
namespace {

/// seen_outline among the pixels of `box` widened by one pixel (no pixel
/// beyond it can be seen or border a seen one), its rows in parallel.
std::vector<std::uint32_t> outline_pixels(const RefractionMap& map, const PixelBox& box) {
  if (box.empty()) return {};
  auto seen = [&](int x, int y) { return map.status[map.index(x, y)] == PixelStatus::valid; };
  const int x0 = std::max(0, box.x0 - 1), x1 = std::min(map.width - 1, box.x1 + 1);
  const int y0 = std::max(0, box.y0 - 1), y1 = std::min(map.height - 1, box.y1 + 1);
  std::vector<std::vector<std::uint32_t>> rows(static_cast<std::size_t>(y1 - y0 + 1));
  tbb::parallel_for(y0, y1 + 1, [&](int y) {
    for (int x = x0; x <= x1; ++x) {
      const bool s = seen(x, y);
      bool mixed = false;
      for (int dy = -1; dy <= 1 && !mixed; ++dy)
        for (int dx = -1; dx <= 1 && !mixed; ++dx) {
          const int xx = x + dx, yy = y + dy;
          mixed = xx >= 0 && yy >= 0 && xx < map.width && yy < map.height && seen(xx, yy) != s;
        }
      if (mixed) rows[y - y0].push_back(static_cast<std::uint32_t>(map.index(x, y)));
    }
  });
  std::vector<std::uint32_t> out;
  for (const auto& row : rows) out.insert(out.end(), row.begin(), row.end());
  return out;
}

}  // namespace

void measure_seen_fraction(const MapRun& run) {
  RefractionMap& map = run.map;
  map.seen_fraction.resize(map.status.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, map.status.size(), 1 << 16), [&](const auto& r) {
    for (std::size_t k = r.begin(); k < r.end(); ++k) map.seen_fraction[k] = map.status[k] == PixelStatus::valid ? 1.f : 0.f;
  });
  const std::vector<std::uint32_t> outline = outline_pixels(map, run.box);
  constexpr std::size_t kPerPixel = kSeenSub * kSeenSub;
  constexpr std::size_t kBatch = 256;  // outline pixels per task
  tbb::parallel_for(std::size_t{0}, (outline.size() + kBatch - 1) / kBatch, [&](std::size_t b) {
    const std::size_t p0 = b * kBatch, p1 = std::min(outline.size(), p0 + kBatch);
    std::vector<Vec2> points;
    points.reserve((p1 - p0) * kPerPixel);
    for (std::size_t i = p0; i < p1; ++i) {
      const auto square = seen_sample_points(static_cast<int>(outline[i] % map.width), static_cast<int>(outline[i] / map.width));
      points.insert(points.end(), square.begin(), square.end());
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

}  // namespace refraction_detail

std::vector<std::uint32_t> seen_outline(const RefractionMap& map) {
  return refraction_detail::outline_pixels(map, {0, 0, map.width - 1, map.height - 1});
}

std::array<Vec2, kSeenSub * kSeenSub> seen_sample_points(int x, int y) {
  std::array<Vec2, kSeenSub * kSeenSub> points;
  for (int v = 0; v < kSeenSub; ++v)
    for (int u = 0; u < kSeenSub; ++u)
      points[v * kSeenSub + u] = Vec2(x + (u + 0.5) / kSeenSub - 0.5, y + (v + 0.5) / kSeenSub - 0.5);
  return points;
}

}  // namespace clearfit
