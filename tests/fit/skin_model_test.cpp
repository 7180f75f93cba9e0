// The skin forward model against closed forms: steady-state feature vs the
// calibration's logistic, lag time constants, pulse, ridge period (2D FFT).
#include <clearfit/fit/skin_model.hpp>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cmath>

namespace clearfit {

TEST(SkinModel, DefaultsAndPresetsValidate) {
  SkinParameters p;
  EXPECT_NO_THROW(p.validate());
  for (const char* t : {"light", "medium", "dark"}) {
    p.tone = SkinTone::preset(t);
    EXPECT_NO_THROW(p.validate()) << t;
  }
  EXPECT_NEAR(SkinTone::preset("light").reflectance[1], 0.41, 1e-12);
  EXPECT_NEAR(SkinTone::preset("medium").reflectance[1], 0.33, 1e-12);
  EXPECT_NEAR(SkinTone::preset("dark").reflectance[1], 0.11, 1e-12);
  EXPECT_THROW(SkinTone::preset("green"), std::invalid_argument);
  p.beta = 1.5;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

TEST(SkinModel, SteadyFeatureIsTheCalibrationLogistic) {
  SkinParameters p;
  p.s50_kpa = 9;
  p.width_kpa = 1.7;
  p.beta = 0.8;
  const EquivalentCalibration cal = equivalent_calibration(p);
  const double s0 = 1 / (1 + std::exp(9 / 1.7));  // σ(−p50/w)
  for (double kpa : {0.0, 2.0, 5.5, 9.0, 15.0, 40.0}) {
    const double y = std::log(radiance_factor(p, steady_blood_loss(p, kpa), 0)[1] / radiance_factor(p, 0, 0)[1]);
    const double psi = (1 / (1 + std::exp(-(kpa - 9) / 1.7)) - s0) / (1 - s0);
    EXPECT_NEAR(y, cal.y_max * psi, 1e-12) << kpa;
  }
  EXPECT_NEAR(cal.y_max, 0.06 * 0.8, 1e-15);
  EXPECT_EQ(normalized_logistic(0, 9, 1.7), 0.0);
  EXPECT_NEAR(normalized_logistic(200, 9, 1.7), 1.0, 1e-12);
  // Full blanching at the default k_G brightens green by exp(0.06·β) − 1 ≈ 5 %.
  EXPECT_NEAR(radiance_factor(SkinParameters{}, 0.85, 0)[1] - 1, std::exp(0.06 * 0.85) - 1, 1e-12);
}

TEST(SkinModel, LagReachesOneTimeConstant) {
  SkinParameters p;
  double b = 0, t = 0;
  const double dt = 1e-3;
  while (b < 0.7 * (1 - std::exp(-1.0))) b = lag_step(p, b, 0.7, dt), t += dt;
  EXPECT_NEAR(t, p.tau_on_s, 2 * dt);
  t = 0;
  b = 0.7;
  while (b > 0.7 * std::exp(-1.0)) b = lag_step(p, b, 0.0, dt), t += dt;
  EXPECT_NEAR(t, p.tau_off_s, 2 * dt);
  // Exact for a constant target: one big step equals many small ones.
  double b1 = 0.1, b2 = 0.1;
  for (int i = 0; i < 100; ++i) b1 = lag_step(p, b1, 0.5, 0.01);
  b2 = lag_step(p, b2, 0.5, 1.0);
  EXPECT_NEAR(b1, b2, 1e-12);
}

TEST(SkinModel, PulseIsZeroMeanUnitPeakPeriodic) {
  double sum = 0, peak = 0;
  const int n = 10000;
  const double hz = 1.3;
  for (int i = 0; i < n; ++i) {
    const double g = pulse_waveform(i / (n * hz), hz);
    sum += g;
    peak = std::max(peak, std::abs(g));
    EXPECT_NEAR(g, pulse_waveform(i / (n * hz) + 1 / hz, hz), 1e-9);
  }
  EXPECT_NEAR(sum / n, 0, 1e-9);
  EXPECT_NEAR(peak, 1, 1e-3);
}

namespace {
// Dominant spatial period (mm) of a texture term over a square of `n` samples every `h` mm (2D DFT).
template <class F>
double dominant_period_mm(F f, int n, double h) {
  cv::Mat img(n, n, CV_32F);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) img.at<float>(j, i) = static_cast<float>(f(Vec2(i * h, j * h)));
  img -= cv::mean(img)[0];
  cv::Mat spec;
  cv::dft(img, spec, cv::DFT_COMPLEX_OUTPUT);
  double best = 0, period = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const cv::Vec2f c = spec.at<cv::Vec2f>(j, i);
      const double m = c[0] * c[0] + c[1] * c[1];
      const int fi = i <= n / 2 ? i : i - n, fj = j <= n / 2 ? j : j - n;
      if (m > best && (fi || fj)) best = m, period = n * h / std::hypot(fi, fj);
    }
  return period;
}
}  // namespace

TEST(SkinTexture, RidgePeriodFromTheSpectrum) {
  SkinParameters p;
  p.ridge_warp_mm = 0;  // straight ridges: the spectrum peaks at exactly 1/period
  for (unsigned seed : {1u, 7u}) {
    p.texture_seed = seed;
    const SkinTexture tex(p);
    std::printf("seed %u: straight ridges, period %.4f mm\n", seed, dominant_period_mm([&](const Vec2& uv) { return tex.ridge(uv); }, 256, 0.04));
    EXPECT_NEAR(dominant_period_mm([&](const Vec2& uv) { return tex.ridge(uv); }, 256, 0.04), 0.31, 0.02) << seed;
  }
  p.ridge_warp_mm = 0.25;  // wavy ridges keep their period within the measured 0.28–0.33 mm
  const SkinTexture wavy(p);
  const double per = dominant_period_mm([&](const Vec2& uv) { return wavy.ridge(uv); }, 256, 0.04);
  EXPECT_GE(per, 0.28);
  EXPECT_LE(per, 0.33);
}

TEST(SkinTexture, MottlingHasUnitSpreadAndModulationMeanOne) {
  const SkinParameters p;
  const SkinTexture tex(p);
  double s = 0, s2 = 0, m = 0;
  int n = 0;
  for (double y = 0; y < 40; y += 0.1)
    for (double x = 0; x < 40; x += 0.1, ++n) {
      const double v = tex.mottling({x, y});
      s += v, s2 += v * v, m += tex.modulation({x, y});
    }
  EXPECT_NEAR(s / n, 0, 0.15);
  EXPECT_NEAR(std::sqrt(s2 / n - (s / n) * (s / n)), 1, 0.2);
  EXPECT_NEAR(m / n, 1, 0.01);
}

TEST(SkinDrive, BlurKeepsAWideUniformPlateauAndMixesVonMises) {
  ChartField p;
  p.grid = ChartGrid::covering(Vec2(-5, -5), Vec2(5, 5), 0.05);
  p.value.resize(p.grid.size());
  for (int j = 0; j < p.grid.height; ++j)
    for (int i = 0; i < p.grid.width; ++i) p.value[p.grid.index(i, j)] = p.grid.uv(i, j).norm() < 3 ? 10.0f : 0.0f;
  SkinParameters sp;
  const ChartField d = skin_drive(sp, p);
  const int c = p.grid.width / 2;
  EXPECT_NEAR(d.value[p.grid.index(c, c)], 10.0, 1e-3);
  // At the edge of the disc the blur halves the step (a straight edge to first order).
  const int edge = static_cast<int>(std::lround((3.0 - p.grid.uv_origin.x()) / 0.05));
  EXPECT_NEAR(d.value[p.grid.index(edge, c)], 5.0, 0.6);
  sp.von_mises_weight = 1;
  const ChartField vm = skin_drive(sp, p);
  EXPECT_LT(vm.value[p.grid.index(c, c)], 2.0);            // uniform load: nearly hydrostatic under the centre
  EXPECT_GT(vm.value[p.grid.index(edge, c)], 4.0);         // shear at the edge of the loaded disc
}

}  // namespace clearfit
