// The assessment's stages (fit/assessment_stages.hpp) on hand-made inputs, against closed forms: the
// checks that refuse or warn about captures at their thresholds, the pose's and the camera model's
// position σ, the projection uncertainty over the seen contact surface and its warning, the blur's
// first-order effect on a paraboloid and a Gaussian place, the deblur's noise gain, the signal's σ in quadrature, the centres' position term and the
// pressure through a linear calibration with its detection gate; the deblur's residual on a Gaussian place and the
// logistic's curvature residual on a ramp.
#include <clearfit/error.hpp>
#include <clearfit/fit/assessment_stages.hpp>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace clearfit {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

ChartGrid grid(int w, int h, double texel_mm) {
  ChartGrid g;
  g.width = w, g.height = h, g.texel_mm = texel_mm;
  return g;
}

ChartField constant(const ChartGrid& g, float v) { return {g, std::vector<float>(g.size(), v)}; }

/// y = a·u + b·v (+ c·(u² + v²)) at the texels' chart coordinates (mm, origin at texel (0, 0)).
ChartField field(const ChartGrid& g, double a, double b, double c = 0) {
  ChartField f = constant(g, 0.f);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const double u = i * g.texel_mm, v = j * g.texel_mm;
      f.value[g.index(i, j)] = static_cast<float>(a * u + b * v + c * (u * u + v * v));
    }
  return f;
}

bool contains(const std::vector<std::string>& warnings, const std::string& text) {
  return std::any_of(warnings.begin(), warnings.end(), [&](const std::string& w) { return w.find(text) != std::string::npos; });
}

// ---- Checks on the captures ----

TEST(AssessmentStages, ExposureIsRefusedJustBeyondItsThresholdsAndGlareExcusesItsSaturation) {
  AssessmentOptions o;  // at most 2 % saturated, mean green code at least 10
  PhaseAverage avg;
  avg.window = {40, 20};
  avg.mean_code = 100;
  avg.saturated_fraction = 0.019;
  EXPECT_NO_THROW(check_exposure(avg, "worn.mkv", "worn", o, 0.0));
  avg.saturated_fraction = 0.021;
  try {
    check_exposure(avg, "worn.mkv", "worn", o, 0.0);
    ADD_FAILURE() << "2.1 % saturated was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "worn.mkv");
    EXPECT_EQ(e.element(), "frames 40..59");  // the window, first to last frame
    EXPECT_NE(std::string(e.what()).find("2.1 %"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(check_exposure(avg, "worn.mkv", "worn", o, 0.002));  // 2.1 % ≤ 2 % + 0.2 % glare
  avg.saturated_fraction = 0;
  avg.mean_code = 9.9;
  EXPECT_THROW(check_exposure(avg, "base.mkv", "baseline", o, 0.0), InputError);
  avg.mean_code = 10.0;
  EXPECT_NO_THROW(check_exposure(avg, "base.mkv", "baseline", o, 0.0));
}

TEST(AssessmentStages, GainsWarnBeyondTwoPercentSpanOrAFifthOfAPercentSigma) {
  PhaseReport p;
  std::vector<std::string> w;
  p.gain_min = 0.99, p.gain_max = 0.99 * 1.019, p.gain_sigma = 0.0019;
  warn_gains(p, "worn", w);
  EXPECT_TRUE(w.empty());
  p.gain_max = 0.99 * 1.03;
  warn_gains(p, "worn", w);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("changed by 3.0 % during the worn window"), std::string::npos) << w[0];
  w.clear();
  p.gain_max = p.gain_min, p.gain_sigma = 0.0031;
  warn_gains(p, "baseline", w);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("known to 0.31 % only"), std::string::npos) << w[0];
}

TEST(AssessmentStages, MostlyGlareIsRefusedNamingTheWorsePhase) {
  GlareOptions o;  // at most half the seen skin
  GlareMask g;
  PhaseReport base, worn;
  base.source = "base.mkv", worn.source = "worn.mkv";
  std::vector<std::string> w;
  g.fraction = 0.1, g.fraction_baseline = 0.6, g.fraction_worn = 0.2;
  try {
    check_glare(g, base, worn, o, w);
    ADD_FAILURE() << "60 % glare was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "base.mkv");
    EXPECT_NE(std::string(e.what()).find("60.0 %"), std::string::npos) << e.what();
  }
  g.fraction_baseline = 0.05, g.regions = 2;
  check_glare(g, base, worn, o, w);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("2 specular highlights masked (10.0 %"), std::string::npos) << w[0];
  // The highlights with the fixed margin are weighed, not the tails of large ones (masked all the same).
  g.fraction = 0.55, g.fraction_glare = 0.45;
  EXPECT_NO_THROW(check_glare(g, base, worn, o, w));
  g.fraction_glare = 0.52;
  EXPECT_THROW(check_glare(g, base, worn, o, w), InputError);
}

// ---- Where on the skin each texel lies ----

TEST(AssessmentStages, PoseSigmaAcrossTheLineOfSightIsTranslationAndRotationTimesDistance) {
  // With cam_from_part's translation 0, a rotation error δθ moves p by δθ × p, always across the line of
  // sight: isotropic σ_r gives σ_r·|p| per lateral axis; an isotropic translation σ_t gives σ_t per
  // lateral axis (its part along the ray is dropped). Together: √(σ_t² + σ_r²·|p|²).
  const double sr = 0.002, st = 0.05;  // rad, mm
  PoseCovariance c = PoseCovariance::Zero();
  c.diagonal() << sr * sr, sr * sr, sr * sr, st * st, st * st, st * st;
  ChartRaster raster;
  raster.grid = grid(3, 1, 0.1);
  raster.face = {0, -1, 2};
  const Vec3 nan3 = Vec3::Constant(std::nan(""));
  raster.point = {Vec3(10, 0, 100), nan3, Vec3(-30, 20, 60)};
  raster.area_mm2 = {0.01f, 0.f, 0.01f};
  Rigid3 cam_from_part;  // a turn about the optical axis keeps every |p| and t = 0
  cam_from_part.rotation = Eigen::AngleAxisd(0.7, Vec3::UnitZ()).toRotationMatrix();
  const ChartField s = position_sigma(raster, cam_from_part, c);
  for (int k : {0, 2})
    EXPECT_NEAR(s.value[k], std::sqrt(st * st + sr * sr * raster.point[k].squaredNorm()), 1e-6) << k;
  EXPECT_TRUE(std::isnan(s.value[1]));
  // Translation along the optical axis only: nothing across an on-axis ray, σ_t·sin(angle) off axis.
  c.setZero();
  c(5, 5) = st * st;
  raster.point = {Vec3(0, 0, 100), nan3, Vec3(60, 0, 80)};
  const ChartField z = position_sigma(raster, Rigid3{}, c);
  EXPECT_NEAR(z.value[0], 0.0, 1e-9);
  EXPECT_NEAR(z.value[2], st * 0.6 / std::sqrt(2.0), 1e-6);  // |δt × û| = σ_t·0.6 on one axis, halved over two
}

/// A texel → pixel map that is affine: pixel = (x0 + kx·u + s·v, y0 + ky·v) with u, v in mm.
InverseMap affine_map(int w, int h, double texel_mm, double kx, double ky, double s, double x0, double y0) {
  InverseMap inv;
  inv.width = w, inv.height = h, inv.texel_mm = texel_mm;
  inv.map_x.resize(static_cast<std::size_t>(w) * h), inv.map_y.resize(inv.map_x.size());
  inv.valid.assign(inv.map_x.size(), 1);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const double u = i * texel_mm, v = j * texel_mm;
      inv.map_x[inv.index(i, j)] = static_cast<float>(x0 + kx * u + s * v);
      inv.map_y[inv.index(i, j)] = static_cast<float>(y0 + ky * v);
    }
  return inv;
}

/// σ_q of a model with two cells side by side over a W-pixel-wide imager: `left` at the left cell's centre
/// (W/4 − 0.5), `right` at the right one's (3W/4 − 0.5), linear between, constant beyond.
double two_cell_sigma(double x, double width, double left, double right) {
  const double t = std::clamp(((x + 0.5) * 2 / width - 0.5), 0.0, 1.0);
  return left + t * (right - left);
}

TEST(AssessmentStages, IntrinsicsTermIsSigmaThroughTheInverseOfTheMapsJacobian) {
  // pixel = (x0 + kx·u + s·v, y0 + ky·v): J = [[kx, s], [0, ky]], A = J⁻¹ = [[1/kx, −s/(kx·ky)], [0, 1/ky]],
  // ‖A‖_F² = 1/kx² + s²/(kx·ky)² + 1/ky²; y = a·u + b·v: Aᵀ∇y = (a/kx, −s·a/(kx·ky) + b/ky).
  const double kx = 8, ky = 5, s = 2, a = 0.03, b = -0.01;
  const int W = 400, H = 300;
  const ProjectionUncertainty u{2, 1, 100.0, {0.2, 1.0}, ProjectionUncertainty::Layout::cells};
  const InverseMap inv = affine_map(40, 30, 0.25, kx, ky, s, 60, 80);
  ChartField y = field(grid(40, 30, 0.25), a, b);
  y.value[y.grid.index(10, 10)] = kNaN;  // unseen: no signal term there, and one-sided differences beside it
  InverseMap holed = inv;
  holed.valid[inv.index(20, 15)] = 0;  // no pixel: nothing there, one-sided differences beside it
  const IntrinsicsTerm t = intrinsics_term(holed, y, u, W, H);
  const double norm_a = std::sqrt(1 / (kx * kx) + s * s / (kx * kx * ky * ky) + 1 / (ky * ky));
  const double at_y = std::hypot(a / kx, -s * a / (kx * ky) + b / ky);
  int checked = 0;
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 40; ++i) {
      const auto k = y.grid.index(i, j);
      if (i == 20 && j == 15) {
        EXPECT_TRUE(std::isnan(t.pixel_sigma_px.value[k]) && std::isnan(t.position_mm.value[k]));
        continue;
      }
      const double q = two_cell_sigma(inv.map_x[k], W, 0.2, 1.0);
      ASSERT_NEAR(t.pixel_sigma_px.value[k], q, 1e-5) << i << "," << j;
      ASSERT_NEAR(t.position_mm.value[k], q * norm_a / std::sqrt(2.0), 1e-4 * q * norm_a) << i << "," << j;
      if (i == 10 && j == 10)
        EXPECT_TRUE(std::isnan(t.signal.value[k]));
      else
        ASSERT_NEAR(t.signal.value[k], q * at_y, 2e-4 * q * at_y) << i << "," << j;
      ++checked;
    }
  EXPECT_EQ(checked, 40 * 30 - 1);
}

TEST(AssessmentStages, ProjectionSigmaOverTheSeenContactWarnsWhereTheCalibrationDidNotReach) {
  // The part's pixels run from x = 60 to 60 + 8·(39·0.25) = 138 px of a 200 px wide imager whose right
  // cell is unsure: σ_q rises linearly from 0.1 px (x ≤ 49.5) to 3 px (x ≥ 149.5). Only columns i < 30 are
  // seen (the signal is defined there), so the largest σ_q is at column 29, x = 60 + 8·29·0.25 = 118.
  const int W = 200, H = 100;
  const ProjectionUncertainty u{2, 1, 100.0, {0.1, 3.0}, ProjectionUncertainty::Layout::cells};
  const InverseMap inv = affine_map(40, 10, 0.25, 8, 8, 0, 60, 30);
  ChartField y = field(grid(40, 10, 0.25), 0.01, 0);
  for (int j = 0; j < 10; ++j)
    for (int i = 30; i < 40; ++i) y.value[y.grid.index(i, j)] = kNaN;
  const IntrinsicsTerm t = intrinsics_term(inv, y, u, W, H);
  const double threshold = 1.5;
  const ProjectionSigmaOnContact s = projection_sigma_on_contact(t, y, inv, threshold);
  const double largest = two_cell_sigma(118, W, 0.1, 3.0);
  EXPECT_EQ(s.texels, 300);
  EXPECT_NEAR(s.largest_px, largest, 1e-5);
  EXPECT_NEAR(s.largest_at_px.x(), 118, 1e-4);
  EXPECT_NEAR(s.position_mm, largest / 8, 1e-5);  // A = I/8 mm per px: σ_q·‖A‖_F/√2 = σ_q/8
  // Above 1.5 px where x > (1.4/2.9 + 0.5)·100 − 0.5 = 97.78: columns x = 60 + 2i > 97.78, i ≥ 19, 11 of 30.
  EXPECT_NEAR(s.fraction_above, 11.0 / 30, 1e-12);
  EXPECT_NEAR(s.median_px, two_cell_sigma(60 + 2 * 15, W, 0.1, 3.0), 1e-5);  // 300 values: the 151st, column 15
  std::vector<std::string> w;
  warn_projection_sigma(s, w);
  ASSERT_EQ(w.size(), 1u);
  char figure[64];
  std::snprintf(figure, sizeof figure, "reaches %.2f px at pixel (118, ", largest);
  EXPECT_NE(w[0].find(figure), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("36.7 % of it above 1.50 px"), std::string::npos) << w[0];
  EXPECT_NE(w[0].find("calibrate again"), std::string::npos) << w[0];
  // Above the largest σ_q, or without the term: no warning.
  w.clear();
  warn_projection_sigma(projection_sigma_on_contact(t, y, inv, largest + 0.01), w);
  warn_projection_sigma(projection_sigma_on_contact(IntrinsicsTerm{}, y, inv, 0.0), w);
  EXPECT_TRUE(w.empty());
}

TEST(AssessmentStages, PositionSigmasAddInQuadratureAndOnTheCentres) {
  const ChartGrid g = grid(4, 1, 0.1);
  const ChartField pose{g, {0.3f, kNaN, 0.3f, kNaN}}, intr{g, {0.4f, 0.2f, kNaN, kNaN}};
  const ChartField both = position_sigma_total(pose, intr);
  EXPECT_NEAR(both.value[0], 0.5, 1e-6);
  EXPECT_NEAR(both.value[1], 0.2, 1e-6);
  EXPECT_NEAR(both.value[2], 0.3, 1e-6);
  EXPECT_TRUE(std::isnan(both.value[3]));
  const ChartField alone = position_sigma_total(pose, ChartField{});  // without the intrinsics: the pose's
  EXPECT_EQ(alone.value[0], 0.3f);
  EXPECT_TRUE(std::isnan(alone.value[1]));
  // A place over texels of σ 1, 1, 2 and one without: mean σ² = 2, two axes: 0.1² + 2·2.
  std::vector<Hotspot> h(2);
  h[0].id = 1, h[0].centre_of_pressure_sigma_mm = 0.1, h[0].centroid_sigma_mm = 0.2;
  h[1].id = 2, h[1].centre_of_pressure_sigma_mm = std::nan(""), h[1].centroid_sigma_mm = std::nan("");
  const ChartGrid g5 = grid(5, 1, 0.1);
  add_position_to_centres(h, {1, 1, 1, 1, 2}, ChartField{g5, {1.f, 1.f, 2.f, kNaN, 5.f}});
  EXPECT_NEAR(h[0].centre_of_pressure_sigma_mm, std::sqrt(0.01 + 2 * 2.0), 1e-9);
  EXPECT_NEAR(h[0].centroid_sigma_mm, std::sqrt(0.04 + 2 * 2.0), 1e-9);
  EXPECT_TRUE(std::isnan(h[1].centre_of_pressure_sigma_mm));
  EXPECT_TRUE(std::isnan(h[1].centroid_sigma_mm));
}

// ---- The blur's first-order effect and the signal's σ ----

TEST(AssessmentStages, BlurEffectOfAParaboloidIsHalfTheBlurSquaredTimesItsLaplacian) {
  // y = c·(u² + v²): ∇²y = 4c everywhere, and a normalised Gaussian keeps a quadratic's Laplacian, so far
  // from the grid's edge the effect is ½·(skin_blur² + smoothing²)·4c.
  const double c = 0.05, texel = 0.1;
  const ChartGrid g = grid(80, 80, texel);
  BlanchingSignal s;
  s.y = field(g, 0, 0, c);
  s.y.value[g.index(60, 60)] = kNaN;
  BlanchingOptions o;
  o.skin_blur_mm = 0.3, o.smoothing_mm = 0.25, o.curvature_smoothing_mm = 0.5;
  const ChartField e = blur_effect(s, o);
  const double expected = 0.5 * (0.3 * 0.3 + 0.25 * 0.25) * 4 * c;
  for (int j = 22; j < 40; ++j)
    for (int i = 22; i < 40; ++i) ASSERT_NEAR(e.value[g.index(i, j)], expected, 0.01 * expected) << i << "," << j;
  for (auto [i, j] : {std::pair{60, 60}, {61, 60}, {59, 60}, {60, 61}, {60, 59}, {0, 30}, {79, 30}})
    EXPECT_EQ(e.value[g.index(i, j)], 0.f) << i << "," << j;  // an unseen neighbour, or the grid's edge
  const ChartField sharp = sharpened_signal(s.y, e);
  EXPECT_NEAR(sharp.value[g.index(30, 30)], s.y.value[g.index(30, 30)] - expected, 0.01 * expected);
  EXPECT_TRUE(std::isnan(sharp.value[g.index(60, 60)]));
}

TEST(AssessmentStages, DeblurOfAGaussianPlaceKeepsMostOfItsFirstOrderTermWithABoundedNoiseGain) {
  // A Gaussian place of σ0 = 1.5 mm (the SigmaCoverage scene's 10 kPa place): each Gaussian of the difference keeps
  // its peak's fraction σ0² / (σ0² + c²), so the deblur adds β²·A·(2/(σ0² + c²) − 1/(σ0² + 2c²)) at the peak, 86 % of
  // the first order's β²·A/σ0² at c = 1 mm (a Laplacian of y smoothed 1 mm: 48 %).
  const double texel = 0.05, s0 = 1.5, amp = 0.03, c = 1.0;
  const ChartGrid g = grid(301, 301, texel);
  BlanchingSignal s;
  s.y = constant(g, 0.f);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const double u = (i - 150) * texel, v = (j - 150) * texel;
      s.y.value[g.index(i, j)] = static_cast<float>(amp * std::exp(-(u * u + v * v) / (2 * s0 * s0)));
    }
  BlanchingOptions o;
  o.skin_blur_mm = 0.3, o.smoothing_mm = 0.25, o.curvature_smoothing_mm = c;
  const double b2 = 0.3 * 0.3 + 0.25 * 0.25;
  const double expected = -b2 * amp * (2 / (s0 * s0 + c * c) - 1 / (s0 * s0 + 2 * c * c));
  EXPECT_NEAR(blur_effect(s, o).value[g.index(150, 150)], expected, 0.01 * std::abs(expected));
  EXPECT_NEAR(expected / (-b2 * amp / (s0 * s0)), 0.855, 0.005);
  // The noise gain: white noise smoothed by smoothing_mm, through the deblur; its σ over the interior against the closed form.
  std::mt19937 rng(7);
  std::normal_distribution<float> normal(0.f, 1.f);
  BlanchingSignal n;
  n.y = constant(g, 0.f);
  for (float& x : n.y.value) x = normal(rng);
  n.y = smooth_field(n.y, o.smoothing_mm);
  const ChartField e = blur_effect(n, o);
  double s_in = 0, s_out = 0;
  long long count = 0;
  for (int j = 70; j < 231; ++j)
    for (int i = 70; i < 231; ++i) {
      const auto k = g.index(i, j);
      s_in += n.y.value[k] * n.y.value[k], s_out += std::pow(n.y.value[k] - e.value[k], 2), ++count;
    }
  const double gain = deblur_noise_gain(o, texel);
  EXPECT_NEAR(gain, 1.20, 0.01);
  EXPECT_NEAR(std::sqrt(s_out / s_in), gain, 0.03);
  EXPECT_LT(gain, 1 + 1.5 * b2 / (c * c));  // the gain on white noise, its bound
}

TEST(AssessmentStages, SignalSigmaIsNoiseBlurIntrinsicsAndGradientTimesPositionInQuadrature) {
  // y = a·u + b·v with a constant blur effect: the sharpened signal has the same gradient |(a, b)|.
  const double a = 0.02, b = 0.015, noise = 0.001, blur = 0.0007, intr = 0.0004, pos = 0.05;
  const ChartGrid g = grid(12, 9, 0.2);
  BlanchingSignal s;
  s.y = field(g, a, b);
  s.y.value[g.index(5, 4)] = kNaN;
  s.sigma_y = constant(g, static_cast<float>(noise));
  s.sigma_y.value[g.index(5, 4)] = kNaN;
  const ChartField blur_f = constant(g, static_cast<float>(blur)), intr_f = constant(g, static_cast<float>(intr));
  const ChartField with = signal_sigma(s, constant(g, static_cast<float>(pos)), intr_f, blur_f);
  const ChartField without = signal_sigma(s, ChartField{}, intr_f, blur_f);
  const ChartField gained = signal_sigma(s, ChartField{}, intr_f, blur_f, 1.2);  // the deblur's noise gain: on the noise only
  const double grad = std::hypot(a, b);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (i == 5 && j == 4) {
        EXPECT_TRUE(std::isnan(with.value[k]));
        continue;
      }
      ASSERT_NEAR(without.value[k], std::sqrt(noise * noise + blur * blur + intr * intr), 1e-8);
      ASSERT_NEAR(gained.value[k], std::sqrt(1.44 * noise * noise + blur * blur + intr * intr), 1e-8);
      ASSERT_NEAR(with.value[k], std::sqrt(noise * noise + blur * blur + intr * intr + grad * grad * pos * pos), 1e-6) << i << "," << j;
    }
}

// ---- Pressure through the calibration ----

/// y = 0.01·p (kPa), calibrated over 0..30 kPa, noise 0.001.
PressureCalibration linear_calibration() {
  PressureCalibration cal;
  cal.model = PressureModelKind::linear;
  cal.intercept = 0, cal.slope_per_kpa = 0.01, cal.noise_sigma = 0.001;
  cal.p_min_kpa = 0, cal.p_max_kpa = 30;
  cal.person = "p";
  return cal;
}

TEST(AssessmentStages, DeblurResidualOfAGaussianPlaceIsMostOfWhatTheDeblurMisses) {
  // y0 a Gaussian place of σ0 = 1.5 mm, y = G_β∗y0 (a Gaussian of σ0² + β²) read through the deblur: it misses
  // y0 − y' (1.2 % of the peak at c = 1 mm), and the residual read on y' alone is 93 % of that at the peak
  // (95 % over the place within σ0; 81 % at the peak for σ0 = 1 mm, 97 % for 2 mm: the noise-free model,
  // scripts/deblur-bias.py).
  const double texel = 0.05, s0 = 1.5, amp = 0.03;
  const ChartGrid g = grid(301, 301, texel);
  BlanchingOptions o;
  o.skin_blur_mm = 0.3, o.smoothing_mm = 0.25, o.curvature_smoothing_mm = 1.0;
  const double b2 = 0.3 * 0.3 + 0.25 * 0.25, sy2 = s0 * s0 + b2;
  BlanchingSignal s;
  s.y = constant(g, 0.f);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const double u = (i - 150) * texel, v = (j - 150) * texel;
      s.y.value[g.index(i, j)] = static_cast<float>(amp * s0 * s0 / sy2 * std::exp(-(u * u + v * v) / (2 * sy2)));
    }
  const ChartField sharp = sharpened_signal(s.y, blur_effect(s, o));
  const ChartField r = deblur_residual(sharp, o);
  const double miss = amp - sharp.value[g.index(150, 150)], read = r.value[g.index(150, 150)];
  std::printf("peak: the deblur misses %.3g, its residual reads %.3g (%.1f %%)\n", miss, read, 100 * read / miss);
  EXPECT_NEAR(miss / amp, 0.012, 0.002);
  EXPECT_NEAR(read / miss, 0.93, 0.03);
  EXPECT_TRUE(std::isnan(r.value[g.index(0, 150)]));  // the grid's edge: undeblurred
  // An unseen texel: its neighbours' residual is unknown.
  ChartField holed = sharp;
  holed.value[g.index(100, 100)] = kNaN;
  const ChartField rh = deblur_residual(holed, o);
  EXPECT_TRUE(std::isnan(rh.value[g.index(101, 100)]));
  EXPECT_TRUE(std::isfinite(rh.value[g.index(150, 150)]));
}

TEST(AssessmentStages, LogisticResidualIsHalfTheBlurSquaredTimesTheCurvatureRatioTimesTheSlopeSquared) {
  // p = 4 + 2·u kPa (a ramp: blurring keeps it, |∇p| = 2 kPa/mm): ½b²(1 − 2σ((p − p50)/w))/w·|∇p|², positive below p50.
  const ChartGrid g = grid(120, 40, 0.05);
  PressureCalibration cal;
  cal.model = PressureModelKind::logistic;
  cal.logistic = {0.05, 8.0, 2.0};
  cal.person = "p";
  const ChartField p = field(g, 2.0, 0.0);
  ChartField ramp = p;
  for (float& v : ramp.value) v += 4.f;
  const double b = 0.3;
  const ChartField r = logistic_residual(cal, ramp, b);
  for (int i = 30; i < 90; i += 10) {
    const auto k = g.index(i, 20);
    const double pk = ramp.value[k], expected = 0.5 * b * b * (1 - 2 / (1 + std::exp(-(pk - 8.0) / 2.0))) / 2.0 * 4.0;
    EXPECT_NEAR(r.value[k], expected, 1e-3 * std::abs(expected) + 1e-6) << "p " << pk;
  }
  EXPECT_GT(r.value[g.index(30, 20)], 0.f);  // p 7 kPa: read low
  EXPECT_LT(r.value[g.index(90, 20)], 0.f);  // p 13 kPa: read high
  EXPECT_EQ(logistic_residual(linear_calibration(), ramp, b).value[g.index(60, 20)], 0.f);
  EXPECT_EQ(logistic_residual(cal, ramp, 0.0).value[g.index(60, 20)], 0.f);
}

TEST(AssessmentStages, LinearCalibrationInvertsTheSharpenedSignalAndGatesByTheTexelsOwnNoise) {
  // y = 0.01·p (kPa), calibrated over 0..30 kPa, noise 0.001: detection at 0.003, saturation at 0.3.
  const PressureCalibration cal = linear_calibration();
  const ChartGrid g = grid(5, 1, 0.1);
  Assessment a;
  a.signal.y = {g, {0.002f, 0.06f, 0.11f, 0.5f, kNaN}};
  a.signal.sigma_y = {g, {0.001f, 0.015f, 0.015f, 0.001f, kNaN}};
  a.blur_effect = constant(g, 0.01f);                                   // undone: y − 0.01
  a.signal_sigma = {g, {0.001f, 0.002f, 0.002f, 0.001f, kNaN}};          // σ_p = σ / 0.01
  AssessmentOptions o;                                                   // gate: 5 σ_y
  const std::vector<std::uint8_t> sat = calibrated_pressure(cal, false, o, a);
  auto status = [&](int k) { return static_cast<PressureStatus>(a.pressure_status[k]); };
  EXPECT_TRUE(a.calibrated);
  EXPECT_EQ(status(0), PressureStatus::below_detection);  // −0.008 after sharpening
  EXPECT_EQ(a.pressure.value[0], 0.f);
  EXPECT_TRUE(std::isnan(a.pressure_sigma.value[0]));
  EXPECT_EQ(status(1), PressureStatus::ok);
  EXPECT_NEAR(a.pressure.value[1], 5.0, 1e-4);  // (0.06 − 0.01) / 0.01
  EXPECT_NEAR(a.pressure_sigma.value[1], 0.2, 1e-5);
  EXPECT_NEAR(a.pressure.value[2], 10.0, 1e-4);
  EXPECT_EQ(status(3), PressureStatus::saturated);
  EXPECT_NEAR(a.pressure.value[3], 30.0, 1e-4);  // the lower bound at the calibration's top
  EXPECT_EQ(status(4), PressureStatus::invalid);
  EXPECT_TRUE(std::isnan(a.pressure.value[4]));
  EXPECT_EQ(sat, (std::vector<std::uint8_t>{0, 0, 0, 1, 0}));
  EXPECT_NEAR(a.below_detection_fraction, 0.25, 1e-12);
  EXPECT_NEAR(a.saturated_fraction, 0.25, 1e-12);
  EXPECT_NEAR(a.peak_kpa, 30.0, 1e-4);
  EXPECT_NEAR(a.mean_kpa, (0 + 5 + 10 + 30) / 4.0, 1e-4);
  EXPECT_TRUE(contains(a.warnings, "25.00 % of the seen skin is beyond the calibration's range"));

  // A capture with its own noise: 0.06 < 5 × 0.015 is below detection; 0.11 ≥ 0.075 stays (hysteresis off).
  Assessment lossy;
  lossy.signal = a.signal, lossy.blur_effect = a.blur_effect, lossy.signal_sigma = a.signal_sigma;
  AssessmentOptions gate_only;
  gate_only.hysteresis_sigmas = gate_only.signal_threshold_sigmas;
  calibrated_pressure(cal, true, gate_only, lossy);
  EXPECT_EQ(static_cast<PressureStatus>(lossy.pressure_status[1]), PressureStatus::below_detection);
  EXPECT_EQ(lossy.pressure.value[1], 0.f);
  EXPECT_TRUE(std::isnan(lossy.pressure_sigma.value[1]));
  EXPECT_EQ(static_cast<PressureStatus>(lossy.pressure_status[2]), PressureStatus::ok);
  EXPECT_NEAR(lossy.below_detection_fraction, 0.5, 1e-12);
}

TEST(AssessmentStages, CalibrationsGateRisesWithATexelsOwnNoiseAboveTheCapturesMedian) {
  // y = 0.01·p, the calibration's gate 0.003 (3 σ of its presses' 0.001), a lossless capture of median σ_y 0.001. A texel
  // beside a mask with twice that σ needs 0.006: 0.005 there is below detection (5 σ of the median, 2.5 of its own),
  // 0.0065 is detected; at the median σ (or below it) the calibration's 0.003 stands.
  EXPECT_DOUBLE_EQ(local_gate(0.003, 0.002, 0.001), 0.006);
  EXPECT_DOUBLE_EQ(local_gate(0.003, 0.0005, 0.001), 0.003);
  EXPECT_DOUBLE_EQ(local_gate(0.003, kNaN, 0.001), 0.003);
  EXPECT_DOUBLE_EQ(local_gate(0.003, 0.002, 0.0), 0.003);  // no median σ: the calibration's gate
  const PressureCalibration cal = linear_calibration();
  const ChartGrid g = grid(4, 1, 0.1);
  Assessment a;
  a.signal.y = {g, {0.005f, 0.005f, 0.0065f, 0.0029f}};
  a.signal.sigma_y = {g, {0.001f, 0.002f, 0.002f, 0.0005f}};
  a.signal.noise_sigma = 0.001;
  a.signal_sigma = a.signal.sigma_y;
  AssessmentOptions o;
  o.hysteresis_sigmas = o.signal_threshold_sigmas;  // the gate alone
  calibrated_pressure(cal, false, o, a);
  auto status = [&](int k) { return static_cast<PressureStatus>(a.pressure_status[k]); };
  EXPECT_EQ(status(0), PressureStatus::ok);
  EXPECT_NEAR(a.pressure.value[0], 0.5, 1e-4);
  EXPECT_EQ(status(1), PressureStatus::below_detection);
  EXPECT_EQ(a.pressure.value[1], 0.f);
  EXPECT_EQ(status(2), PressureStatus::ok);
  EXPECT_EQ(status(3), PressureStatus::below_detection);
  EXPECT_NEAR(a.detection_limit.kpa, 0.3, 1e-4);  // the limit reported is the median texel's
}

TEST(AssessmentStages, TheGapsTermRaisesATexelsGateAndIsSharedByAPlace) {
  // y = 0.01·p, the calibration's gate 0.003, median σ_y 0.001. The estimated gap's term (Assessment::gap_signal_sigma)
  // adds to a texel's detection σ in quadrature: 0.002 makes it √5 · 0.001, the gate 0.0067, and 0.005 is below
  // detection there (detected where the term is unknown). A saturated 0.5 whose term is 0.2 (at the edge of the
  // parallax a wrong gap moves) is below detection too; before, a saturated texel skipped the gate.
  const PressureCalibration cal = linear_calibration();
  const ChartGrid g = grid(4, 1, 0.1);
  Assessment a;
  a.signal.y = {g, {0.005f, 0.005f, 0.5f, 0.02f}};
  a.signal.sigma_y = constant(g, 0.001f);
  a.signal.noise_sigma = 0.001;
  a.signal_sigma = a.signal.sigma_y;
  Assessment without = a;
  a.gap_signal_sigma = {g, {kNaN, 0.002f, 0.2f, 0.001f}};
  EXPECT_NEAR(detection_sigma(a, 0), 0.001, 1e-9);
  EXPECT_NEAR(detection_sigma(a, 1), std::sqrt(5.0) * 0.001, 1e-9);
  EXPECT_NEAR(detection_sigma(without, 1), 0.001, 1e-9);
  AssessmentOptions o;
  o.hysteresis_sigmas = o.signal_threshold_sigmas;  // the gate alone
  calibrated_pressure(cal, false, o, a);
  calibrated_pressure(cal, false, o, without);
  auto status = [](const Assessment& x, int k) { return static_cast<PressureStatus>(x.pressure_status[k]); };
  EXPECT_EQ(status(a, 0), PressureStatus::ok);
  EXPECT_EQ(status(a, 1), PressureStatus::below_detection);
  EXPECT_EQ(status(without, 1), PressureStatus::ok);
  EXPECT_EQ(status(a, 2), PressureStatus::below_detection);
  EXPECT_EQ(status(without, 2), PressureStatus::saturated);
  ASSERT_EQ(status(a, 3), PressureStatus::ok);
  // One gap for every texel: its term is shared by a place, with the calibration's parameters (0.001 of signal is
  // 0.1 kPa here, in quadrature).
  const double with_gap = a.pressure_sigma_parts.shared.value[3], alone = without.pressure_sigma_parts.shared.value[3];
  EXPECT_NEAR(with_gap * with_gap - alone * alone, 0.1 * 0.1, 1e-6);
}

TEST(AssessmentStages, HysteresisKeepsAPlacesTailButNotIsolatedNoise) {
  // y = 0.01·p, a capture with its own noise (σ_y 0.01, gate 5 σ = 0.05, hysteresis 2 σ = 0.02). One row:
  // a place (0.08 detected) with a tail 0.04, 0.03 beside it, then 0.01 (1 σ: not kept), and apart from
  // it, beyond a texel of 0, an isolated 0.04 (4 σ but connected to nothing detected).
  const PressureCalibration cal = linear_calibration();
  const ChartGrid g = grid(8, 1, 0.1);
  Assessment a;
  a.signal.y = {g, {0.03f, 0.04f, 0.08f, 0.04f, 0.01f, 0.03f, 0.0f, 0.04f}};
  a.signal.sigma_y = constant(g, 0.01f);
  a.signal_sigma = constant(g, 0.01f);
  AssessmentOptions o;
  ASSERT_DOUBLE_EQ(o.hysteresis_sigmas, 2.0);
  // A detected piece grows only when it is as large as the smallest place: one texel (0.01 mm²) does not
  // under the default 0.05 mm².
  Assessment speck;
  speck.signal = a.signal, speck.signal_sigma = a.signal_sigma;
  calibrated_pressure(cal, true, o, speck);
  for (int k = 0; k < 8; ++k) EXPECT_EQ(static_cast<PressureStatus>(speck.pressure_status[k]) == PressureStatus::ok, k == 2) << k;
  o.min_hotspot_area_mm2 = 0.01;
  calibrated_pressure(cal, true, o, a);
  auto status = [&](int k) { return static_cast<PressureStatus>(a.pressure_status[k]); };
  for (int k : {0, 1, 2, 3}) {
    EXPECT_EQ(status(k), PressureStatus::ok) << k;
    EXPECT_NEAR(a.pressure.value[k], a.signal.y.value[k] / 0.01, 1e-4) << k;  // the inverse, not 0
    EXPECT_NEAR(a.pressure_sigma.value[k], 1.0, 1e-5) << k;                   // σ 0.01 / 0.01
  }
  for (int k : {4, 5, 6, 7}) {  // 1 σ; beyond it; 0; isolated
    EXPECT_EQ(status(k), PressureStatus::below_detection) << k;
    EXPECT_EQ(a.pressure.value[k], 0.f) << k;
  }
  // At the gate the hysteresis is off: only the detected texel keeps its pressure.
  Assessment off;
  off.signal = a.signal, off.signal_sigma = a.signal_sigma;
  o.hysteresis_sigmas = o.signal_threshold_sigmas;
  calibrated_pressure(cal, true, o, off);
  for (int k = 0; k < 8; ++k) EXPECT_EQ(static_cast<PressureStatus>(off.pressure_status[k]) == PressureStatus::ok, k == 2) << k;
}

TEST(AssessmentStages, ThresholdsBelowTheDetectionLimitAreNamedWithTheLimit) {
  // y = 0.01·p, the calibration presses' noise 0.001 (its gate 3 σ = 0.003, 0.3 kPa). A capture with its own
  // noise of median σ_y 0.01: gate 5 σ = 0.05, 5 kPa; the hysteresis's 2 σ = 0.02, 2 kPa.
  const PressureCalibration cal = linear_calibration();
  AssessmentOptions o;
  const DetectionLimit own = detection_limit(cal, 0.01, true, o);
  EXPECT_TRUE(own.capture_noise);
  EXPECT_NEAR(own.signal, 0.05, 1e-12);
  EXPECT_NEAR(own.kpa, 5.0, 1e-4);
  EXPECT_NEAR(own.tail_kpa, 2.0, 1e-4);
  // Without a noise of its own the gate is the calibration's; the hysteresis's 2 σ_y (0.004) is above it: off.
  const DetectionLimit presses = detection_limit(cal, 0.002, false, o);
  EXPECT_FALSE(presses.capture_noise);
  EXPECT_NEAR(presses.kpa, 0.3, 1e-4);
  EXPECT_TRUE(std::isnan(presses.tail_kpa));
  // A gate beyond the calibration's saturation (0.3): its top, 30 kPa.
  EXPECT_NEAR(detection_limit(cal, 0.1, true, o).kpa, 30.0, 1e-4);

  // The limit is where calibrated_pressure's gate is (hysteresis off): a texel just above it is an estimate, just
  // below it is below detection.
  const ChartGrid g = grid(3, 1, 0.1);
  Assessment a;
  a.signal.y = {g, {0.0499f, 0.0501f, 0.2f}};
  a.signal.sigma_y = constant(g, 0.01f);
  a.signal.noise_sigma = 0.01;
  a.signal_sigma = constant(g, 0.01f);
  o.hysteresis_sigmas = o.signal_threshold_sigmas;
  calibrated_pressure(cal, true, o, a);
  EXPECT_EQ(static_cast<PressureStatus>(a.pressure_status[0]), PressureStatus::below_detection);
  EXPECT_EQ(static_cast<PressureStatus>(a.pressure_status[1]), PressureStatus::ok);
  EXPECT_NEAR(a.detection_limit.kpa, 5.0, 1e-4);

  // 4.3 kPa is below the 5 kPa limit but above the 2 kPa tail: places under 5 kPa are not found, the areas of those
  // found hold. 1.5 kPa is below the tail too: its areas are underestimated. 5.5 is above the limit: no warning.
  std::vector<std::string> warnings;
  warn_thresholds_below_detection({1.5, 4.3, 5.5}, own, warnings);
  ASSERT_EQ(warnings.size(), 2u);
  for (const char* text : {"hotspot threshold 1.5 kPa is below the detection limit of 5.0 kPa (the pressure whose signal is 5 σ of this "
                           "capture's noise (median σ 0.0100)), and below the 2.0 kPa down to which a detected place's tail is read",
                           "so the areas at that threshold are underestimated", "give thresholds of at least 2.0 kPa"})
    EXPECT_NE(warnings[0].find(text), std::string::npos) << text << "\n" << warnings[0];
  for (const char* text : {"hotspot threshold 4.3 kPa is below the detection limit of 5.0 kPa", "stays between 4.3 kPa and 5.0 kPa is not reported",
                           "read down to about 2.0 kPa"})
    EXPECT_NE(warnings[1].find(text), std::string::npos) << text << "\n" << warnings[1];
  EXPECT_EQ(warnings[1].find("areas at that threshold are underestimated"), std::string::npos) << warnings[1];
  // Without a tail (the hysteresis off) every threshold below the limit has its areas underestimated.
  warnings.clear();
  warn_thresholds_below_detection({0.2, 0.3, 4.3}, presses, warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_TRUE(contains(warnings, "hotspot threshold 0.2 kPa is below the detection limit of 0.3 kPa (the pressure whose signal is 3 σ of "
                                 "the calibration presses' noise (σ 0.0010)): the outline at 0.2 kPa")) << warnings[0];
  EXPECT_TRUE(contains(warnings, "areas at that threshold are underestimated"));
  warnings.clear();
  warn_thresholds_below_detection({4.3}, DetectionLimit{}, warnings);  // uncalibrated: no limit
  EXPECT_TRUE(warnings.empty());
}

// A boundary vertex the camera sees obliquely: the worn map's first seen texel is 3 texels (0.15 mm) in from
// it, and a camera pixel spans 0.2 mm along u there (kx = 5 px/mm), so two pixels reach 8 texels and the
// vertex is seen; its value is the nearest signal within 8 texels plus the smoothing's 0.25 mm (5 texels),
// here 8 texels in (the signal stops short of the seen skin, as beside a held baseline's blind strip). Seen
// square on (kx = 20 px/mm) two pixels are 2 texels and the same vertex is not seen. A vertex 12 texels from
// the seen skin is not seen though a signal lies within its value's reach; one under the glare mask neither.
TEST(AssessmentStages, VerticesAreSeenWithinTwoCameraPixelsMeasuredWhereTheSkinIsSeen) {
  constexpr int kW = 40, kH = 30;
  constexpr double kTexel = 0.05;
  auto map = [&](double kx) {
    InverseMap inv = affine_map(kW, kH, kTexel, kx, 20, 0, 10, 10);
    for (int j = 0; j < kH; ++j)
      for (int i = 0; i < kW; ++i)
        if (i < (j >= 20 ? 3 : 12)) inv.valid[inv.index(i, j)] = 0, inv.map_x[inv.index(i, j)] = inv.map_y[inv.index(i, j)] = -1;
    return inv;
  };
  const InverseMap oblique = map(5);
  ChartField signal{ChartGrid{kW, kH, kTexel, Vec2::Zero()}, std::vector<float>(kW * kH, kNaN)};
  for (int j = 0; j < kH; ++j)
    for (int i = 8; i < kW; ++i)
      if (oblique.valid[oblique.index(i, j)]) signal.value[signal.grid.index(i, j)] = static_cast<float>(i + 100 * j);
  Chart chart;
  chart.uv = {Vec2(0, 25 * kTexel), Vec2(0, 4 * kTexel), Vec2(30 * kTexel, 25 * kTexel), Vec2(kNaN, kNaN)};
  const std::vector<float> reach = vertex_reach_texels(oblique, {}, chart, 2);
  ASSERT_EQ(reach.size(), 4u);
  EXPECT_NEAR(reach[0], 2 * 0.2 / kTexel, 1e-4);  // seen: 8 texels
  EXPECT_TRUE(std::isnan(reach[1]));               // 12 texels from the seen skin
  EXPECT_NEAR(reach[2], 8, 1e-4);
  EXPECT_TRUE(std::isnan(reach[3]));  // no chart coordinate
  const std::vector<float> v = vertex_values(signal, chart, reach, 0.25);
  EXPECT_EQ(v[0], 8 + 100 * 25);  // the nearest signal, 8 texels in
  EXPECT_TRUE(std::isnan(v[1]));  // though a signal lies 12 texels from it, within 8 + 5
  EXPECT_FLOAT_EQ(v[2], 30 + 100 * 25);  // interior: the bilinear sample at a texel centre
  EXPECT_TRUE(std::isnan(v[3]));
  // Square on: two pixels are two texels.
  EXPECT_TRUE(std::isnan(vertex_reach_texels(map(20), {}, chart, 2)[0]));
  // Under the glare mask from its first seen texel to u = 20 texels: not seen.
  std::vector<std::uint8_t> glare(kW * kH, 0);
  for (int j = 20; j < kH; ++j)
    for (int i = 3; i < 20; ++i) glare[oblique.index(i, j)] = 1;
  EXPECT_TRUE(std::isnan(vertex_reach_texels(oblique, glare, chart, 2)[0]));
}

}  // namespace
}  // namespace clearfit
