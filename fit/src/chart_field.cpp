#include <algorithm>
#include <clearfit/fit/chart_field.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace clearfit {

ChartGrid ChartGrid::covering(const Vec2& uv_min, const Vec2& uv_max, double texel_mm) {
  if (!(texel_mm > 0) || !std::isfinite(texel_mm))
    throw std::invalid_argument("ChartGrid::covering: texel_mm must be positive and finite");
  if (!uv_min.allFinite() || !uv_max.allFinite() || (uv_max.array() < uv_min.array()).any())
    throw std::invalid_argument("ChartGrid::covering: bounds must be finite with uv_min <= uv_max");
  ChartGrid g;
  g.texel_mm = texel_mm;
  const Vec2 first = (uv_min / texel_mm).array().floor() * texel_mm;
  const Vec2 last = (uv_max / texel_mm).array().ceil() * texel_mm;
  g.uv_origin = first;
  g.width = static_cast<int>(std::lround((last.x() - first.x()) / texel_mm)) + 1;
  g.height = static_cast<int>(std::lround((last.y() - first.y()) / texel_mm)) + 1;
  return g;
}

float ChartField::sample(const Vec2& uv) const {
  constexpr float nan = std::numeric_limits<float>::quiet_NaN();
  if (grid.width <= 0 || grid.height <= 0 || !uv.allFinite()) return nan;
  const double fx = (uv.x() - grid.uv_origin.x()) / grid.texel_mm;
  const double fy = (uv.y() - grid.uv_origin.y()) / grid.texel_mm;
  if (fx < -0.5 || fy < -0.5 || fx > grid.width - 0.5 || fy > grid.height - 0.5) return nan;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const double tx = fx - x0, ty = fy - y0;
  double sum = 0, weight = 0;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = x0 + dx, y = y0 + dy;
      if (x < 0 || y < 0 || x >= grid.width || y >= grid.height) continue;
      const float v = value[grid.index(x, y)];
      if (!std::isfinite(v)) continue;
      const double w = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty);
      sum += w * v;
      weight += w;
    }
  return weight > 1e-12 ? static_cast<float>(sum / weight) : nan;
}

float ChartField::nearest_defined(const Vec2& uv, double reach_texels) const {
  float best = std::numeric_limits<float>::quiet_NaN();
  if (grid.width <= 0 || grid.height <= 0 || !uv.allFinite()) return best;
  const double fx = (uv.x() - grid.uv_origin.x()) / grid.texel_mm, fy = (uv.y() - grid.uv_origin.y()) / grid.texel_mm;
  double best_d2 = reach_texels * reach_texels;
  const int x0 = std::max(0, static_cast<int>(std::floor(fx - reach_texels)));
  const int x1 = std::min(grid.width - 1, static_cast<int>(std::ceil(fx + reach_texels)));
  const int y0 = std::max(0, static_cast<int>(std::floor(fy - reach_texels)));
  const int y1 = std::min(grid.height - 1, static_cast<int>(std::ceil(fy + reach_texels)));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const float v = value[grid.index(x, y)];
      const double d2 = (x - fx) * (x - fx) + (y - fy) * (y - fy);
      if (std::isfinite(v) && d2 <= best_d2) best_d2 = d2, best = v;
    }
  return best;
}

std::vector<float> sample_at_vertices(const ChartField& field, const Chart& chart) {
  std::vector<float> out(chart.uv.size(), std::numeric_limits<float>::quiet_NaN());
  for (std::size_t v = 0; v < chart.uv.size(); ++v)
    if (chart.uv[v].allFinite()) {
      out[v] = field.sample(chart.uv[v]);
      // On the chart's boundary the texel centres around a vertex may all lie just outside the
      // charted (or seen) surface: take the nearest defined texel close by.
      if (!std::isfinite(out[v])) out[v] = field.nearest_defined(chart.uv[v], kVertexReachTexels);
    }
  return out;
}

}  // namespace clearfit
