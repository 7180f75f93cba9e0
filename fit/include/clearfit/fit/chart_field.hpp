#pragma once
// Scalar fields on the contact chart's texel grid (the grid of the inverse
// refraction map): blanching signal, pressure, ground truth. Texel (i, j) has
// its centre at chart uv = uv_origin + texel_mm * (i, j), row-major at
// j * width + i, as in InverseMap.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <cstddef>
#include <vector>

namespace clearfit {

struct ChartGrid {
  int width = 0, height = 0;    ///< texels
  double texel_mm = 0;          ///< texel edge, mm
  Vec2 uv_origin = Vec2::Zero();  ///< chart uv (mm) of the centre of texel (0, 0)
  std::size_t size() const { return static_cast<std::size_t>(width) * height; }
  std::size_t index(int i, int j) const { return static_cast<std::size_t>(j) * width + i; }
  Vec2 uv(int i, int j) const { return uv_origin + texel_mm * Vec2(i, j); }
  /// Texel grid covering [uv_min, uv_max] with texel centres on multiples of texel_mm.
  static ChartGrid covering(const Vec2& uv_min, const Vec2& uv_max, double texel_mm);
};

struct ChartField {
  ChartGrid grid;
  std::vector<float> value;  ///< grid.size() values; NaN where undefined
  /// Bilinear interpolation at chart uv (mm) over the defined texels (weights
  /// renormalised over the defined ones among the four); NaN when none of the
  /// four is defined or uv is more than half a texel outside the grid.
  float sample(const Vec2& uv) const;
  /// The value of the defined texel nearest to uv within `reach_texels` texels (NaN if none).
  float nearest_defined(const Vec2& uv, double reach_texels) const;
};

/// How far from a vertex sample_at_vertices looks for a defined texel when
/// none of the four around it is defined (a vertex on the chart's boundary).
inline constexpr double kVertexReachTexels = 1.5;

/// The field at every mesh vertex that has a chart coordinate: the bilinear
/// sample, else the nearest defined texel within kVertexReachTexels (NaN elsewhere).
std::vector<float> sample_at_vertices(const ChartField& field, const Chart& chart);

}  // namespace clearfit
