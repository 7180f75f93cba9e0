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
#include <clearfit/fit/indenter_field.hpp>
#include <clearfit/fit/pressure_model.hpp>

namespace clearfit {

struct FieldFitOptions {
  PressureField field = PressureField::punch;
  double blur_sigma_mm = 0.3;   ///< the skin's lateral blur (SKIN.md)
  int samples_per_ring = 8;
  void validate() const;        ///< throws InputError naming --blur-mm
};

/// Whether every press carries a radial profile.
bool presses_have_profiles(const std::vector<CalibrationPress>& presses);

/// The fit above. The result's logistic and calibration hold the field fit;
/// linear, levels and the uniform start are as fit_pressure_calibration gives
/// them. rmse_kpa: the rings' signals inverted against the rings' mean drive
/// (blurred pressure), over the rings inside the invertible range
/// (presses_in_range counts those rings). Throws InputError naming the file and
/// line of a press without a profile, force or indenter diameter.
PressureFitResult fit_pressure_field(const std::vector<CalibrationPress>& presses, const PressureFitOptions& options,
                                     const FieldFitOptions& field);

}  // namespace clearfit
