// Skin that slides and bulges between the phases (see SkinMotion in simulate.hpp).
#include <clearfit/fit/simulate.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace clearfit::sim {

void SkinMotion::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) {
      std::ostringstream s;
      s << "skin_motion." << field << " = " << v << ": " << rule;
      throw std::invalid_argument(s.str());
    }
  };
  check(slide_mm.allFinite() && slide_mm.norm() <= 5, "slide_mm", slide_mm.norm(), "must be at most 5 mm long");
  check(std::isfinite(bulge_mm) && std::abs(bulge_mm) <= 2, "bulge_mm", bulge_mm, "must be in [-2, 2] mm");
  check(std::isfinite(bulge_width_mm) && bulge_width_mm >= 0.1 && bulge_width_mm <= 20, "bulge_width_mm", bulge_width_mm,
        "must be in [0.1, 20] mm");
}

Vec2 SkinDisplacement::at(const Vec2& uv) const {
  const ChartGrid& g = dx_mm.grid;
  if (g.size() == 0) return Vec2::Zero();
  // Clamped into the grid: beyond it the edge's displacement holds.
  const Vec2 lo = g.uv_origin, hi = g.uv(g.width - 1, g.height - 1);
  const Vec2 c = uv.cwiseMax(lo).cwiseMin(hi);
  const float x = dx_mm.sample(c), y = dy_mm.sample(c);
  return {std::isfinite(x) ? x : 0.0, std::isfinite(y) ? y : 0.0};
}

SkinDisplacement skin_displacement(const SkinMotion& m, const ChartField& pressure) {
  m.validate();
  const ChartGrid& g = pressure.grid;
  SkinDisplacement d;
  d.dx_mm = d.dy_mm = {g, std::vector<float>(g.size(), 0.f)};
  if (g.size() == 0) return d;
  cv::Mat p(g.height, g.width, CV_32F);
  for (std::size_t k = 0; k < g.size(); ++k) p.at<float>(static_cast<int>(k)) = std::isfinite(pressure.value[k]) ? pressure.value[k] : 0.f;
  const double s = m.bulge_width_mm / g.texel_mm;
  cv::GaussianBlur(p, p, cv::Size(), s, s, cv::BORDER_CONSTANT);
  cv::Mat gx, gy;  // per mm: central differences (Sobel's 3x3 scaled by 1/8 and the texel)
  cv::Sobel(p, gx, CV_32F, 1, 0, 3, 1.0 / (8 * g.texel_mm));
  cv::Sobel(p, gy, CV_32F, 0, 1, 3, 1.0 / (8 * g.texel_mm));
  double peak = 0;
  for (std::size_t k = 0; k < g.size(); ++k)
    peak = std::max(peak, std::hypot(double(gx.at<float>(static_cast<int>(k))), double(gy.at<float>(static_cast<int>(k)))));
  const double scale = peak > 0 ? m.bulge_mm / peak : 0.0;
  for (std::size_t k = 0; k < g.size(); ++k) {
    const int i = static_cast<int>(k);
    d.dx_mm.value[k] = static_cast<float>(m.slide_mm.x() - scale * gx.at<float>(i));
    d.dy_mm.value[k] = static_cast<float>(m.slide_mm.y() - scale * gy.at<float>(i));
  }
  return d;
}

void write_displacement_npy(const SkinDisplacement& d, const std::filesystem::path& path) {
  const ChartGrid& g = d.dx_mm.grid;
  std::vector<float> uv(2 * g.size());
  for (std::size_t k = 0; k < g.size(); ++k) uv[2 * k] = d.dx_mm.value[k], uv[2 * k + 1] = d.dy_mm.value[k];
  write_npy_float32(path, {static_cast<std::size_t>(g.height), static_cast<std::size_t>(g.width), 2}, uv.data());
}

}  // namespace clearfit::sim
