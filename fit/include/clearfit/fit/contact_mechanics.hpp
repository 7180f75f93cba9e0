#pragma once
// Closed forms of elastic contact on a half-space (Johnson, "Contact
// Mechanics", 1985, ch. 3-4; Sneddon 1946), for the simulator's pressure
// fields and their subsurface stress (the study's edge ring), and for tests.
//
// Units: lengths mm, force N, moduli and stresses kPa (1 N/mm² = 1000 kPa).
// Stresses are compressive-positive for σz on the axis helpers; the stress
// tensor helpers use the elastic sign convention (tension positive), so the
// stress under a pressed surface has σzz < 0.
#include <clearfit/fit/chart_field.hpp>

#include <Eigen/Core>
#include <array>

namespace clearfit::contact {

/// Mean pressure (kPa) of force `force_n` spread over a disc of `radius_mm`.
double mean_pressure_kpa(double force_n, double radius_mm);

/// Plane-strain modulus E* = E / (1 − ν²) (same unit as E).
double plane_strain_modulus(double youngs, double poisson);

/// Rigid flat cylindrical punch of radius a on an elastic half-space (Sneddon):
/// p(r) = F / (2πa·√(a² − r²)) for r < a, 0 outside. The rim is singular; with
/// rim_cap_ratio > 0 the pressure is capped at rim_cap_ratio · p_mean (the
/// capped field carries slightly less than F: see punch_capped_force_fraction).
struct FlatPunch {
  double radius_mm = 2.5;
  double force_n = 0.5;
  double rim_cap_ratio = 0;  ///< 0: no cap (the integrable singularity)
  /// Surface pressure (kPa) at distance r_mm from the axis.
  double pressure_kpa(double r_mm) const;
  /// Normal stress magnitude on the axis at depth z (compressive, kPa):
  /// F(a² + 3z²) / (2π(a² + z²)²); equals p(0) = p_mean/2 at z = 0 and
  /// peaks at 1.125·p(0) = 0.5625·p_mean at z = a/√3.
  double axis_sigma_z_kpa(double z_mm) const;
  /// Indentation depth d (mm) for modulus E* (kPa): F = 2aE*d.
  double indentation_mm(double e_star_kpa) const;
  /// Fraction of F the capped field carries: 1 − 1/(4c) for cap c ≥ 1/2 (1 without a cap).
  double capped_force_fraction() const;
};

/// Hertz contact of a rigid sphere of radius R: a = (3FR / (4E*))^{1/3},
/// p0 = 3F / (2πa²), p(r) = p0·√(1 − r²/a²).
struct HertzSphere {
  double sphere_radius_mm = 10;
  double force_n = 0.5;
  double e_star_kpa = 100;  ///< plane-strain modulus of the skin (E* = E/(1 − ν²))
  double contact_radius_mm() const;
  double peak_pressure_kpa() const;
  double pressure_kpa(double r_mm) const;
};

/// Stress tensor (kPa, tension positive) as xx, yy, zz, xy, xz, yz.
using Stress = std::array<double, 6>;
/// Von Mises equivalent stress of a tensor (kPa).
double von_mises(const Stress& s);

/// Boussinesq: stress at (dx, dy, z) (mm, z > 0 into the body) under a normal
/// point force `force_n` pressing at the origin of the surface, Poisson ratio
/// nu (Johnson eq. 3.4, rotated from cylindrical to Cartesian axes). The
/// r → 0 terms use the stable form (1 − z/ρ)/r² = 1/(ρ(ρ + z)).
Stress boussinesq_point(double force_n, double dx, double dy, double z, double nu);

/// Stress under an axisymmetric Sneddon punch at radius r_mm (on the x axis)
/// and depth z_mm, by Boussinesq superposition in polar quadrature with the
/// substitution r' = a·sin θ that removes the rim singularity (n_theta × n_phi
/// nodes, midpoint rule). Accurate to ~1e-3 relative for z ≳ a/50 with the
/// defaults; the reference for the grid convolution below.
Stress punch_stress(const FlatPunch& punch, double r_mm, double z_mm, double nu, int n_theta = 400, int n_phi = 720);

/// Von Mises stress (kPa) at depth z_mm under an arbitrary surface pressure
/// field on the chart grid (kPa; NaN texels count as 0), by superposing the
/// Boussinesq tensor of every texel's force (p·texel area, the kernel averaged
/// over 3×3 points of a texel) — six convolutions (cv::filter2D, DFT for large
/// kernels) with the kernel cut at `kernel_radius_mm`. Same grid as the input;
/// NaN where the input is NaN. Treats the chart as flat (curvature ignored).
ChartField von_mises_at_depth(const ChartField& pressure_kpa, double z_mm, double nu,
                              double kernel_radius_mm = 3.0);

}  // namespace clearfit::contact
