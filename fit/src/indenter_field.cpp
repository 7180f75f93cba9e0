// A clear flat indenter on the skin: pixel → skin through a flat slab, and the
// blurred punch / uniform pressure profiles (indenter_field.hpp).
#include <clearfit/error.hpp>
#include <clearfit/fit/indenter_field.hpp>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace clearfit {
namespace {

/// Clenshaw's sum of a Chebyshev series as Cephes' chbevl writes it (coefficients highest order first).
template <std::size_t N>
double chebyshev(double x, const std::array<double, N>& c) {
  double b0 = c[0], b1 = 0, b2 = 0;
  for (std::size_t i = 1; i < N; ++i) b2 = b1, b1 = b0, b0 = x * b1 - b2 + c[i];
  return 0.5 * (b0 - b2);
}

/// I0(x)·e^(−x) for x ≥ 0 (the exponentially scaled modified Bessel function), by Cephes' i0e: Chebyshev
/// series on [0, 8] and of 32/x beyond (relative error about 1e-16; std::cyl_bessel_i's series took 5 µs a call,
/// 6 s of calibrate-pressure's 6.4 for the punch's two profiles).
double bessel_i0e(double x) {
  static constexpr std::array<double, 30> a{
      -4.4153416464793395e-18, 3.3307945188222384e-17, -2.431279846547955e-16, 1.715391285555133e-15, -1.1685332877993451e-14,
      7.676185498604936e-14,   -4.856446783111929e-13, 2.95505266312964e-12,   -1.726826291441556e-11, 9.675809035373237e-11,
      -5.189795601635263e-10,  2.6598237246823866e-09, -1.300025009986248e-08, 6.046995022541919e-08,  -2.670793853940612e-07,
      1.1173875391201037e-06,  -4.4167383584587505e-06, 1.6448448070728896e-05, -5.754195010082104e-05, 0.00018850288509584165,
      -0.0005763755745385824,  0.0016394756169413357,  -0.004324309995050576,  0.010546460394594998,   -0.02373741480589947,
      0.04930528423967071,     -0.09490109704804764,   0.17162090152220877,    -0.3046826723431984,    0.6767952744094761};
  static constexpr std::array<double, 25> b{
      -7.233180487874754e-18, -4.830504485944182e-18, 4.46562142029676e-17,   3.461222867697461e-17,  -2.8276239805165836e-16,
      -3.425485619677219e-16, 1.7725601330565263e-15, 3.8116806693526224e-15, -9.554846698828307e-15, -4.150569347287222e-14,
      1.54008621752141e-14,   3.8527783827421426e-13, 7.180124451383666e-13,  -1.7941785315068062e-12, -1.3215811840447713e-11,
      -3.1499165279632416e-11, 1.1889147107846439e-11, 4.94060238822497e-10,  3.3962320257083865e-09, 2.266668990498178e-08,
      2.0489185894690638e-07, 2.8913705208347567e-06, 6.889758346916825e-05,  0.0033691164782556943,  0.8044904110141088};
  if (x <= 8) return chebyshev(x / 2 - 2, a);
  return chebyshev(32 / x - 2, b) / std::sqrt(x);
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
  // The nodes' source radii r' and weights of p r' dr' (the same for every r): punch r' = a sin φ, p r' dr' = sin φ dφ / (2π);
  // the uniform disc p r' dr' = r' dr' / (π a²).
  std::vector<double> node_r(kNodes), node_w(kNodes);
  for (int k = 0; k < kNodes && field_ != PressureField::hertz; ++k) {
    const double u = (k + 0.5) / kNodes;
    const double sin_phi = std::sin(u * std::numbers::pi / 2);
    node_r[k] = field_ == PressureField::punch ? a_ * sin_phi : u * a_;
    node_w[k] = field_ == PressureField::punch ? sin_phi / (2 * std::numbers::pi) : node_r[k] / (std::numbers::pi * a_ * a_);
  }
  const double dnode = field_ == PressureField::punch ? std::numbers::pi / 2 / kNodes : a_ / kNodes;
  table_.resize(n);
  tbb::parallel_for(0, n, [&](int i) {  // each entry on its own: the same table on any number of threads
    const double r = i * step_;
    if (field_ == PressureField::hertz) {  // smooth after r' = a sin φ: fewer nodes do
      table_[i] = blurred_hertz(r, a_, sigma_);
      return;
    }
    double sum = 0;
    for (int k = 0; k < kNodes; ++k) sum += node_w[k] * ring_kernel(r, node_r[k], sigma_) * dnode;
    table_[i] = 1000 * sum;  // N/mm² → kPa
  });
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
