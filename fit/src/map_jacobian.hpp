#pragma once
// How the inverse map stretches the chart into the image, shared by the signal's σ (blanching.cpp:
// texels per camera pixel) and the intrinsics' and curvature's terms (assessment_stages.cpp). Private to fit.
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <optional>

namespace clearfit {

/// The camera pixel of texel (i, j); NaN where the texel has none.
inline Vec2 texel_pixel(const InverseMap& inv, int i, int j) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  const auto k = inv.index(i, j);
  return inv.valid[k] ? Vec2(inv.map_x[k], inv.map_y[k]) : Vec2(nan, nan);
}

/// ∂pixel/∂uv (px per mm) at texel (i, j) of the inverse map, by central differences (one-sided at its
/// edges); nullopt where the texel has no pixel or the Jacobian is singular.
inline std::optional<Eigen::Matrix2d> pixel_jacobian(const InverseMap& inv, int i, int j) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  auto derivative = [&](int di, int dj) {  // ∂pixel per mm along (di, dj)
    const bool ahead = i + di < inv.width && j + dj < inv.height, behind = i - di >= 0 && j - dj >= 0;
    const Vec2 a = ahead ? texel_pixel(inv, i + di, j + dj) : Vec2(nan, nan);
    const Vec2 b = behind ? texel_pixel(inv, i - di, j - dj) : Vec2(nan, nan), c = texel_pixel(inv, i, j);
    if (a.allFinite() && b.allFinite()) return Vec2((a - b) / (2 * inv.texel_mm));
    if (a.allFinite()) return Vec2((a - c) / inv.texel_mm);
    if (b.allFinite()) return Vec2((c - b) / inv.texel_mm);
    return Vec2(nan, nan);
  };
  if (!texel_pixel(inv, i, j).allFinite()) return std::nullopt;
  Eigen::Matrix2d J;
  J.col(0) = derivative(1, 0), J.col(1) = derivative(0, 1);
  if (!J.allFinite() || std::abs(J.determinant()) < 1e-12) return std::nullopt;
  return J;
}

}  // namespace clearfit
