#include <clearfit/fit/contact_mechanics.hpp>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace clearfit::contact {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kKpaPerNmm2 = 1000.0;  // 1 N/mm² = 1 MPa = 1000 kPa
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}
}  // namespace

double mean_pressure_kpa(double force_n, double radius_mm) {
  require(radius_mm > 0, "contact::mean_pressure_kpa: radius_mm must be > 0");
  return force_n / (kPi * radius_mm * radius_mm) * kKpaPerNmm2;
}

double plane_strain_modulus(double youngs, double poisson) {
  require(poisson > -1 && poisson < 1, "contact::plane_strain_modulus: poisson must be in (-1, 1)");
  return youngs / (1 - poisson * poisson);
}

double FlatPunch::pressure_kpa(double r_mm) const {
  require(radius_mm > 0 && force_n >= 0, "FlatPunch: radius_mm must be > 0 and force_n >= 0");
  const double a = radius_mm, r = std::abs(r_mm);
  if (r >= a) return 0.0;
  const double p = force_n / (2 * kPi * a * std::sqrt(a * a - r * r)) * kKpaPerNmm2;
  return rim_cap_ratio > 0 ? std::min(p, rim_cap_ratio * mean_pressure_kpa(force_n, a)) : p;
}

double FlatPunch::axis_sigma_z_kpa(double z_mm) const {
  const double a2 = radius_mm * radius_mm, z2 = z_mm * z_mm;
  return force_n * (a2 + 3 * z2) / (2 * kPi * (a2 + z2) * (a2 + z2)) * kKpaPerNmm2;
}

double FlatPunch::indentation_mm(double e_star_kpa) const {
  require(e_star_kpa > 0, "FlatPunch::indentation_mm: e_star_kpa must be > 0");
  return force_n / (2 * radius_mm * e_star_kpa / kKpaPerNmm2);
}

double FlatPunch::capped_force_fraction() const {
  if (rim_cap_ratio <= 0) return 1.0;
  require(rim_cap_ratio >= 0.5, "FlatPunch: rim_cap_ratio must be 0 or >= 0.5 (the centre pressure is p_mean/2)");
  return 1 - 1 / (4 * rim_cap_ratio);
}

double HertzSphere::contact_radius_mm() const {
  require(sphere_radius_mm > 0 && e_star_kpa > 0 && force_n >= 0, "HertzSphere: radius, modulus > 0, force >= 0");
  return std::cbrt(3 * force_n * sphere_radius_mm / (4 * e_star_kpa / kKpaPerNmm2));
}

double HertzSphere::peak_pressure_kpa() const {
  const double a = contact_radius_mm();
  return a > 0 ? 3 * force_n / (2 * kPi * a * a) * kKpaPerNmm2 : 0.0;
}

double HertzSphere::pressure_kpa(double r_mm) const {
  const double a = contact_radius_mm();
  if (!(std::abs(r_mm) < a)) return 0.0;
  return peak_pressure_kpa() * std::sqrt(1 - r_mm * r_mm / (a * a));
}

double von_mises(const Stress& s) {
  const double dxy = s[0] - s[1], dyz = s[1] - s[2], dzx = s[2] - s[0];
  return std::sqrt(0.5 * (dxy * dxy + dyz * dyz + dzx * dzx) + 3 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
}

Stress boussinesq_point(double force_n, double dx, double dy, double z, double nu) {
  require(z > 0, "contact::boussinesq_point: z must be > 0 (below the surface)");
  const double r2 = dx * dx + dy * dy, r = std::sqrt(r2);
  const double rho2 = r2 + z * z, rho = std::sqrt(rho2), rho5 = rho2 * rho2 * rho;
  const double P = force_n / (2 * kPi) * kKpaPerNmm2;
  const double inv_term = 1 / (rho * (rho + z));  // (1 − z/ρ) / r²
  const double s_r = P * ((1 - 2 * nu) * inv_term - 3 * z * r2 / rho5);
  const double s_t = -P * (1 - 2 * nu) * (inv_term - z / (rho2 * rho));
  const double s_z = -3 * P * z * z * z / rho5;
  const double t_rz = -3 * P * r * z * z / rho5;
  const double c = r > 0 ? dx / r : 1.0, s = r > 0 ? dy / r : 0.0;
  return {s_r * c * c + s_t * s * s, s_r * s * s + s_t * c * c, s_z, (s_r - s_t) * s * c, t_rz * c, t_rz * s};
}

Stress punch_stress(const FlatPunch& punch, double r_mm, double z_mm, double nu, int n_theta, int n_phi) {
  require(n_theta > 0 && n_phi > 0, "contact::punch_stress: node counts must be > 0");
  Stress sum{};
  const double a = punch.radius_mm, dth = kPi / 2 / n_theta, dph = 2 * kPi / n_phi;
  for (int i = 0; i < n_theta; ++i) {
    const double th = (i + 0.5) * dth, rp = a * std::sin(th);
    const double dF = punch.force_n / (2 * kPi) * std::sin(th) * dth * dph;
    for (int j = 0; j < n_phi; ++j) {
      const double ph = (j + 0.5) * dph;
      const Stress s = boussinesq_point(dF, r_mm - rp * std::cos(ph), -rp * std::sin(ph), z_mm, nu);
      for (int k = 0; k < 6; ++k) sum[k] += s[k];
    }
  }
  return sum;
}

ChartField von_mises_at_depth(const ChartField& pressure, double z_mm, double nu, double kernel_radius_mm) {
  const ChartGrid& g = pressure.grid;
  require(z_mm > 0 && kernel_radius_mm > 0 && g.texel_mm > 0 && g.width > 0 && g.height > 0 &&
              pressure.value.size() == g.size(),
          "contact::von_mises_at_depth: needs z_mm > 0, kernel_radius_mm > 0 and a filled grid");
  cv::Mat force(g.height, g.width, CV_64F);  // N per texel
  const double area = g.texel_mm * g.texel_mm;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const float p = pressure.value[g.index(i, j)];
      force.at<double>(j, i) = std::isfinite(p) ? p * area / kKpaPerNmm2 : 0.0;
    }
  const int k = std::max(1, static_cast<int>(std::ceil(kernel_radius_mm / g.texel_mm)));
  std::array<cv::Mat, 6> kernel;
  for (auto& m : kernel) m = cv::Mat::zeros(2 * k + 1, 2 * k + 1, CV_64F);
  // filter2D correlates: out(x) = Σ_d K(d)·f(x + d); a source at x + d lies at offset −d from x.
  for (int v = -k; v <= k; ++v)
    for (int u = -k; u <= k; ++u) {
      Stress acc{};
      for (int sv = -1; sv <= 1; ++sv)
        for (int su = -1; su <= 1; ++su) {
          const Stress s = boussinesq_point(1.0 / 9, -(u + su / 3.0) * g.texel_mm, -(v + sv / 3.0) * g.texel_mm, z_mm, nu);
          for (int c = 0; c < 6; ++c) acc[c] += s[c];
        }
      for (int c = 0; c < 6; ++c) kernel[c].at<double>(v + k, u + k) = acc[c];
    }
  std::array<cv::Mat, 6> stress;
  for (int c = 0; c < 6; ++c)
    cv::filter2D(force, stress[c], CV_64F, kernel[c], cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
  ChartField out;
  out.grid = g;
  out.value.assign(g.size(), std::numeric_limits<float>::quiet_NaN());
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      if (!std::isfinite(pressure.value[g.index(i, j)])) continue;
      Stress s;
      for (int c = 0; c < 6; ++c) s[c] = stress[c].at<double>(j, i);
      out.value[g.index(i, j)] = static_cast<float>(von_mises(s));
    }
  return out;
}

}  // namespace clearfit::contact
