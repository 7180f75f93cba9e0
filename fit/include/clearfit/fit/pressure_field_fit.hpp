#pragma once
// The per-person calibration fitted to the signal field under the indenter
// (radially resolved, `clearfit presses`) with the indenter's pressure
// distribution, not to (mean pressure, mean signal): under a rigid flat punch
// the pressure is Sneddon's p(r) = F/(2πa√(a² − r²)), far higher at the rim
// than at the centre (SKIN.md), and the skin blurs it (σ ≈ 0.3 mm) before it
// blanches. The model of ring k of press i (force F_i):
//   y_ik = mean over the ring of y_max·Ψ(F_i·q(r); p50, w),
// q the blurred profile per newton (IndenterProfile), the ring mean taken over
// equal-area sub-radii. Fitted by Levenberg–Marquardt (Eigen's
// unsupported LevenbergMarquardt) on (ln y_max, p50, ln w) from the
// uniform fit of the disc means; covariance s²(JᵀJ)⁻¹ over the rings (rings of
// one press share its baseline noise: the σ are a lower bound).
//
// A spherical indenter (presses with sphere_radius_mm, field hertz): q is
// Hertz's 3/(2πa²)·√(1 − r²/a²) blurred, with the contact radius
// a = (3FR/(4E*))^{1/3} of each press's force (SKIN.md). The skin's E* is
// given (FieldFitOptions::e_star_kpa) or fitted as a fourth parameter ln E*,
// started from the radius where the strongest press's profile falls to half
// its centre (taken as a) with the logistic first fitted at that E*; the
// calibration's covariance is then the logistic's block of the 4×4 one (E*'s
// uncertainty included).
#include <clearfit/fit/indenter_field.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/fit/skin_blur.hpp>

namespace clearfit {

struct FieldFitOptions {
  PressureField field = PressureField::punch;
  double skin_blur_mm = SkinBlur{}.sigma_mm;  ///< the skin's lateral blur (skin_blur.hpp owns its default and rule)
  int samples_per_ring = 8;
  double e_star_kpa = 0;        ///< hertz: the skin's plane-strain modulus E* (kPa); 0: fitted
  void validate() const;        ///< throws InputError naming --skin-blur-mm or --e-star-kpa
};

/// Whether every press carries a radial profile.
bool presses_have_profiles(const std::vector<CalibrationPress>& presses);

/// The fit above. The result's logistic and calibration hold the field fit;
/// linear, levels and the uniform start are as fit_pressure_calibration gives
/// them. rmse_kpa: the rings' signals inverted against the rings' mean drive
/// (blurred pressure), over the rings inside the invertible range
/// (presses_in_range counts those rings). Throws InputError naming the file and
/// line of a press without a profile, force or indenter diameter, or (hertz)
/// without sphere_radius_mm. The hertz fit fills the result's e_star_kpa and e_star_se_kpa.
PressureFitResult fit_pressure_field(const std::vector<CalibrationPress>& presses, const PressureFitOptions& options,
                                     const FieldFitOptions& field);

/// The rings' mean drive (kPa) of one press under the field, as the fit models
/// it (the mean over equal-area sub-radii): for the fit's plot. e_star_kpa is
/// used by hertz only.
std::vector<double> ring_drives_kpa(const CalibrationPress& press, const FieldFitOptions& field, double e_star_kpa);

}  // namespace clearfit
