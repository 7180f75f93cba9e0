#include <clearfit/format.hpp>
#include <clearfit/fit/vignetting.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace clearfit {

namespace {

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Residuals of the model at (c, v) and their robust scale (1.4826 MAD, floored).
double residuals(const std::vector<VignettingSample>& s, double c, double v, std::vector<double>& e) {
  e.resize(s.size());
  std::vector<double> a(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    e[i] = s[i].d - c - (log_vignetting(v, s[i].r2_worn) - log_vignetting(v, s[i].r2_base));
    a[i] = std::abs(e[i]);
  }
  return std::max(1.4826 * median_of(std::move(a)), 1e-6);
}

}  // namespace

void VignettingOptions::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(std::string("assess.vignetting.") + field + " = " + fixed_digits(v, 4) + ": " + rule);
  };
  check(max_abs > 0 && max_abs < 1, "max_abs", max_abs, "must be in (0, 1)");
  check(min_spread >= 0 && min_spread < 0.1, "min_spread", min_spread, "must be in [0, 0.1)");
  check(stride_px >= 1 && stride_px <= 64, "stride_px", stride_px, "must be in [1, 64]");
  check(pressed_margin_mm >= 0 && pressed_margin_mm <= 20, "pressed_margin_mm", pressed_margin_mm, "must be in [0, 20] mm");
}

double vignetting_r2(double x, double y, int width, int height) {
  const double cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  return ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / std::max(cx * cx + cy * cy, 1e-12);
}

VignettingEstimate estimate_vignetting(const std::vector<VignettingSample>& samples, const VignettingOptions& o) {
  o.validate();
  VignettingEstimate est;
  est.samples = static_cast<long long>(samples.size());
  if (!o.enabled) return est.problem = "disabled", est;
  if (samples.size() < 100) return est.problem = "fewer than 100 pixels are seen in both phases", est;
  double m = 0, m2 = 0;
  for (const auto& s : samples) {
    const double x = s.r2_worn - s.r2_base;
    m += x, m2 += x * x;
  }
  m /= samples.size();
  est.spread = std::sqrt(std::max(0.0, m2 / samples.size() - m * m));
  if (est.spread < o.min_spread)
    return est.problem = "the phases see the skin at nearly the same pixels (no parallax to tell the fall-off)", est;

  // Iteratively reweighted Gauss–Newton on (c, v) with Tukey's biweight.
  std::vector<double> e, d(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) d[i] = samples[i].d;
  double c = median_of(d), v = 0, scale = residuals(samples, c, v, e), sigma = 0;
  long long inliers = 0;
  for (int iter = 0; iter < 20; ++iter) {
    const double k = 4.685 * scale;
    double s11 = 0, s12 = 0, s22 = 0, b1 = 0, b2 = 0, rss = 0, wsum = 0;
    inliers = 0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const double u = e[i] / k;
      if (std::abs(u) >= 1) continue;
      const double w = (1 - u * u) * (1 - u * u);
      const double j = samples[i].r2_worn / (1 + v * samples[i].r2_worn) - samples[i].r2_base / (1 + v * samples[i].r2_base);
      s11 += w, s12 += w * j, s22 += w * j * j, b1 += w * e[i], b2 += w * j * e[i];
      rss += w * e[i] * e[i], wsum += w, ++inliers;
    }
    const double det = s11 * s22 - s12 * s12;
    if (inliers < 50 || !(det > 1e-30 * std::max(1.0, s11 * s22))) return est.problem = "the fit is singular", est;
    const double dc = (s22 * b1 - s12 * b2) / det, dv = (s11 * b2 - s12 * b1) / det;
    c += dc, v = std::clamp(v + dv, -0.99, 0.99);
    sigma = std::sqrt(rss / std::max(wsum - 2, 1.0) * s11 / det);
    scale = residuals(samples, c, v, e);
    if (std::abs(dv) < 1e-5 && std::abs(dc) < 1e-7) break;
  }
  est.inlier_fraction = static_cast<double>(inliers) / samples.size();
  est.sigma = sigma;
  if (!std::isfinite(v) || std::abs(v) > o.max_abs) {
    est.problem = "the fitted fall-off (" + fixed_digits(v, 3) + " at the corner) is beyond " + fixed_digits(o.max_abs, 2) +
                  ": what differs between the phases is not vignetting";
    return est;
  }
  est.estimated = true;
  est.v = v;
  return est;
}

}  // namespace clearfit
