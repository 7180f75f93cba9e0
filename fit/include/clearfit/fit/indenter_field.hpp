#pragma once
// A clear flat indenter pressed on the skin, as a calibration session sees it:
// where a camera pixel lands on the skin through the indenter (a flat clear
// slab on the skin, or nothing), and the skin's drive under the indenter
// (SKIN.md: contact pressure blurred laterally by σ ≈ 0.3 mm) for the flat
// punch (Sneddon) or the uniform disc, per newton of force.
//
// Geometry: the camera's optical axis is normal to the skin, its centre
// distance_mm from the skin; the slab (thickness slab_mm, index slab_ior) lies
// on the skin (its lower face is the indenter's contact face). A ray at angle θ
// from the axis meets the skin at radius
//   ρ = (D − t)·tan θ + t·tan θ',  sin θ' = sin θ / n  (Snell, flat slab).
#include <Eigen/Core>

#include <vector>

namespace clearfit {

struct IndenterOptics {
  double distance_mm = 60;  ///< camera centre to skin, along the optical axis
  double slab_mm = 0;       ///< clear slab on the skin (0: the skin seen directly)
  double slab_ior = 1.49;
  /// Throws InputError (element `--NAME`) for a non-positive distance, a slab
  /// thicker than the distance, a negative thickness or an index below 1.
  void validate() const;
  /// The skin point (mm, skin plane, origin on the optical axis) of a camera-frame ray
  /// (z along the axis). NaN for rays that do not point at the skin.
  Eigen::Vector2d skin_point(const Eigen::Vector3d& ray) const;
};

enum class PressureField { punch, uniform, hertz };
const char* to_string(PressureField field);

/// The blurred pressure profile of an indenter of radius a for a force of 1 N,
/// tabulated in r (0 to a + 6σ, step σ/20; beyond it 0): kPa per newton.
///   punch:   p(r) = 1/(2πa√(a² − r²))   (Sneddon; the rim singularity is integrable)
///   uniform: p(r) = 1/(πa²) for r < a
///   hertz:   p(r) = 3/(2πa²)·√(1 − r²/a²)  (a sphere; a is the contact radius,
///            which grows with the force: contact::HertzSphere)
/// blurred by an isotropic Gaussian of σ (0: not blurred; the punch then is its
/// closed form, capped nowhere). The radial convolution is exact in the angle
/// (the Bessel I0 form); the punch's and the sphere's r' = a·sin φ removes the
/// singularity (the punch) and the square root's kink (the sphere).
/// The blurred Hertz profile at r (kPa per newton) for contact radius a, computed
/// at that one radius (no table: for fits whose a changes with every evaluation).
/// Equals IndenterProfile(hertz, a, σ).kpa_per_newton(r) to the table's interpolation.
double blurred_hertz_kpa_per_newton(double r_mm, double contact_radius_mm, double blur_sigma_mm);

class IndenterProfile {
 public:
  IndenterProfile(PressureField field, double radius_mm, double blur_sigma_mm);
  double kpa_per_newton(double r_mm) const;
  double radius_mm() const { return a_; }
  PressureField field() const { return field_; }

 private:
  PressureField field_;
  double a_, sigma_, step_ = 0;
  std::vector<double> table_;
};

}  // namespace clearfit
