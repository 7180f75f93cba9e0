// Registration of the phases on the chart (see phase_registration.hpp).
#include <clearfit/fit/phase_registration.hpp>
#include <clearfit/format.hpp>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace clearfit {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string fmt(double v, int digits) { return fixed_digits(v, digits); }

double quantile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::ptrdiff_t>(std::min(v.size() - 1, static_cast<std::size_t>(q * v.size())));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

/// An average's image (`half`: on the half grid of photometric.hpp) read at each texel's pixel
/// (CV_32F chart grid; NaN where the texel is not valid or its pixel lies outside the roi).
cv::Mat on_chart(const cv::Mat& image, bool half, const PhaseAverage& avg, const InverseMap& inv) {
  cv::Mat mx(inv.height, inv.width, CV_32F), my(inv.height, inv.width, CV_32F);
  const float dx = static_cast<float>(avg.residual_shift_px.x() - avg.roi.x), dy = static_cast<float>(avg.residual_shift_px.y() - avg.roi.y);
  for (std::size_t k = 0; k < inv.valid.size(); ++k) {
    float x = inv.valid[k] ? inv.map_x[k] + dx : -1e6f, y = inv.valid[k] ? inv.map_y[k] + dy : -1e6f;
    if (half) x = 0.5f * (x - 0.5f), y = 0.5f * y;  // half-grid cell (i, j) is the mean of roi pixels (2i, 2j), (2i + 1, 2j)
    mx.at<float>(static_cast<int>(k)) = x, my.at<float>(static_cast<int>(k)) = y;
  }
  cv::Mat out;
  cv::remap(image, out, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(kNaN));
  for (std::size_t k = 0; k < inv.valid.size(); ++k) {
    const float x = mx.at<float>(static_cast<int>(k)), y = my.at<float>(static_cast<int>(k));
    if (!inv.valid[k] || x < 0 || y < 0 || x > image.cols - 1 || y > image.rows - 1) out.at<float>(static_cast<int>(k)) = kNaN;
  }
  return out;
}

/// Gaussian of σ texels over the texels where `w` > 0 (normalised convolution); `v` is weighted by `w`.
cv::Mat weighted_blur(const cv::Mat& v, const cv::Mat& w, double sigma, cv::Mat* weight_out = nullptr) {
  cv::Mat vw = v.mul(w), num, den;
  cv::GaussianBlur(vw, num, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::GaussianBlur(w, den, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::Mat out = num / cv::max(den, 1e-12);
  if (weight_out) *weight_out = den;
  return out;
}

/// The feature ln R − ratio·ln G, high-passed; NaN where unseen.
cv::Mat texture(const PhaseAverage& avg, const InverseMap& inv, const PhaseRegistrationOptions& o) {
  const cv::Mat g = on_chart(avg.mean, false, avg, inv), r = on_chart(avg.red, false, avg, inv);
  cv::Mat f(g.size(), CV_32F), seen(g.size(), CV_32F);
  for (int k = 0; k < static_cast<int>(g.total()); ++k) {
    const float G = g.at<float>(k), R = r.at<float>(k);
    const bool ok = G > 1e-4f && R > 1e-4f;  // NaN compares false
    f.at<float>(k) = ok ? std::log(R) - static_cast<float>(o.red_green_ratio) * std::log(G) : 0.f;
    seen.at<float>(k) = ok ? 1.f : 0.f;
  }
  const cv::Mat low = weighted_blur(f, seen, o.highpass_mm / inv.texel_mm);
  cv::Mat t = f - low;
  t.setTo(kNaN, seen == 0);
  return t;
}

/// Normalised correlation of a and b over `mask` (CV_8U).
double correlation(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  long long n = 0;
  for (int k = 0; k < static_cast<int>(a.total()); ++k) {
    const double x = a.at<float>(k), y = b.at<float>(k);
    if (!mask.at<std::uint8_t>(k) || !std::isfinite(x) || !std::isfinite(y)) continue;
    sa += x, sb += y, saa += x * x, sbb += y * y, sab += x * y, ++n;
  }
  if (n < 2) return 0;
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  return va > 0 && vb > 0 ? (sab - sa * sb / n) / std::sqrt(va * vb) : 0;
}

/// 8-bit image of a texture for DIS: 128 + 32 per robust σ, clipped; 128 where unseen.
cv::Mat to_u8(const cv::Mat& t, double sigma) {
  cv::Mat out(t.size(), CV_8U);
  for (int k = 0; k < static_cast<int>(t.total()); ++k) {
    const float v = t.at<float>(k);
    out.at<std::uint8_t>(k) = std::isfinite(v) ? cv::saturate_cast<std::uint8_t>(128.0 + 32.0 * v / sigma) : 128;
  }
  return out;
}

}  // namespace

void PhaseRegistrationOptions::validate() const {
  auto rule = [](bool ok, const std::string& field, double v, const std::string& what) {
    if (!ok) throw std::invalid_argument("phase_registration." + field + " = " + fmt(v, 3) + ": " + what);
  };
  rule(std::isfinite(red_green_ratio) && red_green_ratio >= 0 && red_green_ratio <= 1, "red_green_ratio", red_green_ratio, "must be in [0, 1]");
  rule(std::isfinite(highpass_mm) && highpass_mm >= 0.1 && highpass_mm <= 10, "highpass_mm", highpass_mm, "must be in [0.1, 10] mm");
  rule(std::isfinite(smoothing_mm) && smoothing_mm >= 0.05 && smoothing_mm <= 5, "smoothing_mm", smoothing_mm, "must be in [0.05, 5] mm");
  rule(std::isfinite(max_displacement_mm) && max_displacement_mm > 0, "max_displacement_mm", max_displacement_mm, "must be > 0 mm");
  rule(std::isfinite(min_match) && min_match >= 0 && min_match <= 1, "min_match", min_match, "must be in [0, 1]");
  rule(std::isfinite(max_weak_fraction) && max_weak_fraction >= 0 && max_weak_fraction <= 1, "max_weak_fraction", max_weak_fraction,
       "must be in [0, 1]");
}

PhaseRegistration register_phases(const PhaseAverage& baseline, const PhaseAverage& worn, const InverseMap& base_inv,
                                  const InverseMap& worn_inv, const std::vector<std::uint8_t>& excluded, const PhaseRegistrationOptions& o) {
  o.validate();
  const auto t0 = std::chrono::steady_clock::now();
  if (base_inv.width != worn_inv.width || base_inv.height != worn_inv.height)
    throw std::invalid_argument("register_phases: the two inverse maps' grids differ");
  if (baseline.red.empty() || worn.red.empty()) throw std::invalid_argument("register_phases: the averages hold no red");
  PhaseRegistration r;
  ChartGrid grid;
  grid.width = worn_inv.width, grid.height = worn_inv.height, grid.texel_mm = worn_inv.texel_mm, grid.uv_origin = worn_inv.uv_origin;
  r.dx_mm = r.dy_mm = {grid, std::vector<float>(grid.size(), kNaN)};
  const cv::Mat tb = texture(baseline, base_inv, o), tw = texture(worn, worn_inv, o);
  cv::Mat seen(tw.size(), CV_8U);
  std::vector<float> abs_tw;
  for (int k = 0; k < static_cast<int>(tw.total()); ++k) {
    const bool ok = std::isfinite(tw.at<float>(k)) && std::isfinite(tb.at<float>(k)) && (excluded.empty() || !excluded[k]);
    seen.at<std::uint8_t>(k) = ok;
    if (ok) abs_tw.push_back(std::abs(tw.at<float>(k)));
  }
  r.texels = static_cast<long long>(abs_tw.size());
  auto done = [&] {
    r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return r;
  };
  const double sigma = 1.4826 * quantile(abs_tw, 0.5);
  if (r.texels < 400 || !(sigma > 1e-5)) {
    r.warnings.push_back("the phases could not be registered on the chart: " + std::to_string(r.texels) + " texels seen in both, texture " +
                         fmt(sigma, 5) + " (ln units); skin that slid between them would be read as pressure");
    return done();
  }
  // Dense flow: worn(x) ≈ baseline(x + flow(x)), texels.
  // The texture without its finest lines: ridges repeat every ~0.3 mm, about as far as skin slides,
  // so a flow that follows them locks onto the wrong ridge; the mottling does not repeat.
  cv::Mat seen_f;
  seen.convertTo(seen_f, CV_32F);
  auto coarse = [&](const cv::Mat& t) {
    cv::Mat z = t.clone();
    z.setTo(0, seen == 0);
    cv::Mat c = weighted_blur(z, seen_f, o.coarse_mm / grid.texel_mm);
    c.setTo(kNaN, seen == 0);
    return c;
  };
  const cv::Mat cw = coarse(tw), cb = coarse(tb);
  std::vector<float> abs_cw;
  for (int k = 0; k < static_cast<int>(cw.total()); ++k)
    if (seen.at<std::uint8_t>(k)) abs_cw.push_back(std::abs(cw.at<float>(k)));
  const double sigma_c = std::max(1.4826 * quantile(abs_cw, 0.5), 1e-6);
  // On a grid of half the chart's resolution when that is still finer than the blur (DIS is then a quarter of the work).
  const bool half = o.coarse_mm >= 2 * grid.texel_mm;
  cv::Mat w8 = to_u8(cw, sigma_c), b8 = to_u8(cb, sigma_c), flow;
  if (half) {
    cv::resize(w8, w8, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    cv::resize(b8, b8, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  }
  cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  dis->calc(w8, b8, flow);
  if (half) {
    cv::resize(flow, flow, tw.size(), 0, 0, cv::INTER_LINEAR);
    flow *= 2.0;
  }
  // Confidence: local texture energy of the worn texture followed (gradients), nothing outside the seen texels.
  const double s = o.smoothing_mm / grid.texel_mm;
  cv::Mat gx, gy, energy, twz = cw.clone();
  twz.setTo(0, seen == 0);
  cv::Sobel(twz, gx, CV_32F, 1, 0);
  cv::Sobel(twz, gy, CV_32F, 0, 1);
  energy = weighted_blur(gx.mul(gx) + gy.mul(gy), seen_f, s);
  std::vector<float> e_seen;
  for (int k = 0; k < static_cast<int>(energy.total()); ++k)
    if (seen.at<std::uint8_t>(k)) e_seen.push_back(energy.at<float>(k));
  const double e_med = std::max(quantile(e_seen, 0.5), 1e-12);
  long long weak = 0;
  cv::Mat w(tw.size(), CV_32F, cv::Scalar(0));
  for (int k = 0; k < static_cast<int>(w.total()); ++k)
    if (seen.at<std::uint8_t>(k)) {
      const double e = energy.at<float>(k) / e_med;
      weak += e < 0.1;
      w.at<float>(k) = static_cast<float>(std::min(1.0, e));
    }
  r.weak_texture_fraction = static_cast<double>(weak) / r.texels;
  // Regularise twice: the second pass leaves out vectors far from the first (robust).
  cv::Mat fc[2];
  cv::split(flow, fc);
  cv::Mat sx = weighted_blur(fc[0], w, s), sy = weighted_blur(fc[1], w, s);
  std::vector<float> dev;
  for (int k = 0; k < static_cast<int>(w.total()); ++k)
    if (seen.at<std::uint8_t>(k)) dev.push_back(std::hypot(fc[0].at<float>(k) - sx.at<float>(k), fc[1].at<float>(k) - sy.at<float>(k)));
  const double cut = 3 * std::max(1.4826 * quantile(dev, 0.5), 0.05);
  cv::Mat w2 = w.clone();
  for (int k = 0; k < static_cast<int>(w.total()); ++k)
    if (std::hypot(fc[0].at<float>(k) - sx.at<float>(k), fc[1].at<float>(k) - sy.at<float>(k)) > cut) w2.at<float>(k) = 0;
  cv::Mat weight;
  sx = weighted_blur(fc[0], w2, s, &weight);
  sy = weighted_blur(fc[1], w2, s);
  // The skin moved by −flow (baseline → worn); defined where the worn map sees and weights reach.
  std::vector<float> mag;
  for (int k = 0; k < static_cast<int>(w.total()); ++k) {
    if (!worn_inv.valid[static_cast<std::size_t>(k)] || !(weight.at<float>(k) > 1e-6f)) continue;
    r.dx_mm.value[k] = static_cast<float>(-sx.at<float>(k) * grid.texel_mm);
    r.dy_mm.value[k] = static_cast<float>(-sy.at<float>(k) * grid.texel_mm);
    if (seen.at<std::uint8_t>(k)) mag.push_back(std::hypot(r.dx_mm.value[k], r.dy_mm.value[k]));
  }
  r.median_mm = quantile(mag, 0.5), r.p95_mm = quantile(mag, 0.95), r.max_mm = quantile(mag, 1.0);
  // How well the textures agree, before and after.
  cv::Mat mx(tw.size(), CV_32F), my(tw.size(), CV_32F), cb_moved;
  for (int j = 0; j < tw.rows; ++j)
    for (int i = 0; i < tw.cols; ++i) mx.at<float>(j, i) = i + sx.at<float>(j, i), my.at<float>(j, i) = j + sy.at<float>(j, i);
  cv::remap(cb, cb_moved, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(kNaN));
  r.match_before = correlation(cw, cb, seen);
  r.match_after = correlation(cw, cb_moved, seen);
  r.applied = true;
  const std::string figures = " (median " + fmt(r.median_mm, 3) + " mm, p95 " + fmt(r.p95_mm, 3) + " mm, max " + fmt(r.max_mm, 3) +
                              " mm; texture correlation " + fmt(r.match_before, 2) + " before, " + fmt(r.match_after, 2) + " after)";
  if (r.match_after < o.min_match)
    r.warnings.push_back("the registration of the phases is unsure: the skin textures of the two captures correlate only " +
                         fmt(r.match_after, 2) + " after it (at least " + fmt(o.min_match, 2) + " expected)" + figures +
                         "; skin that slid between them may be read as pressure");
  if (r.weak_texture_fraction > o.max_weak_fraction)
    r.warnings.push_back("the registration of the phases is unsure on " + fmt(100 * r.weak_texture_fraction, 0) +
                         " % of the seen skin: too little texture there to follow it (the field is interpolated from around)" + figures);
  if (r.max_mm > o.max_displacement_mm)
    r.warnings.push_back("the skin moved by up to " + fmt(r.max_mm, 2) + " mm between the captures (more than " +
                         fmt(o.max_displacement_mm, 2) + " mm): registered, but check that the part and the skin stayed put" + figures);
  return done();
}

InverseMap displaced_inverse(const InverseMap& inv, const PhaseRegistration& r) {
  InverseMap out = inv;
  if (!r.applied) return out;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const std::size_t k = inv.index(i, j);
      const float dx = r.dx_mm.value[k], dy = r.dy_mm.value[k];
      if (!std::isfinite(dx) || !std::isfinite(dy)) continue;
      const double fi = i - dx / inv.texel_mm, fj = j - dy / inv.texel_mm;
      const int i0 = static_cast<int>(std::floor(fi)), j0 = static_cast<int>(std::floor(fj));
      // Bilinear over the valid taps (renormalised), when they carry most of the weight.
      double w = 0, x = 0, y = 0;
      for (int dj = 0; dj < 2; ++dj)
        for (int di = 0; di < 2; ++di) {
          const int ii = i0 + di, jj = j0 + dj;
          if (ii < 0 || jj < 0 || ii >= inv.width || jj >= inv.height) continue;
          const std::size_t t = inv.index(ii, jj);
          if (!inv.valid[t]) continue;
          const double wt = (di ? fi - i0 : 1 - (fi - i0)) * (dj ? fj - j0 : 1 - (fj - j0));
          w += wt, x += wt * inv.map_x[t], y += wt * inv.map_y[t];
        }
      // Else (the skin's edge) the texel keeps its own pixel.
      if (w >= 0.5) out.valid[k] = 1, out.map_x[k] = static_cast<float>(x / w), out.map_y[k] = static_cast<float>(y / w);
    }
  return out;
}

}  // namespace clearfit
