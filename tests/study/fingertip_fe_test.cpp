// The layered finite-element punch model against closed forms on a homogeneous
// body (Sneddon's flat punch and Boussinesq's point load, fit/contact_mechanics),
// mesh convergence, and the study's edge concentration on its layered fingertip.
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/study/analysis.hpp>
#include <clearfit/study/fingertip_fe.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace clearfit::study {
namespace {

/// A homogeneous body far larger than the load (rigid base 30 mm down, rim 30 mm out).
PunchFeOptions homogeneous(double nu) {
  PunchFeOptions o;
  o.layers = {{"homogeneous", 30.0, 100.0, nu}};
  o.domain_radius_mm = 30;
  o.punch_radius_mm = 1.0;
  o.depth_mm = 0.05;
  o.element_mm = 0.05;
  o.roi_radius_mm = 3;
  o.roi_depth_mm = 3;
  o.grid_radius_mm = 3;
  o.grid_depth_mm = 3;
  o.grid_step_mm = 0.25;
  return o;
}

TEST(FingertipFe, FlatPunchOnAHomogeneousBodyIsSneddons) {
  const double nu = 0.3;
  const PunchFeOptions o = homogeneous(nu);
  const PunchStress s = solve_punch_stress(o);
  const double e_star = contact::plane_strain_modulus(100.0, nu);
  const double f_sneddon = 2 * o.punch_radius_mm * e_star * o.depth_mm * 1e-3;  // F = 2aE*d (kPa·mm² → N)
  std::printf("punch force %.6f N, Sneddon %.6f N (%d elements, %d dofs)\n", s.force_n, f_sneddon, s.elements, s.dofs);
  // A body of finite depth on a rigid base is stiffer than the half-space: a few per cent at H = 30a.
  EXPECT_NEAR(s.force_n / f_sneddon, 1.0, 0.05);
  // Stress under the punch against the closed form with the FE's own force (shape, not scale).
  const contact::FlatPunch punch{o.punch_radius_mm, s.force_n, 0};
  for (std::size_t k = 2; k < s.depth_mm.size(); ++k)      // z ≥ 0.5 mm: away from the rim singularity
    for (std::size_t i = 0; i < s.r_mm.size(); i += 2) {
      const double z = s.depth_mm[k], r = s.r_mm[i];
      const double ref = contact::von_mises(contact::punch_stress(punch, r, z, nu, 200, 360));
      EXPECT_NEAR(s.vm(k, i), ref, 0.06 * ref + 0.02) << "r " << r << " z " << z;
    }
  for (std::size_t k = 2; k < s.depth_mm.size(); ++k)
    EXPECT_NEAR(-s.sigma_z_kpa[k * s.r_mm.size()], punch.axis_sigma_z_kpa(s.depth_mm[k]),
                0.04 * punch.axis_sigma_z_kpa(s.depth_mm[k]))
        << "axis, z " << s.depth_mm[k];
}

TEST(FingertipFe, DiscLoadIsBoussinesqsSuperposition) {
  const double nu = 0.45, b = 0.2, p = 100.0;
  PunchFeOptions o = homogeneous(nu);
  o.layers[0].thickness_mm = o.domain_radius_mm = 15;
  o.element_mm = 0.025;  // four elements across the loaded disc (at 0.05 the axis stress at z = 5b is 8 % low)
  const PunchStress s = solve_disc_load_stress(o, b, p);
  for (std::size_t k = 4; k < s.depth_mm.size(); ++k) {  // z ≥ 1 mm = 5b
    const double z = s.depth_mm[k];
    // On the axis: the uniform disc's closed form p(1 − z³/(b² + z²)^{3/2}) (Johnson 3.4, integrated).
    const double disc = p * (1 - z * z * z / std::pow(b * b + z * z, 1.5));
    EXPECT_NEAR(-s.sigma_z_kpa[k * s.r_mm.size()], disc, 0.015 * disc) << "axis, z " << z;
    // Ten radii away, the disc acts as Boussinesq's point force.
    for (std::size_t i = 0; i < s.r_mm.size(); ++i) {
      const double r = s.r_mm[i];
      if (std::hypot(r, z) < 10 * b) continue;
      const contact::Stress ref = contact::boussinesq_point(s.force_n, r, 0, z, nu);
      EXPECT_NEAR(s.sigma_z_kpa[k * s.r_mm.size() + i], ref[2], 0.03 * std::abs(ref[2]) + 0.005) << "r " << r << " z " << z;
    }
  }
}

TEST(FingertipFe, LayeredModelConvergesAndLoadsTheRim) {
  PunchFeOptions coarse;  // the study's layers, a 4 mm punch 1 mm deep
  coarse.element_mm = 0.1;
  PunchFeOptions fine = coarse;
  fine.element_mm = 0.05;
  const PunchStress a = solve_punch_stress(coarse), b = solve_punch_stress(fine);
  std::printf("4 mm punch, 1 mm deep: force %.4f N (h 0.1), %.4f N (h 0.05)\n", a.force_n, b.force_n);
  EXPECT_NEAR(a.force_n / b.force_n, 1.0, 0.01);
  // Away from the rim singularity the stress field agrees between the meshes (3 % of the value, or
  // 0.5 % of the field's peak where the value is near a minimum of von Mises).
  const double peak_vm = *std::max_element(b.von_mises_kpa.begin(), b.von_mises_kpa.end());
  for (std::size_t k = 4; k < b.depth_mm.size(); k += 4)
    for (std::size_t i = 0; i < b.r_mm.size(); i += 10)
      if (std::abs(b.r_mm[i] - fine.punch_radius_mm) > 0.5)
        EXPECT_NEAR(a.vm(k, i), b.vm(k, i), 0.03 * b.vm(k, i) + 0.005 * peak_vm) << "r " << b.r_mm[i] << " depth " << b.depth_mm[k];
  // The study's finding: under a flat punch the shallow stress concentrates at the rim, not the centre.
  const std::size_t shallow = 2;  // 0.1 mm
  std::size_t peak = 0;
  for (std::size_t i = 0; i < b.r_mm.size(); ++i)
    if (b.vm(shallow, i) > b.vm(shallow, peak)) peak = i;
  EXPECT_NEAR(b.r_mm[peak], fine.punch_radius_mm, 0.25);
  EXPECT_GT(b.vm(shallow, peak), 2 * b.vm(shallow, 0));
  std::printf("von Mises at 0.1 mm depth: centre %.1f kPa, rim (r = %.2f mm) %.1f kPa\n", b.vm(shallow, 0), b.r_mm[peak],
              b.vm(shallow, peak));
}

TEST(FingertipFe, RefusesInvalidOptions) {
  PunchFeOptions o;
  o.depth_mm = 100;
  EXPECT_THROW(solve_punch_stress(o), std::invalid_argument);
  o = PunchFeOptions();
  o.layers[1].poisson = 0.5;
  EXPECT_THROW(solve_punch_stress(o), std::invalid_argument);
  o = PunchFeOptions();
  o.punch_radius_mm = 0;
  EXPECT_THROW(solve_punch_stress(o), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit::study

namespace clearfit::study {
namespace {

TEST(StressPls, ShallowStressExplainsAShallowProfile) {
  PunchFeOptions o;  // 4 mm punch, 1 mm deep, coarse mesh
  o.element_mm = 0.1;
  const PunchStress s = solve_punch_stress(o);
  // A colour profile that follows the stress 0.1 mm deep (blurred edge, saturating), sampled as the study does.
  RadialProfile colour;
  for (int k = -140; k <= 140; ++k) {
    const double r = std::abs(k * 0.05);
    const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(std::lround(r / o.grid_step_mm)), s.r_mm.size() - 1);
    colour.position_mm.push_back(k * 0.05);
    colour.value.push_back(0.05 * std::tanh(s.vm(2, i) / 30.0));
    colour.segments.push_back(9);
  }
  const StressPls pls = stress_profile_pls(colour, s, 2);
  std::printf("PLS R² %.3f over %d radii; VIP > 1 at %s\n", pls.r2, pls.samples, pls.important_depths().c_str());
  EXPECT_GT(pls.r2, 0.9);
  double shallow = 0, deep = 0;  // the largest VIP down to 0.3 mm, and below 1 mm
  for (std::size_t k = 0; k < pls.depth_mm.size(); ++k) {
    if (pls.depth_mm[k] <= 0.3) shallow = std::max(shallow, pls.vip[k]);
    if (pls.depth_mm[k] >= 1.0) deep = std::max(deep, pls.vip[k]);
  }
  EXPECT_GT(shallow, 1.0);
  EXPECT_GT(shallow, deep);
  RadialProfile empty = colour;
  for (double& v : empty.value) v = NAN;
  EXPECT_THROW(stress_profile_pls(empty, s, 2), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit::study
