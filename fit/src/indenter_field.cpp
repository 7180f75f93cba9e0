// A clear flat indenter on the skin: pixel → skin through a flat slab, and the
// blurred punch / uniform pressure profiles (indenter_field.hpp).
#include <clearfit/error.hpp>
#include <clearfit/fit/indenter_field.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace clearfit {
namespace {

/// I0(x)·e^(−x) for x ≥ 0 (the exponentially scaled modified Bessel function).
double bessel_i0e(double x) {
  if (x < 50) return std::cyl_bessel_i(0.0, x) * std::exp(-x);
  return (1 + 1 / (8 * x) + 9 / (128 * x * x)) / std::sqrt(2 * std::numbers::pi * x);
}

/// The Gaussian's angular mean around the ring at r of a source ring at r' (per unit r'·dr'·2π weight):
/// (1/σ²)·exp(−(r − r')²/(2σ²))·I0e(r·r'/σ²).
double ring_kernel(double r, double rp, double s) {
  return std::exp(-(r - rp) * (r - rp) / (2 * s * s)) * bessel_i0e(r * rp / (s * s)) / (s * s);
}

/// I0(x)·e^(−x) by Abramowitz & Stegun 9.8.1–9.8.2 (relative error below 2e-7), for the Hertz
/// profile that a fit recomputes at every evaluation.
double bessel_i0e_fast(double x) {
  if (x <= 3.75) {
    const double t = (x / 3.75) * (x / 3.75);
    return std::exp(-x) * (1 + t * (3.5156229 + t * (3.0899424 + t * (1.2067492 + t * (0.2659732 + t * (0.0360768 + t * 0.0045813))))));
  }
  const double t = 3.75 / x;
  return (0.39894228 + t * (0.01328592 + t * (0.00225319 + t * (-0.00157565 + t * (0.00916281 + t * (-0.02057706 + t * (0.02635537 + t * (-0.01647633 + t * 0.00392377)))))))) /
         std::sqrt(x);
}

/// The Hertz profile per newton blurred, at r: with r' = a·sin φ, p r' dr' = 3/(2π)·sin φ cos² φ dφ per
/// newton; midpoint nodes in φ at most σ/8 apart in r'.
double blurred_hertz(double r, double a, double s) {
  const int nodes = std::max(256, static_cast<int>(std::ceil(8 * a / s * std::numbers::pi / 2)));
  const double h = std::numbers::pi / 2 / nodes;
  double sum = 0;
  for (int k = 0; k < nodes; ++k) {
    const double phi = (k + 0.5) * h, rp = a * std::sin(phi), c = std::cos(phi);
    const double kernel = std::exp(-(r - rp) * (r - rp) / (2 * s * s)) * bessel_i0e_fast(r * rp / (s * s)) / (s * s);
    sum += 3 / (2 * std::numbers::pi) * std::sin(phi) * c * c * kernel * h;
  }
  return 1000 * sum;  // N/mm² → kPa
}

}  // namespace

double blurred_hertz_kpa_per_newton(double r_mm, double contact_radius_mm, double blur_sigma_mm) {
  r_mm = std::abs(r_mm);
  const double a = contact_radius_mm;
  if (blur_sigma_mm == 0) return r_mm < a ? 1000 * 3 / (2 * std::numbers::pi * a * a) * std::sqrt(1 - r_mm * r_mm / (a * a)) : 0;
  if (r_mm > a + 8 * blur_sigma_mm) return 0;
  return blurred_hertz(r_mm, a, blur_sigma_mm);
}

void IndenterOptics::validate() const {
  auto need = [](bool ok, const char* option, double v, const char* rule) {
    if (!ok) throw InputError("", option, "is " + std::to_string(v) + "; " + rule);
  };
  need(std::isfinite(distance_mm) && distance_mm > 0, "--distance-mm", distance_mm, "expected the camera-to-skin distance in mm (> 0)");
  need(std::isfinite(slab_mm) && slab_mm >= 0 && slab_mm < distance_mm, "--slab-mm", slab_mm,
       "expected the clear indenter's thickness in mm, from 0 to the camera distance");
  need(std::isfinite(slab_ior) && slab_ior >= 1 && slab_ior < 4, "--slab-ior", slab_ior, "expected a refractive index from 1 to 4");
}

Eigen::Vector2d IndenterOptics::skin_point(const Eigen::Vector3d& ray) const {
  const double lateral = std::hypot(ray.x(), ray.y());
  if (!(ray.z() > 0) || !std::isfinite(lateral)) return Eigen::Vector2d::Constant(NAN);
  if (lateral == 0) return Eigen::Vector2d::Zero();
  const double tan_air = lateral / ray.z(), sin_air = lateral / ray.norm();
  const double sin_slab = sin_air / slab_ior, tan_slab = sin_slab / std::sqrt(1 - sin_slab * sin_slab);
  const double rho = (distance_mm - slab_mm) * tan_air + slab_mm * tan_slab;
  return Eigen::Vector2d(ray.x(), ray.y()) * (rho / lateral);
}

const char* to_string(PressureField field) {
  return field == PressureField::punch ? "punch" : field == PressureField::hertz ? "hertz" : "uniform";
}

IndenterProfile::IndenterProfile(PressureField field, double radius_mm, double blur_sigma_mm)
    : field_(field), a_(radius_mm), sigma_(blur_sigma_mm) {
  if (!(radius_mm > 0) || !(blur_sigma_mm >= 0)) throw std::invalid_argument("IndenterProfile: radius must be > 0, blur >= 0");
  if (sigma_ == 0) return;
  step_ = sigma_ / 20;
  const int n = static_cast<int>(std::ceil((a_ + 6 * sigma_) / step_)) + 1;
  constexpr int kNodes = 2000;
  table_.resize(n);
  for (int i = 0; i < n; ++i) {
    const double r = i * step_;
    if (field_ == PressureField::hertz) {  // smooth after r' = a sin φ: fewer nodes do
      table_[i] = blurred_hertz(r, a_, sigma_);
      continue;
    }
    double sum = 0;
    for (int k = 0; k < kNodes; ++k) {
      const double u = (k + 0.5) / kNodes;
      if (field_ == PressureField::punch) {  // r' = a sin φ: p r' dr' = sin φ dφ / (2π)
        const double phi = u * std::numbers::pi / 2;
        sum += std::sin(phi) / (2 * std::numbers::pi) * ring_kernel(r, a_ * std::sin(phi), sigma_) * (std::numbers::pi / 2 / kNodes);
      } else {  // p r' dr' = r' dr' / (π a²)
        const double rp = u * a_;
        sum += rp / (std::numbers::pi * a_ * a_) * ring_kernel(r, rp, sigma_) * (a_ / kNodes);
      }
    }
    table_[i] = 1000 * sum;  // N/mm² → kPa
  }
}

double IndenterProfile::kpa_per_newton(double r_mm) const {
  r_mm = std::abs(r_mm);
  if (table_.empty()) {  // not blurred: the closed forms
    if (r_mm >= a_) return 0;
    if (field_ == PressureField::hertz) return blurred_hertz_kpa_per_newton(r_mm, a_, 0);
    return field_ == PressureField::punch ? 1000 / (2 * std::numbers::pi * a_ * std::sqrt(a_ * a_ - r_mm * r_mm))
                                          : 1000 / (std::numbers::pi * a_ * a_);
  }
  const double x = r_mm / step_;
  if (x >= double(table_.size() - 1)) return 0;
  const auto i = static_cast<std::size_t>(x);
  return table_[i] + (x - double(i)) * (table_[i + 1] - table_[i]);
}

}  // namespace clearfit
