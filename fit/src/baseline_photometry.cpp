#include "baseline_photometry.hpp"
#include "masked_smoothing.hpp"

#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace clearfit {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// Bilinear value of a map's per-pixel array at (x, y); NaN outside the image.
float bilinear(const RefractionMap& m, const PixelArray<float>& a, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.width || y0 + 1 >= m.height) return kNaN;
  const float u = static_cast<float>(x - x0), v = static_cast<float>(y - y0);
  const std::size_t k = m.index(x0, y0);
  return (1 - v) * ((1 - u) * a[k] + u * a[k + 1]) + v * ((1 - u) * a[k + m.width] + u * a[k + m.width + 1]);
}

/// Per roi pixel: where the baseline sees the same skin (camera pixel), whether it does, and the
/// transmittance ratio T_worn(p) / T_base(p_b) there.
struct SourcePixels {
  cv::Mat x, y;        ///< CV_32F camera pixel of the same chart point in the baseline (else the pixel itself)
  cv::Mat comparable;  ///< CV_8U 255 where found
  cv::Mat t_ratio;     ///< CV_32F (1 where not comparable)
};

/// The pixels that see the skin and whose 3 × 3 neighbours all do: a pixel at the skin's edge in the
/// image averages skin and what lies beyond it, differently in each phase.
cv::Mat interior_pixels(const RefractionMap& m) {
  cv::Mat valid(m.height, m.width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      if (m.status[m.index(x, y)] == PixelStatus::valid) valid.at<std::uint8_t>(y, x) = 255;
  cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  return valid;
}

SourcePixels source_pixels(const cv::Rect& roi, const RefractionMap& worn, const RefractionMap& base_map, const InverseMap& inv) {
  const cv::Mat worn_inside = interior_pixels(worn), base_inside = interior_pixels(base_map);
  SourcePixels s{cv::Mat(roi.size(), CV_32F), cv::Mat(roi.size(), CV_32F), cv::Mat(roi.size(), CV_8U, cv::Scalar(0)),
                 cv::Mat(roi.size(), CV_32F, cv::Scalar(1))};
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      float bx = static_cast<float>(x + roi.x), by = static_cast<float>(y + roi.y);
      const std::size_t p = worn.index(x + roi.x, y + roi.y);
      if (worn.status[p] == PixelStatus::valid && worn.chart_uv[p].allFinite()) {
        const double fi = (worn.chart_uv[p].x() - inv.uv_origin.x()) / inv.texel_mm;
        const double fj = (worn.chart_uv[p].y() - inv.uv_origin.y()) / inv.texel_mm;
        const int i0 = static_cast<int>(std::floor(fi)), j0 = static_cast<int>(std::floor(fj));
        if (i0 >= 0 && j0 >= 0 && i0 + 1 < inv.width && j0 + 1 < inv.height) {
          const std::size_t k = inv.index(i0, j0), w = static_cast<std::size_t>(inv.width);
          if (inv.valid[k] && inv.valid[k + 1] && inv.valid[k + w] && inv.valid[k + w + 1]) {
            const float u = static_cast<float>(fi - i0), v = static_cast<float>(fj - j0);
            auto lerp = [&](const std::vector<float>& m) {
              return (1 - v) * ((1 - u) * m[k] + u * m[k + 1]) + v * ((1 - u) * m[k + w] + u * m[k + w + 1]);
            };
            bx = lerp(inv.map_x), by = lerp(inv.map_y);
            const float tb = bilinear(base_map, base_map.transmittance, bx, by), tw = worn.transmittance[p];
            const int ix = static_cast<int>(std::lround(bx)), iy = static_cast<int>(std::lround(by));
            const bool inside = ix >= 0 && iy >= 0 && ix < base_map.width && iy < base_map.height &&
                                base_inside.at<std::uint8_t>(iy, ix) && worn_inside.at<std::uint8_t>(y + roi.y, x + roi.x);
            if (inside && tb > 0 && tw > 0) {
              s.comparable.at<std::uint8_t>(y, x) = 255;
              s.t_ratio.at<float>(y, x) = tw / tb;
            }
          }
        }
      }
      s.x.at<float>(y, x) = bx, s.y.at<float>(y, x) = by;
    }
  return s;
}


/// The pressed places and a margin around them: ln(worn / baseline) of the local means more than 3 robust
/// deviations above its median, dilated by `margin_px`. Tukey's weights drop strong blanching sample by
/// sample, but a place's mild foot (a few kPa, within the noise per sample) is kept and, lying where the
/// places are, leaks into the fall-off (v came out −0.37 for a true −0.25 on a slab held 1 mm).
cv::Mat pressed_pixels(const cv::Mat& worn_local, const cv::Mat& base_local, const cv::Mat& comparable, double margin_px) {
  cv::Mat d(worn_local.size(), CV_32F, cv::Scalar(kNaN));
  std::vector<double> all;
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x) {
      const float gw = worn_local.at<float>(y, x), gb = base_local.at<float>(y, x);
      if (comparable.at<std::uint8_t>(y, x) && gw > 1e-4f && gb > 1e-4f) d.at<float>(y, x) = std::log(gw / gb), all.push_back(d.at<float>(y, x));
    }
  cv::Mat pressed(d.size(), CV_8U, cv::Scalar(0));
  if (all.size() < 100) return pressed;
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double m = median(all);
  for (double& v : all) v = std::abs(v - m);
  const double limit = m + 3 * 1.4826 * median(all);
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x)
      if (d.at<float>(y, x) > limit) pressed.at<std::uint8_t>(y, x) = 255;
  const int r = static_cast<int>(std::ceil(margin_px));
  if (r > 0) cv::dilate(pressed, pressed, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  return pressed;
}

/// Camera pixels per mm on the chart near the roi's centre (the worn map's chart points of neighbours).
double pixels_per_mm(const RefractionMap& m, const cv::Rect& roi) {
  std::vector<double> steps;
  for (int y = roi.y; y < roi.y + roi.height; y += 4)
    for (int x = roi.x; x + 1 < roi.x + roi.width; x += 4) {
      const std::size_t a = m.index(x, y), b = m.index(x + 1, y);
      if (m.status[a] == PixelStatus::valid && m.status[b] == PixelStatus::valid && m.chart_uv[a].allFinite() && m.chart_uv[b].allFinite())
        steps.push_back((m.chart_uv[b] - m.chart_uv[a]).norm());
    }
  if (steps.empty()) return 1;
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
  const double mm = steps[steps.size() / 2];
  return mm > 0 ? 1 / mm : 1;
}

/// The fall-off's samples: comparable, unsaturated pixels on a stride grid. Each phase's green is
/// averaged over its neighbours first (linear, over the same comparable pixels): the log of one
/// pixel grows with its footprint on the skin (it averages more texture), which differs between
/// the phases and along the band, and would be read as fall-off.
std::vector<VignettingSample> vignetting_samples(const cv::Mat& worn_mean, const cv::Mat& base_mean, const SourcePixels& s,
                                                 const cv::Rect& roi, int image_w, int image_h, int stride, double margin_px) {
  std::vector<VignettingSample> out;
  constexpr float kDark = 1e-4f, kBright = 0.95f;
  const double sigma_px = 2.0 * stride;
  const cv::Mat worn_local = masked_gaussian(worn_mean, s.comparable, sigma_px, cv::BORDER_CONSTANT);
  const cv::Mat base_local = masked_gaussian(base_mean.mul(s.t_ratio), s.comparable, sigma_px, cv::BORDER_CONSTANT);
  const cv::Mat pressed = pressed_pixels(worn_local, base_local, s.comparable, margin_px);
  for (int y = 0; y < roi.height; y += stride)
    for (int x = 0; x < roi.width; x += stride) {
      if (!s.comparable.at<std::uint8_t>(y, x) || pressed.at<std::uint8_t>(y, x)) continue;
      const float gw = worn_local.at<float>(y, x), gb = base_local.at<float>(y, x);
      if (!(gw > kDark && gb > kDark && gw < kBright && gb < kBright)) continue;
      out.push_back({std::log(gw / gb), static_cast<float>(vignetting_r2(x + roi.x, y + roi.y, image_w, image_h)),
                     static_cast<float>(vignetting_r2(s.x.at<float>(y, x), s.y.at<float>(y, x), image_w, image_h))});
    }
  return out;
}

}  // namespace

BaselineAsWorn baseline_as_worn(const PhaseAverage& base, const PhaseAverage& worn, const RefractionMap& worn_map,
                                const RefractionMap& base_map, const InverseMap& base_inv, const VignettingOptions& options) {
  const cv::Rect roi = base.roi;
  SourcePixels src = source_pixels(roi, worn_map, base_map, base_inv);
  const float rx = static_cast<float>(base.residual_shift_px.x()), ry = static_cast<float>(base.residual_shift_px.y());
  cv::Mat mx = src.x - static_cast<float>(roi.x) + rx, my = src.y - static_cast<float>(roi.y) + ry;

  BaselineAsWorn out;
  out.average = base;  // its images are replaced, never written into (cv::Mat shares data)
  PhaseAverage& a = out.average;
  a.mean = cv::Mat(), a.variance = cv::Mat(), a.blue_half = cv::Mat();
  cv::remap(base.mean, a.mean, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::remap(base.variance, a.variance, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE);

  // The fall-off, from the comparable pixels with the transmittances divided out.
  out.vignetting = estimate_vignetting(
      vignetting_samples(worn.mean, a.mean, src, roi, worn_map.width, worn_map.height, options.stride_px,
                         options.pressed_margin_mm * pixels_per_mm(worn_map, roi)),
      options);
  cv::Mat factor = src.t_ratio.clone();
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x)
      if (src.comparable.at<std::uint8_t>(y, x) && out.vignetting.v != 0) {
        const double v = out.vignetting.v;
        const double lw = log_vignetting(v, vignetting_r2(x + roi.x, y + roi.y, worn_map.width, worn_map.height));
        const double lb = log_vignetting(v, vignetting_r2(src.x.at<float>(y, x), src.y.at<float>(y, x), worn_map.width, worn_map.height));
        factor.at<float>(y, x) *= static_cast<float>(std::exp(lw - lb));
      }
  a.mean = a.mean.mul(factor);
  a.variance = a.variance.mul(factor.mul(factor));

  if (!base.blue_half.empty()) {  // the half grid: every other pixel's source, halved
    cv::Mat hx(base.blue_half.size(), CV_32F), hy(base.blue_half.size(), CV_32F), hf(base.blue_half.size(), CV_32F);
    for (int j = 0; j < hx.rows; ++j)
      for (int i = 0; i < hx.cols; ++i) {
        const int x = std::min(2 * i, roi.width - 1), y = std::min(2 * j, roi.height - 1);
        const int x1 = std::min(x + 1, roi.width - 1);  // the cell averages columns 2i, 2i + 1 of row 2j
        hx.at<float>(j, i) = 0.5f * (0.5f * (mx.at<float>(y, x) + mx.at<float>(y, x1)) - 0.5f), hy.at<float>(j, i) = 0.5f * my.at<float>(y, x);
        hf.at<float>(j, i) = factor.at<float>(y, x);
      }
    cv::remap(base.blue_half, a.blue_half, hx, hy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    a.blue_half = a.blue_half.mul(hf);
  }
  a.residual_shift_px = Vec2::Zero();
  out.comparable = src.comparable;
  return out;
}

std::vector<float> log_phase_ratio(const RefractionMap& worn, const InverseMap& worn_inv, const RefractionMap& base,
                                   const InverseMap& base_inv, double v) {
  std::vector<float> r(worn_inv.valid.size(), kNaN);
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (!worn_inv.valid[k] || !base_inv.valid[k]) continue;
    const double xw = worn_inv.map_x[k], yw = worn_inv.map_y[k], xb = base_inv.map_x[k], yb = base_inv.map_y[k];
    const float tw = bilinear(worn, worn.transmittance, xw, yw), tb = bilinear(base, base.transmittance, xb, yb);
    if (!(tw > 0 && tb > 0)) continue;
    const double lv = log_vignetting(v, vignetting_r2(xw, yw, worn.width, worn.height)) -
                      log_vignetting(v, vignetting_r2(xb, yb, base.width, base.height));
    r[k] = static_cast<float>(std::log(tw / tb) + lv);
  }
  return r;
}

PhaseAverage nan_where_unseen(const PhaseAverage& average, const RefractionMap& map) {
  PhaseAverage out = average;
  out.mean = average.mean.clone();
  const cv::Rect roi = average.roi;
  const cv::Mat inside = interior_pixels(map);
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      const int ix = x + roi.x, iy = y + roi.y;
      if (ix < 0 || iy < 0 || ix >= map.width || iy >= map.height || !inside.at<std::uint8_t>(iy, ix)) out.mean.at<float>(y, x) = kNaN;
    }
  return out;
}

}  // namespace clearfit
