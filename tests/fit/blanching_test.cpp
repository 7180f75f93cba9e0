// The blanching signal's options for phases seen through pixels of different footprints
// (fit/blanching.hpp: ratio_of_smoothed, local_spatial_noise), on hand-made averages with an
// identity inverse map, against closed forms.
#include <clearfit/fit/blanching.hpp>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <array>
#include <cmath>
#include <random>

namespace clearfit {
namespace {

constexpr int kW = 240, kH = 120;

InverseMap identity_map() {
  InverseMap inv;
  inv.width = kW, inv.height = kH, inv.texel_mm = 0.1;
  inv.map_x.resize(kW * kH), inv.map_y.resize(kW * kH);
  inv.valid.assign(kW * kH, 1);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i) inv.map_x[inv.index(i, j)] = static_cast<float>(i), inv.map_y[inv.index(i, j)] = static_cast<float>(j);
  return inv;
}

PhaseAverage average_of(const cv::Mat& mean, double temporal_sigma) {
  PhaseAverage a;
  a.roi = cv::Rect(0, 0, kW, kH);
  a.mean = mean.clone();
  a.variance = cv::Mat(mean.size(), CV_32F);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i) {
      const float g = mean.at<float>(j, i) * static_cast<float>(temporal_sigma);
      a.variance.at<float>(j, i) = g * g;
    }
  return a;
}

/// Skin texture: 0.3 × (1 + c·n), n independent per pixel with unit variance.
cv::Mat texture(double contrast, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  cv::Mat t(kH, kW, CV_32F);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i) t.at<float>(j, i) = 0.3f * (1 + static_cast<float>(contrast) * n(rng));
  return t;
}

double mean_over(const ChartField& f, int i0, int i1) {
  double s = 0;
  int n = 0;
  for (int j = 10; j < kH - 10; ++j)
    for (int i = i0; i < i1; ++i)
      if (const float v = f.value[f.grid.index(i, j)]; std::isfinite(v)) s += v, ++n;
  return s / n;
}

TEST(Blanching, RatioOfSmoothedGreensRemovesTheFootprintBias) {
  // The baseline's left half is seen through pixels that each average 3 × 3 of the texture (a
  // larger footprint), its right half and the whole worn capture through single ones. Nothing is
  // pressed. The log of a 3 × 3 mean is higher by about c²(1 − 1/9)/2 (Jensen, to second order),
  // so smoothing log ratios leaves a step of that size between the halves.
  const double c = 0.1;
  const cv::Mat skin = texture(c, 3);
  cv::Mat base = skin.clone(), blurred;
  cv::blur(skin, blurred, cv::Size(3, 3), cv::Point(-1, -1), cv::BORDER_REFLECT);
  blurred(cv::Rect(0, 0, kW / 2, kH)).copyTo(base(cv::Rect(0, 0, kW / 2, kH)));
  const PhaseAverage b = average_of(base, 1e-4), w = average_of(skin, 1e-4);
  const InverseMap inv = identity_map();
  BlanchingOptions o;
  o.smoothing_mm = 0.5;
  const BlanchingSignal logs = compute_blanching(b, w, inv, o);
  const double step_logs = mean_over(logs.y, 20, kW / 2 - 20) - mean_over(logs.y, kW / 2 + 20, kW - 20);
  const double jensen = -c * c * (1 - 1.0 / 9) / 2;
  std::printf("smoothed log ratios: step %.5f (Jensen %.5f)\n", step_logs, jensen);
  EXPECT_NEAR(step_logs, jensen, 0.3 * std::abs(jensen));

  o.ratio_of_smoothed = true;
  const BlanchingSignal ratio = compute_blanching(b, w, inv, o);
  const double step_ratio = mean_over(ratio.y, 20, kW / 2 - 20) - mean_over(ratio.y, kW / 2 + 20, kW - 20);
  std::printf("ratio of smoothed greens: step %.5f\n", step_ratio);
  EXPECT_LT(std::abs(step_ratio), 0.1 * std::abs(jensen));
}

TEST(Blanching, RatioOfSmoothedGreensKeepsAUniformPress) {
  // Same footprints in both phases, a press raising green by 3 % in a disc: both ways agree.
  const cv::Mat skin = texture(0.05, 4);
  cv::Mat worn = skin.clone();
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i)
      if (std::hypot(i - 60, j - 60) < 25) worn.at<float>(j, i) *= 1.03f;
  const InverseMap inv = identity_map();
  BlanchingOptions o;
  o.ratio_of_smoothed = true;
  const BlanchingSignal s = compute_blanching(average_of(skin, 1e-3), average_of(worn, 1e-3), inv, o);
  EXPECT_NEAR(s.y.value[s.y.grid.index(60, 60)], std::log(1.03), 0.002);
  EXPECT_NEAR(s.y.value[s.y.grid.index(180, 60)], 0.0, 0.002);
}

TEST(Blanching, LocalSpatialNoiseGrowsWhereTheTextureDoesNotCancelAndNotOnAPress) {
  // The worn capture's right third holds a texture residual (independent per pixel, 2 % of the
  // green: what differently aliased texture leaves); its left third a 4 % press. The frames' own
  // noise is 0.1 % in each phase (drawn, and declared in the variances).
  cv::Mat skin = texture(0.05, 5);
  cv::Mat worn = skin.clone();
  std::mt19937 rng(6);
  std::normal_distribution<float> n(0, 0.02f), frames(0, 1e-3f);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i) {
      worn.at<float>(j, i) *= 1 + frames(rng);
      skin.at<float>(j, i) *= 1 + frames(rng);
      if (i >= 2 * kW / 3) worn.at<float>(j, i) *= 1 + n(rng);
      if (std::hypot(i - 40, j - 60) < 20) worn.at<float>(j, i) *= 1.04f;
    }
  const InverseMap inv = identity_map();
  BlanchingOptions o;
  o.smoothing_mm = 0.3;
  const BlanchingSignal plain = compute_blanching(average_of(skin, 1e-3), average_of(worn, 1e-3), inv, o);
  o.local_spatial_noise = true;
  const BlanchingSignal local = compute_blanching(average_of(skin, 1e-3), average_of(worn, 1e-3), inv, o);
  // The residual after smoothing: 2 % over the Gaussian's 4πσ² = 113 pixels (σ = 3 texels).
  const double residual = 0.02 / std::sqrt(4 * M_PI * 9);
  const float on_residual = local.sigma_y.value[local.sigma_y.grid.index(200, 60)];
  const float on_press = local.sigma_y.value[local.sigma_y.grid.index(40, 60)];
  const float plain_press = plain.sigma_y.value[plain.sigma_y.grid.index(40, 60)];
  std::printf("sigma_y: residual %.5f (closed form %.5f, frames alone %.5f), press %.5f (frames alone %.5f), p95 %.5f\n", on_residual,
              residual, plain.sigma_y.value[plain.sigma_y.grid.index(200, 60)], on_press, plain_press, local.local_noise_sigma_p95);
  EXPECT_NEAR(on_residual, residual, 0.35 * residual);
  EXPECT_LT(on_press, 1.5 * plain_press + 0.2 * residual);
  EXPECT_GT(local.local_noise_sigma_p95, 0.5 * residual);
  BlanchingOptions bad;
  bad.local_spatial_noise = true;
  bad.local_noise_window_mm = 0;
  EXPECT_THROW(compute_blanching(average_of(skin, 1e-3), average_of(worn, 1e-3), inv, bad), std::invalid_argument);
}

TEST(Blanching, SigmaHoldsAtTheEdgeOfTheSeenSkinAndWhereTheMapIsSteep) {
  // Independent pixel noise (0.1 % of the green in each phase, declared in the variances), nothing
  // pressed, against the spread of y over 200 draws, pooled over three texels (20 apart, 4 kernel σ) in
  // each of: the seen skin inside (one texel a pixel), a strip 3 texels high between masked texels (an
  // edge on both sides: the smoothing kernel holds a tenth of its texels) and a map 3 texels a camera
  // pixel along u (the contact surface seen obliquely: a kernel holds a third of the pixels).
  InverseMap inv = identity_map();
  for (int j = 0; j < kH; ++j)
    for (int i = 160; i < kW; ++i) inv.map_x[inv.index(i, j)] = 160.f + static_cast<float>(i - 160) / 3;
  BlanchingOptions o;
  o.smoothing_mm = 0.5;
  o.excluded.assign(kW * kH, 0);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < 80; ++i) o.excluded[inv.index(i, j)] = j < 59 || j > 61;
  const std::array<std::array<std::pair<int, int>, 3>, 3> at{{{{{100, 30}, {120, 60}, {140, 90}}},
                                                               {{{20, 60}, {40, 60}, {60, 60}}},
                                                               {{{185, 30}, {200, 60}, {215, 90}}}}};
  const char* names[] = {"inside", "strip", "steep"};
  for (bool ratio : {false, true}) {
    o.ratio_of_smoothed = ratio;
    constexpr int kDraws = 200;
    constexpr double kNoise = 1e-3;
    std::mt19937 rng(7);
    std::normal_distribution<float> n(0, static_cast<float>(kNoise));
    double sum[3][3] = {}, sum2[3][3] = {};
    BlanchingSignal s;
    for (int d = 0; d < kDraws; ++d) {
      cv::Mat base(kH, kW, CV_32F), worn(kH, kW, CV_32F);
      for (int j = 0; j < kH; ++j)
        for (int i = 0; i < kW; ++i) base.at<float>(j, i) = 0.3f * (1 + n(rng)), worn.at<float>(j, i) = 0.3f * (1 + n(rng));
      s = compute_blanching(average_of(base, kNoise), average_of(worn, kNoise), inv, o);
      for (int r = 0; r < 3; ++r)
        for (int t = 0; t < 3; ++t) {
          const double y = s.y.value[inv.index(at[r][t].first, at[r][t].second)];
          sum[r][t] += y, sum2[r][t] += y * y;
        }
    }
    for (int r = 0; r < 3; ++r) {
      double spread2 = 0, sigma2 = 0;
      for (int t = 0; t < 3; ++t) {
        const double m = sum[r][t] / kDraws, sigma = s.sigma_y.value[inv.index(at[r][t].first, at[r][t].second)];
        spread2 += sum2[r][t] / kDraws - m * m, sigma2 += sigma * sigma;
      }
      const double ratio_to_spread = std::sqrt(sigma2 / spread2);
      std::printf("%s%s: sigma_y %.6f, spread of %d draws %.6f (ratio %.3f)\n", ratio ? "ratio of smoothed, " : "", names[r],
                  std::sqrt(sigma2 / 3), kDraws, std::sqrt(spread2 / 3), ratio_to_spread);
      EXPECT_NEAR(ratio_to_spread, 1.0, 0.12) << names[r];
    }
  }
}

}  // namespace
}  // namespace clearfit
