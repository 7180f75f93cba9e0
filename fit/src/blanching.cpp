#include <algorithm>
#include <clearfit/error.hpp>
#include <clearfit/fit/blanching.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/format.hpp>
#include "map_jacobian.hpp"
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace clearfit {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

ChartGrid grid_of(const InverseMap& inverse) {
  ChartGrid g;
  g.width = inverse.width;
  g.height = inverse.height;
  g.texel_mm = inverse.texel_mm;
  g.uv_origin = inverse.uv_origin;
  return g;
}

ChartField empty_field(const ChartGrid& g) { return {g, std::vector<float>(g.size(), kNaN)}; }

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Chart texels per camera pixel at each texel of a map: 1 / |det ∂pixel/∂texel| (central differences
/// of the map, one-sided at its edges), at least 1 (a texel coarser than the pixels samples them apart);
/// where no neighbour is valid, the median over the map. Bilinear resampling gives every texel of a
/// pixel's footprint that pixel's noise: the more texels a pixel spans (the contact surface seen
/// obliquely, the map steep), the fewer independent samples a smoothing kernel holds.
std::vector<float> texels_per_pixel(const InverseMap& inv) {
  std::vector<float> out(inv.valid.size(), kNaN);
  std::vector<double> known;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      if (!inv.valid[inv.index(i, j)]) continue;
      const auto J = pixel_jacobian(inv, i, j);  // px per mm
      if (!J) continue;
      const double det = std::abs(J->determinant()) * inv.texel_mm * inv.texel_mm;  // px² per texel
      out[inv.index(i, j)] = static_cast<float>(std::max(1.0, 1.0 / det));
      known.push_back(out[inv.index(i, j)]);
    }
  const double m = median(std::move(known));
  for (std::size_t k = 0; k < out.size(); ++k)
    if (inv.valid[k] && !std::isfinite(out[k])) out[k] = std::isfinite(m) ? static_cast<float>(m) : 1.f;
  return out;
}

/// σ of the smoothed feature per texel. smooth_field is a normalised convolution: y_k = Σ g_ki x_i / Σ g_ki
/// over the seen texels i, so Var(y_k) = Σ g_ki² var_i n_i / (Σ g_ki)², with var_i the texel's own variance
/// and n_i its texels per camera pixel (texels_per_pixel: the n texels of one pixel carry one noise). Where
/// the kernel holds fewer seen texels (the edge of the seen skin, a strip between a mask and the rim) or
/// fewer pixels (an oblique view), the σ grows. It is at most the local variance itself (a kernel
/// narrower than a pixel averages nothing). `var`: var_i; `var_n`: var_i·n_i; NaN where unseen.
ChartField smoothed_sigma(const ChartField& var, const ChartField& var_n, double sigma_mm) {
  const ChartGrid& g = var.grid;
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  if (!(sigma_mm > 0)) {
    for (std::size_t k = 0; k < g.size(); ++k) out.value[k] = std::sqrt(var.value[k]);
    return out;
  }
  const double s = sigma_mm / g.texel_mm;
  const cv::Mat kernel = cv::getGaussianKernel(cvRound(s * 4 * 2 + 1) | 1, s, CV_32F);  // GaussianBlur's own (smooth_field)
  const cv::Mat kernel2 = kernel.mul(kernel);
  cv::Mat seen(g.height, g.width, CV_32F, cv::Scalar(0)), vn(seen.size(), CV_32F, cv::Scalar(0)), v(seen.size(), CV_32F, cv::Scalar(0));
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i)
      if (const auto k = g.index(i, j); std::isfinite(var.value[k]) && std::isfinite(var_n.value[k]))
        seen.at<float>(j, i) = 1, v.at<float>(j, i) = var.value[k], vn.at<float>(j, i) = var_n.value[k];
  cv::Mat weight, sum2, local;
  cv::sepFilter2D(seen, weight, CV_32F, kernel, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
  cv::sepFilter2D(vn, sum2, CV_32F, kernel2, kernel2, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
  cv::sepFilter2D(v, local, CV_32F, kernel, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      const double w = weight.at<float>(j, i);
      if (!seen.at<float>(j, i) || !(w > 1e-6)) continue;
      const double smoothed = sum2.at<float>(j, i) / (w * w), ceiling = local.at<float>(j, i) / w;
      out.value[k] = static_cast<float>(std::sqrt(std::max(0.0, std::min(smoothed, ceiling))));
    }
  return out;
}

/// Robust spread of the smoothed feature over the seen texels (the unpressed majority: 3-MAD
/// clipping around the median, the clipped Gaussian's SD corrected); what the frames' spread
/// does not explain is added to each texel's sigma in quadrature, scaled by `kernel`: the sigma a
/// unit noise per camera pixel keeps after the texel's smoothing (smoothed_sigma), over its median.
/// The compression's error is the camera pixels' as the frames' noise is, so it grows as theirs does
/// where the kernel holds fewer pixels: at the seen skin's edge, beside a glare mask, where the part
/// is seen obliquely (one pixel over several texels).
void add_spatial_noise(BlanchingSignal& s, const ChartField& kernel) {
  std::vector<double> y;
  for (float v : s.y.value)
    if (std::isfinite(v)) y.push_back(v);
  if (y.size() < 10) return;
  double m = median(y), sd = 0;
  for (int iter = 0; iter < 5; ++iter) {
    std::vector<double> dev;
    dev.reserve(y.size());
    for (double v : y) dev.push_back(std::abs(v - m));
    const double mad = 1.4826 * median(dev);
    if (!(mad > 0)) return;
    std::vector<double> kept;
    for (double v : y)
      if (std::abs(v - m) <= 3 * mad) kept.push_back(v);
    double sum = 0, sum2 = 0;
    for (double v : kept) sum += v, sum2 += v * v;
    m = sum / kept.size();
    sd = std::sqrt(std::max(0.0, sum2 / kept.size() - m * m)) / 0.9866;  // SD of a Gaussian clipped at ±3σ
  }
  const double extra2 = sd * sd - s.temporal_noise_sigma * s.temporal_noise_sigma;
  if (!(extra2 > 0)) return;
  s.spatial_noise_sigma = std::sqrt(extra2);
  std::vector<double> k_seen;
  for (std::size_t k = 0; k < s.sigma_y.value.size(); ++k)
    if (std::isfinite(s.sigma_y.value[k]) && std::isfinite(kernel.value[k]) && kernel.value[k] > 0) k_seen.push_back(kernel.value[k]);
  const double k_median = k_seen.empty() ? 0.0 : median(std::move(k_seen));
  std::vector<double> sig;
  for (std::size_t k = 0; k < s.sigma_y.value.size(); ++k)
    if (float& v = s.sigma_y.value[k]; std::isfinite(v)) {
      const double share = k_median > 0 && std::isfinite(kernel.value[k]) ? std::max(1.0, kernel.value[k] / k_median) : 1.0;
      v = static_cast<float>(std::sqrt(v * v + extra2 * share * share));
      sig.push_back(v);
    }
  s.noise_sigma = median(std::move(sig));
}

/// The local spatial term (BlanchingOptions::local_spatial_noise).
void add_local_spatial_noise(BlanchingSignal& s, double window_mm) {
  const ChartGrid& g = s.y.grid;
  cv::Mat neg2(g.height, g.width, CV_32F, cv::Scalar(0)), neg(g.height, g.width, CV_32F, cv::Scalar(0));
  cv::Mat tmp2(g.height, g.width, CV_32F, cv::Scalar(0)), seen(g.height, g.width, CV_32F, cv::Scalar(0));
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const std::size_t k = g.index(i, j);
      const float y = s.y.value[k], t = s.sigma_y.value[k];
      if (!std::isfinite(y) || !std::isfinite(t)) continue;
      seen.at<float>(j, i) = 1;
      if (y < 0) neg2.at<float>(j, i) = y * y, neg.at<float>(j, i) = 1, tmp2.at<float>(j, i) = t * t;
    }
  const double w = window_mm / g.texel_mm;
  for (cv::Mat* m : {&neg2, &neg, &tmp2, &seen}) cv::GaussianBlur(*m, *m, cv::Size(), w, w, cv::BORDER_CONSTANT);
  // A window counts when a fifth of its seen texels are negative (unpressed skin has half).
  std::vector<float> extra(g.size(), kNaN);
  long long known = 0;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const std::size_t k = g.index(i, j);
      if (!std::isfinite(s.y.value[k]) || !std::isfinite(s.sigma_y.value[k])) continue;
      const float n = neg.at<float>(j, i), all = seen.at<float>(j, i);
      if (!(n > 0.2f * all && n > 1e-6f)) continue;
      extra[k] = std::max(0.f, (neg2.at<float>(j, i) - tmp2.at<float>(j, i)) / n);
      ++known;
    }
  if (known == 0) return;
  std::vector<double> sig, local;
  for (std::size_t k = 0; k < g.size(); ++k) {
    float& v = s.sigma_y.value[k];
    if (!std::isfinite(v) || !std::isfinite(s.y.value[k])) continue;
    const float e2 = std::isfinite(extra[k]) ? extra[k] : 0.f;
    v = std::sqrt(v * v + e2);
    sig.push_back(v), local.push_back(std::sqrt(e2));
  }
  s.noise_sigma = median(std::move(sig));
  std::nth_element(local.begin(), local.begin() + static_cast<std::ptrdiff_t>(0.95 * (local.size() - 1)), local.end());
  s.local_noise_sigma_p95 = local[static_cast<std::size_t>(0.95 * (local.size() - 1))];
}


/// The unpressed skin's level of a feature: blanching only raises it, so the unpressed texels are a
/// Gaussian around the level and the pressed ones a tail above it. Iterated: σ from the lower half
/// (1.4826 × the median distance below the level), the texels above level + 2σ left out, and the
/// median of the rest, corrected by the median of a Gaussian cut at +2σ (Φ⁻¹(Φ(2)/2) = −0.0286σ).
/// On the SigmaCoverage scenes (42 % of the seen skin pressed) it lands within 0.15σ of the unpressed
/// texels' own median; the plain median of all texels is 0.4σ above it.
double unpressed_level(const std::vector<double>& values) {
  double m = median(values);
  for (int iter = 0; iter < 50; ++iter) {
    std::vector<double> below, kept;
    for (double v : values)
      if (v <= m) below.push_back(m - v);
    const double sd = std::max(1.4826 * median(std::move(below)), 1e-9);
    for (double v : values)
      if (v <= m + 2 * sd) kept.push_back(v);
    const double next = median(std::move(kept)) + 0.0286 * sd;
    if (std::abs(next - m) < 1e-4 * sd) return next;
    m = next;
  }
  return m;
}

/// Reference: a user disk (the median of its seen texels), or the unpressed level of all seen texels.
void apply_reference(BlanchingSignal& s, const BlanchingOptions& options) {
  const ChartGrid& g = s.y.grid;
  std::vector<double> ref;
  if (options.reference_uv_mm) {
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i)
        if (const float r = s.y.value[g.index(i, j)]; std::isfinite(r) && (g.uv(i, j) - *options.reference_uv_mm).norm() <= options.reference_radius_mm)
          ref.push_back(r);
    if (ref.empty())
      throw InputError("", "assess.reference_uv_mm", "the reference disk holds no seen texel of the chart",
                       "place it on skin that the camera sees through the part and that is not pressed");
    s.reference_log_ratio = median(ref);
    s.reference = "disk of " + std::to_string(options.reference_radius_mm) + " mm at chart (" +
                  std::to_string(options.reference_uv_mm->x()) + ", " + std::to_string(options.reference_uv_mm->y()) + ") mm, " +
                  std::to_string(ref.size()) + " texels";
  } else {
    for (float r : s.y.value)
      if (std::isfinite(r)) ref.push_back(r);
    s.reference_log_ratio = unpressed_level(ref);
    s.reference = "the unpressed level of all seen texels (assumes the pressed area is less than half of what is seen)";
  }
  for (auto& r : s.y.value)
    if (std::isfinite(r)) r -= static_cast<float>(s.reference_log_ratio);
}

}  // namespace

ChartField resample_to_chart(const PhaseAverage& average, const InverseMap& inverse) {
  const ChartGrid g = grid_of(inverse);
  ChartField out = empty_field(g);
  if (g.size() == 0) return out;
  cv::Mat mx(g.height, g.width, CV_32F), my(g.height, g.width, CV_32F);
  const float dx = static_cast<float>(average.residual_shift_px.x() - average.roi.x);
  const float dy = static_cast<float>(average.residual_shift_px.y() - average.roi.y);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      const bool ok = inverse.valid[k] != 0;
      mx.at<float>(j, i) = ok ? inverse.map_x[k] + dx : -1e6f;
      my.at<float>(j, i) = ok ? inverse.map_y[k] + dy : -1e6f;
    }
  cv::Mat sampled;
  // Linear interpolation; taps outside the averaged roi read NaN and make the texel unseen.
  cv::remap(average.mean, sampled, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(kNaN));
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (!inverse.valid[k]) continue;
      // Taps must lie inside the roi: remap blends border NaN into edge texels as NaN already;
      // a texel whose pixel is outside the roi by more than a pixel reads the border value.
      const float x = mx.at<float>(j, i), y = my.at<float>(j, i);
      if (x < 0 || y < 0 || x > average.roi.width - 1 || y > average.roi.height - 1) continue;
      out.value[k] = sampled.at<float>(j, i);
    }
  return out;
}

ChartField smooth_field(const ChartField& field, double sigma_mm) {
  if (!(sigma_mm > 0) || field.grid.size() == 0) return field;
  const ChartGrid& g = field.grid;
  cv::Mat v(g.height, g.width, CV_32F), w(g.height, g.width, CV_32F);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const float x = field.value[g.index(i, j)];
      const bool ok = std::isfinite(x);
      v.at<float>(j, i) = ok ? x : 0.f;
      w.at<float>(j, i) = ok ? 1.f : 0.f;
    }
  const double s = sigma_mm / g.texel_mm;
  cv::GaussianBlur(v, v, cv::Size(), s, s, cv::BORDER_CONSTANT);
  cv::GaussianBlur(w, w, cv::Size(), s, s, cv::BORDER_CONSTANT);
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (std::isfinite(field.value[k]) && w.at<float>(j, i) > 1e-6f) out.value[k] = v.at<float>(j, i) / w.at<float>(j, i);
    }
  return out;
}

void BlanchingOptions::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(std::string("assess.") + field + " = " + significant_digits(v, 4) + ": must be " + rule);
  };
  check(std::isfinite(smoothing_mm) && smoothing_mm >= 0, "smoothing_mm", smoothing_mm, ">= 0 mm");
  SkinBlur{skin_blur_mm}.validate("assess.skin_blur_mm");
  check(curvature_smoothing_mm > 0 && curvature_smoothing_mm < 20, "curvature_smoothing_mm", curvature_smoothing_mm,
        "in (0, 20) mm (the scale over which the deblur reads the blur's first-order term)");
  check(std::isfinite(reference_radius_mm) && reference_radius_mm > 0, "reference_radius_mm", reference_radius_mm, "a positive length in mm");
  check(!local_spatial_noise || (local_noise_window_mm > 0 && std::isfinite(local_noise_window_mm)), "local_noise_window_mm",
        local_noise_window_mm, "> 0 mm");
}

BlanchingSignal compute_blanching(const PhaseAverage& baseline, const PhaseAverage& worn, const InverseMap& inverse,
                                  const BlanchingOptions& options, const InverseMap* baseline_inverse) {
  options.validate();
  BlanchingSignal s;
  const ChartGrid g = grid_of(inverse);
  const InverseMap& base_inv = baseline_inverse ? *baseline_inverse : inverse;
  if (base_inv.width != inverse.width || base_inv.height != inverse.height || base_inv.uv_origin != inverse.uv_origin)
    throw std::invalid_argument("compute_blanching: the baseline's inverse map is on another chart grid");
  if (!options.log_transmittance_ratio.empty() && options.log_transmittance_ratio.size() != g.size())
    throw std::invalid_argument("compute_blanching: log_transmittance_ratio is not one value per texel");
  s.baseline_green = resample_to_chart(baseline, base_inv);
  s.worn_green = resample_to_chart(worn, inverse);
  // Variances of the two averages on the chart (same resampling).
  PhaseAverage base_var = baseline, worn_var = worn;
  base_var.mean = baseline.variance;
  worn_var.mean = worn.variance;
  const ChartField vb = resample_to_chart(base_var, base_inv), vw = resample_to_chart(worn_var, inverse);

  ChartField raw = empty_field(g), var = empty_field(g), var_n = empty_field(g);
  const std::vector<float> n_worn = texels_per_pixel(inverse), n_base = texels_per_pixel(base_inv);
  s.plain_difference = empty_field(g);
  constexpr float kDark = 1e-4f;  // linear green below this carries no usable ratio
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (!options.excluded.empty() && options.excluded[k]) continue;  // glare: unseen, not 0
    const float G = s.worn_green.value[k], G0 = s.baseline_green.value[k];
    if (!(std::isfinite(G) && std::isfinite(G0)) || G < kDark || G0 < kDark) continue;
    raw.value[k] = std::log(G / G0);
    if (!options.log_transmittance_ratio.empty()) {
      if (!std::isfinite(options.log_transmittance_ratio[k])) {
        raw.value[k] = kNaN;
        continue;
      }
      raw.value[k] -= options.log_transmittance_ratio[k];
    }
    const float rel_w = std::max(0.f, vw.value[k]) / (G * G), rel_b = std::max(0.f, vb.value[k]) / (G0 * G0);
    var.value[k] = rel_w + rel_b;
    var_n.value[k] = rel_w * n_worn[k] + rel_b * n_base[k];
    s.plain_difference.value[k] = static_cast<float>(255.0 * (srgb::from_linear(G) - srgb::from_linear(G0)));
    ++s.texels_seen;
  }
  if (s.texels_seen == 0)
    throw InputError("", "captures", "no chart texel is seen in both averages (the captures are black there, or the map sees nothing)",
                     "check the exposure and that the camera and pose match the captures");

  if (options.ratio_of_smoothed) {
    // Both greens averaged over the same texels (raw's), then their ratio; T and V ratios stay divided out.
    ChartField gw = empty_field(g), gb = empty_field(g);
    for (std::size_t k = 0; k < g.size(); ++k)
      if (std::isfinite(raw.value[k])) {
        gb.value[k] = s.baseline_green.value[k];
        gw.value[k] = gb.value[k] * std::exp(raw.value[k]);
      }
    const ChartField sw = smooth_field(gw, options.smoothing_mm), sb = smooth_field(gb, options.smoothing_mm);
    s.y = empty_field(g);
    for (std::size_t k = 0; k < g.size(); ++k)
      if (std::isfinite(raw.value[k]) && sw.value[k] > 0 && sb.value[k] > 0) s.y.value[k] = std::log(sw.value[k] / sb.value[k]);
  } else {
    s.y = smooth_field(raw, options.smoothing_mm);
  }
  // The reference on the feature itself (after smoothing, which is not linear when ratio_of_smoothed).
  apply_reference(s, options);
  // Noise after smoothing: the independent camera pixels inside each texel's kernel (smoothed_sigma).
  s.sigma_y = smoothed_sigma(var, var_n, options.smoothing_mm);
  std::vector<double> sig;
  for (float v : s.sigma_y.value)
    if (std::isfinite(v)) sig.push_back(v);
  s.noise_sigma = s.temporal_noise_sigma = median(std::move(sig));
  if (options.spatial_noise) {
    ChartField unit = empty_field(g), unit_n = empty_field(g);
    for (std::size_t k = 0; k < g.size(); ++k)
      if (std::isfinite(var.value[k])) unit.value[k] = 1.f, unit_n.value[k] = 0.5f * (n_worn[k] + n_base[k]);
    add_spatial_noise(s, smoothed_sigma(unit, unit_n, options.smoothing_mm));
  }
  if (options.local_spatial_noise) add_local_spatial_noise(s, options.local_noise_window_mm);
  long long above = 0;
  for (std::size_t k = 0; k < g.size(); ++k)
    if (std::isfinite(s.y.value[k]) && s.y.value[k] > 3 * std::max(s.sigma_y.value[k], 1e-6f)) ++above;
  if (!options.reference_uv_mm && above > s.texels_seen * 0.4)
    s.warnings.push_back("blanching covers " + std::to_string(100 * above / s.texels_seen) +
                         " % of the seen skin, so the automatic reference (the unpressed majority) may be pressed too: "
                         "give assess.reference_uv_mm on skin that is surely not pressed");
  return s;
}

}  // namespace clearfit
