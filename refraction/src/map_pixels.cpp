// Stage 3 of the refraction map: samples and resets into the map's per-pixel
// arrays, and the statistics counted from them.
#include "map_stages.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>

namespace clearfit::refraction_detail {

void allocate(RefractionMap& map, int width, int height) {
  const std::size_t n = static_cast<std::size_t>(width) * height;
  map.width = width;
  map.height = height;
  map.status.resize(n);
  map.skin_point.resize(n);
  map.face.resize(n);
  map.bary.resize(n);
  map.chart_uv.resize(n);
  map.incidence_deg.resize(n);
  map.contact_deg.resize(n);
  map.transmittance.resize(n);
}

void reset_span(RefractionMap& map, std::size_t p, std::size_t n, PixelStatus why) {
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

void store(RefractionMap& map, const TraceScene& scene, std::size_t p, const SkinSample& s) {
  map.status[p] = s.status;
  map.incidence_deg[p] = static_cast<float>(s.incidence_deg);
  if (s.status != PixelStatus::valid) {  // every other field as reset_span leaves it
    constexpr double dnan = std::numeric_limits<double>::quiet_NaN();
    map.skin_point[p] = Vec3(dnan, dnan, dnan);
    map.face[p] = -1;
    map.bary[p] = map.chart_uv[p] = Eigen::Vector2f(fnan, fnan);
    map.contact_deg[p] = map.transmittance[p] = fnan;
    return;
  }
  map.skin_point[p] = s.skin_point;
  map.face[p] = s.face;
  map.bary[p] = Eigen::Vector2f(static_cast<float>(s.bary[1]), static_cast<float>(s.bary[2]));
  map.contact_deg[p] = static_cast<float>(s.contact_deg);
  map.transmittance[p] = static_cast<float>(s.transmittance);
  map.chart_uv[p] = Eigen::Vector2f(fnan, fnan);
  if (scene.chart && !scene.chart->uv.empty()) {
    const auto& f = scene.mesh->faces[s.face];
    const Vec2 uv = s.bary[0] * scene.chart->uv[f[0]] + s.bary[1] * scene.chart->uv[f[1]] + s.bary[2] * scene.chart->uv[f[2]];
    map.chart_uv[p] = uv.cast<float>();
  }
}

std::array<double, 3> plane_bary(const Mesh& mesh, int face, const Vec3& point) {
  const Vec3 a = mesh.corner(face, 0), e1 = mesh.corner(face, 1) - a, e2 = mesh.corner(face, 2) - a;
  const Vec3 d = point - a;
  const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), det = d11 * d22 - d12 * d12;
  const double b1 = det > 0 ? (d22 * d.dot(e1) - d12 * d.dot(e2)) / det : 0;
  const double b2 = det > 0 ? (d11 * d.dot(e2) - d12 * d.dot(e1)) / det : 0;
  return {1 - b1 - b2, b1, b2};
}

void count_statuses(RefractionMap& map) {
  using Counts = std::array<long long, kPixelStatusCount>;
  const Counts counts = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, map.status.size(), 1 << 16), Counts{},
      [&](const tbb::blocked_range<std::size_t>& r, Counts c) {
        for (std::size_t i = r.begin(); i < r.end(); ++i) ++c[static_cast<int>(map.status[i])];
        return c;
      },
      [](Counts a, const Counts& b) {
        for (int k = 0; k < kPixelStatusCount; ++k) a[k] += b[k];
        return a;
      });
  MapStats& st = map.stats;
  for (int k = 0; k < kPixelStatusCount; ++k) st.by_status[k] = counts[k];
  st.coverage = static_cast<double>(st.by_status[0]) / static_cast<double>(std::max<long long>(1, st.pixels));
}

}  // namespace clearfit::refraction_detail
