#pragma once
// The forward model of skin under pressure (SKIN.md, "A forward model for
// synthetic captures"), in linear RGB up to the camera:
//   1. drive s(x) = pressure blurred laterally (σ = blur_sigma_mm), optionally
//      mixed with the von Mises stress at von_mises_depth_mm:
//      s = (1 − w)·p_blur + w·σ_vM (w = von_mises_weight);
//   2. steady blood loss B_ss(s) = β·Ψ(s; s50, w) with Ψ the normalised logistic
//      (below): Ψ(0) = 0, Ψ → 1;
//   3. first-order lag of B toward B_ss with τ_on (rising) / τ_off (falling);
//   4. blood index b = (1 − B)·(1 + a_p·g(t)), g a zero-mean pulse of peak 1;
//   5. radiance per channel D_c = ρ_c(x)·exp(−k_c·(b − 1)), ρ the albedo with
//      fingerprint ridges and mottling over a skin tone.
//
// The calibration model is exact for it: without pulse, at steady state,
//   y = ln(G / G0) = k_G·B_ss = k_G·β·Ψ(s; s50, w),
// i.e. the calibration's y = y_max·Ψ((p − p50)/w) with y_max = k_G·β,
// p50 = s50, width = w (equivalent_calibration()), where the pressure is the
// drive (equal to the contact pressure where it varies slowly against the
// blur and without the von Mises mix, e.g. under a wide flat indenter's
// centre). With a zero-mean pulse, y averaged over whole pulse periods is the
// same (y = k_G·B·(1 + a_p·g) is linear in g).
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/fit/skin_blur.hpp>

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace clearfit {

/// Normalised logistic: Ψ(s) = (L(s) − L(0)) / (1 − L(0)),
/// L(s) = 1 / (1 + exp(−(s − s50)/width)); Ψ(0) = 0, Ψ(∞) = 1, Ψ(s50) = (1/2 − L(0))/(1 − L(0)).
/// Pressures in kPa, width > 0. Negative s gives Ψ < 0 (callers clamp at 0 pressure).
double normalized_logistic(double s_kpa, double s50_kpa, double width_kpa);

/// Skin tone: linear diffuse reflectance per channel (R, G, B).
struct SkinTone {
  std::string name = "medium";
  Eigen::Vector3d reflectance{0.45, 0.33, 0.27};
  /// Presets spanning NIST's measured green range (0.11–0.41): "light" (green
  /// 0.41), "medium" (0.33, the median), "dark" (0.11). Throws
  /// std::invalid_argument for other names.
  static SkinTone preset(const std::string& name);
};

struct SkinParameters {
  // 1. drive
  double blur_sigma_mm = SkinBlur{}.sigma_mm;  ///< the lateral blur (skin_blur.hpp owns its default and rule)
  double von_mises_weight = 0.0;   ///< 0..1: share of the von Mises stress in the drive
  double von_mises_depth_mm = 0.2;
  double poisson = 0.48;
  // 2. steady state
  double s50_kpa = 8.0, width_kpa = 2.0, beta = 0.85;
  // 3. dynamics
  double tau_on_s = 0.3, tau_off_s = 1.5;
  // 4. pulse
  double pulse_amplitude = 0.005, pulse_hz = 1.2;
  // 5. optics: k_c for R, G, B (k_R = 0.2·k_G, k_B = 0.3·k_G)
  Eigen::Vector3d absorption{0.012, 0.06, 0.018};
  SkinTone tone;
  double ridge_period_mm = 0.31;   ///< fingerprint ridge spacing across the ridges (0.28–0.33)
  double ridge_amplitude = 0.05;   ///< relative (0.03–0.08)
  /// Waviness of the ridge lines: their phase is shifted by ridge_warp_mm·sin(2π·t/4 mm) along
  /// them, which tilts them by up to ±atan(2π·warp/4) and shortens the local period by up to
  /// 1/√(1 + (2π·warp/4)²) (0.25 mm: ±21°, 0.31 → 0.29 mm). 0: straight parallel ridges.
  double ridge_warp_mm = 0.25;
  double mottling_amplitude = 0.03;  ///< relative standard deviation (0.02–0.05)
  double mottling_scale_mm = 2.0;  ///< typical blotch size
  std::uint32_t texture_seed = 1;  ///< ridges' orientation/warp and mottling
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// The calibration model's parameters that this skin reproduces exactly (see above).
struct EquivalentCalibration {
  double y_max = 0, p50_kpa = 0, width_kpa = 0;
};
EquivalentCalibration equivalent_calibration(const SkinParameters& p);

/// Steady blood loss B_ss(s) = β·Ψ(max(s, 0)) for a drive s (kPa).
double steady_blood_loss(const SkinParameters& p, double drive_kpa);

/// One step of the first-order lag: B after dt seconds, starting at b0 and
/// heading to target b_ss (τ_on when b_ss > b0, else τ_off). Exact for a
/// constant target over the step.
double lag_step(const SkinParameters& p, double b0, double b_ss, double dt_s);

/// Zero-mean periodic pulse waveform of peak |g| = 1 (a systolic rise and a
/// dicrotic notch: two harmonics), at pulse_hz; t in seconds.
double pulse_waveform(double t_s, double hz);

/// Radiance ratio per channel exp(−k_c·(b − 1)) for blood loss B and pulse value g.
Eigen::Vector3d radiance_factor(const SkinParameters& p, double blood_loss, double pulse);

/// Albedo texture: the relative modulation m(uv) = (1 + ridges)·(1 + mottling)
/// at chart uv (mm); ρ_c = tone_c · m. Deterministic in texture_seed.
class SkinTexture {
 public:
  explicit SkinTexture(const SkinParameters& p);
  double modulation(const Vec2& uv_mm) const;
  /// Ridge term alone in [−1, 1] (cos of the warped ridge phase).
  double ridge(const Vec2& uv_mm) const;
  /// Mottling term alone (unit standard deviation over a large area).
  double mottling(const Vec2& uv_mm) const;

 private:
  SkinParameters p_;
  Vec2 ridge_dir_;
  struct Wave { Vec2 k; double phase, amp; };
  std::vector<Wave> warp_, mottle_;
};

/// The drive s(x) on the chart grid from the contact pressure (kPa, NaN outside
/// the contact surface, which counts as 0 pressure): Gaussian blur of
/// blur_sigma_mm (cv::GaussianBlur; NaN texels as 0) mixed with the von Mises
/// stress at depth (contact::von_mises_at_depth) when von_mises_weight > 0.
ChartField skin_drive(const SkinParameters& p, const ChartField& pressure_kpa);

}  // namespace clearfit
