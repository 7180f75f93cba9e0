#pragma once
// Subsurface stress under the study's punch (PAPER.md, "Simulation and
// regression"): an axisymmetric, layered, linear-elastic finite-element model
// of the fingertip pad (GetFEM: P2 triangles, the weak form with the hoop
// strain u_r/r, MUMPS), pressed by a rigid flat cylindrical punch to a depth.
// Contact without penetration and without friction: under the punch face the
// normal displacement is the punch's depth (a Lagrange multiplier), the
// tangential traction is free; elsewhere the surface is free. The axis has
// u_r = 0; the base of the deepest layer is fixed; the outer rim is free.
// Verified against Sneddon's flat punch and Boussinesq's point load on a
// homogeneous half-space (fit/contact_mechanics) and by mesh convergence.
#include <string>
#include <vector>

namespace clearfit::study {

struct TissueLayer {
  std::string name;
  double thickness_mm = 1;
  double youngs_kpa = 100;
  double poisson = 0.48;
};

/// The study's Table 1 moduli and Poisson ratios. Thicknesses are not in the
/// paper; typical fingertip-pad values from the literature, stated as
/// assumptions: epidermis 0.75 mm (glabrous skin, 0.5–1 mm), dermis 1.2 mm
/// (1–1.5 mm), subcutaneous pulp 3.0 mm (3–4 mm), then 2 mm of bone (the
/// distal phalanx) on a fixed base. The nail (dorsal) is outside this model.
std::vector<TissueLayer> study_fingertip_layers();

struct PunchFeOptions {
  std::vector<TissueLayer> layers = study_fingertip_layers();
  double punch_radius_mm = 2.0;   ///< half the study's bump width
  double depth_mm = 1.0;          ///< indentation (the study: the bump height, 1 or 2 mm)
  double domain_radius_mm = 15;   ///< outer rim
  double element_mm = 0.1;        ///< element size in the region of interest (below)
  double roi_radius_mm = 8, roi_depth_mm = 2.5;  ///< fine mesh here, growing by 1.25× per element outside
  /// Sampling grid of the stress: r in [0, grid_radius], depth in [0, grid_depth].
  double grid_radius_mm = 7, grid_depth_mm = 2, grid_step_mm = 0.05;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

struct PunchStress {
  std::vector<double> r_mm, depth_mm;      ///< the grid's axes
  std::vector<double> von_mises_kpa;       ///< depth-major: [k * r_mm.size() + i]
  std::vector<double> sigma_z_kpa;         ///< axial stress (compression negative), same layout
  double force_n = 0;                      ///< punch force (from the strain energy: F = 2U/d)
  int elements = 0, dofs = 0;
  double vm(std::size_t depth_index, std::size_t r_index) const { return von_mises_kpa[depth_index * r_mm.size() + r_index]; }
};

/// Solves the model. Throws std::invalid_argument for invalid options and
/// std::runtime_error when the solver does not converge.
PunchStress solve_punch_stress(const PunchFeOptions& options);

/// For the verification: a homogeneous body loaded by a uniform pressure
/// `pressure_kpa` on the disc r < load_radius_mm (no punch), same outputs.
PunchStress solve_disc_load_stress(const PunchFeOptions& options, double load_radius_mm, double pressure_kpa);

}  // namespace clearfit::study

namespace clearfit::study {

struct RadialProfile;

/// The study's PLS (PAPER.md): the 1D colour profile (response, folded about
/// the bump centre: the mean of ±r) against the von Mises stress at each depth
/// of the grid (predictors, highly collinear), over the grid's radii where the
/// profile is defined. R² of the fit and VIP per depth.
struct StressPls {
  int components = 0, samples = 0;
  double r2 = 0;
  std::vector<double> depth_mm, vip;
  /// The depths with VIP > 1, as "a–b mm" ranges joined by ", " (empty if none).
  std::string important_depths() const;
};
/// Throws std::invalid_argument when fewer than components + 2 radii are defined.
StressPls stress_profile_pls(const RadialProfile& colour, const PunchStress& stress, int components = 2);

}  // namespace clearfit::study
