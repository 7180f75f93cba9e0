// Closed-form traces against independent computations: trigonometry for the
// slab, rotations and the law of sines for spheres and cylinders, Fermat's
// principle (finite differences), reciprocity and scale invariance.
#include <clearfit/refraction/analytic.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <iostream>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace clearfit::analytic {
namespace {

using optics::Indices;
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180;
constexpr std::uint64_t kSeed = 20240612;

double rel_err(const Vec3& a, const Vec3& b, double scale) { return (a - b).norm() / scale; }

// Textbook quadratic for |o + t·u| = r (the library uses a different, robust form).
std::optional<std::pair<double, double>> textbook_roots(const Vec3& o, const Vec3& u, double r) {
  const double a = u.dot(u), b = o.dot(u), c = o.dot(o) - r * r, disc = b * b - a * c;
  if (disc < 0 || a == 0) return std::nullopt;
  return std::pair{(-b - std::sqrt(disc)) / a, (-b + std::sqrt(disc)) / a};
}
Vec3 xz(const Vec3& v) { return {v.x(), 0, v.z()}; }

// Unpolarised Fresnel transmittance from the sine/tangent form (independent of optics.cpp).
double fresnel_T(double theta_i, double n1, double n2) {
  if (theta_i == 0) return 1 - std::pow((n1 - n2) / (n1 + n2), 2);
  const double tt = std::asin(n1 * std::sin(theta_i) / n2);
  return 1 - 0.5 * (std::pow(std::sin(theta_i - tt) / std::sin(theta_i + tt), 2) +
                    std::pow(std::tan(theta_i - tt) / std::tan(theta_i + tt), 2));
}

// ---------------------------------------------------------------- slab ----

TEST(Slab, MatchesTrigonometryAtManyTilts) {
  const double h = 2.0;
  const Indices n{1.0, 1.49, 1.4};
  const Vec3 origin(1.5, -0.7, 12.0);
  double worst = 0;
  for (int deg = 0; deg <= 89; ++deg) {
    for (double psi_deg : {0.0, 37.0, 145.0, 260.0}) {
      const double theta = deg * kDeg, psi = psi_deg * kDeg;
      const Vec3 u(std::cos(psi), std::sin(psi), 0);
      const Vec3 d = std::sin(theta) * u - std::cos(theta) * Vec3::UnitZ();
      const SkinHit hit = trace_slab(origin, d, h, n);
      ASSERT_TRUE(hit.valid) << deg << "° " << to_string(hit.reason);
      // Independent: Snell's law in angles, then straight lines.
      const double theta_t = std::asin(std::sin(theta) / 1.49);
      const Vec3 entry = origin + (origin.z() - h) * std::tan(theta) * u - (origin.z() - h) * Vec3::UnitZ();
      const Vec3 skin = entry + h * std::tan(theta_t) * u - h * Vec3::UnitZ();
      const double scale = std::max(1.0, entry.norm());
      const double errs[] = {
          rel_err(hit.entry_point, entry, scale),
          rel_err(hit.skin_point, skin, scale),
          std::abs(hit.incidence_rad - theta),
          std::abs(hit.refraction_rad - theta_t),
          std::abs(hit.contact_rad - theta_t),
          std::abs(hit.exit_rad - std::asin(1.49 * std::sin(theta_t) / 1.4)),
          // The textbook lateral shift: distance of the skin point from the undeviated ray.
          std::abs((hit.skin_point - origin).cross(d).norm() -
                   h * std::sin(theta - theta_t) / std::cos(theta_t)),
          std::abs(hit.transmittance - fresnel_T(theta, 1.0, 1.49) * fresnel_T(theta_t, 1.49, 1.4)) ,
          std::abs(hit.optical_path_mm - ((origin.z() - h) / std::cos(theta) + 1.49 * h / std::cos(theta_t))) / scale,
      };
      for (double e : errs) worst = std::max(worst, e);
      for (double e : errs) EXPECT_LE(e, 1e-12) << deg << "° azimuth " << psi_deg;
      // The closed form used by the fast path.
      const auto shift = slab_shift(h, theta, 1.0, 1.49);
      ASSERT_TRUE(shift);
      EXPECT_NEAR(shift->theta_t_rad, theta_t, 1e-15);
      EXPECT_NEAR(shift->lateral_mm, (hit.skin_point - origin).cross(d).norm(), 1e-12);
      const Vec3 straight = origin + (origin.z() / std::cos(theta)) * d;  // undeviated hit on z = 0
      EXPECT_NEAR(shift->offset_mm, (straight - hit.skin_point).norm(), 1e-12 * scale);
      EXPECT_GT((straight - hit.skin_point).dot(u), -1e-12);  // the skin is seen nearer than it is
    }
  }
  std::cout << "slab: worst deviation from trigonometry " << worst << std::endl;
}

TEST(Slab, EntryTirFromDenseMedium) {
  // Camera in immersion oil denser than the part: rays beyond asin(n_part/n_medium) reflect.
  const Indices n{1.6, 1.49, 1.6};
  const double theta_c = std::asin(1.49 / 1.6);
  for (double delta : {1e-12, 1e-9, 1e-6}) {
    const auto ray = [&](double t) { return Vec3(std::sin(t), 0, -std::cos(t)); };
    const SkinHit in = trace_slab({0, 0, 10}, ray(theta_c - delta), 2.0, n);
    const SkinHit out = trace_slab({0, 0, 10}, ray(theta_c + delta), 2.0, n);
    EXPECT_TRUE(in.valid) << delta << " " << to_string(in.reason);
    EXPECT_TRUE(in.skin_point.allFinite());
    EXPECT_EQ(out.reason, Reason::tir) << delta;
    EXPECT_TRUE(out.entry_point.allFinite());
    EXPECT_TRUE(std::isnan(out.skin_point.x()));
  }
  EXPECT_FALSE(slab_shift(2.0, theta_c + 1e-9, 1.6, 1.49).has_value());
  EXPECT_TRUE(slab_shift(2.0, theta_c - 1e-9, 1.6, 1.49).has_value());
}

TEST(Slab, MissesAndBadInput) {
  EXPECT_EQ(trace_slab({0, 0, 5}, {1, 0, 0}, 2.0).reason, Reason::miss);
  EXPECT_EQ(trace_slab({0, 0, 5}, {0, 0.1, 1}, 2.0).reason, Reason::miss);
  EXPECT_FALSE(trace_slab({0, 0, 5}, {0, 0, 1}, 2.0).valid);
  EXPECT_THROW(trace_slab({0, 0, 1}, {0, 0, -1}, 2.0), std::invalid_argument);  // inside
  EXPECT_THROW(trace_slab({0, 0, 5}, {0, 0, 0}, 2.0), std::invalid_argument);
  EXPECT_THROW(trace_slab({0, 0, 5}, {0, 0, -1}, 0.0), std::invalid_argument);
  EXPECT_THROW(trace_slab({0, 0, 5}, {0, 0, -1}, 2.0, Indices{1.0, 0.5, 1.4}), std::invalid_argument);
  EXPECT_THROW(slab_shift(2.0, kPi / 2, 1.0, 1.49), std::invalid_argument);
  // Matched indices: a straight line, everything transmitted.
  const SkinHit same = trace_slab({0, 0, 5}, {0.3, 0.2, -1}, 2.0, Indices{1.49, 1.49, 1.49});
  ASSERT_TRUE(same.valid);
  EXPECT_LT(same.refracted_dir.cross(Vec3(0.3, 0.2, -1).normalized()).norm(), 1e-16);
  EXPECT_EQ(same.transmittance, 1.0);
  // Normal incidence: R = ((n1 − n2)/(n1 + n2))² at both faces.
  const SkinHit down = trace_slab({3, 4, 5}, {0, 0, -1}, 2.0);
  ASSERT_TRUE(down.valid);
  EXPECT_EQ(down.skin_point, Vec3(3, 4, 0));
  EXPECT_NEAR(down.transmittance, (1 - std::pow(0.49 / 2.49, 2)) * (1 - std::pow(0.09 / 2.89, 2)), 1e-15);
}

// --------------------------------------------------------------- wedge ----

TEST(Wedge, ZeroTiltIsTheSlab) {
  std::mt19937_64 rng(kSeed);
  std::uniform_real_distribution<double> uni(-1, 1);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 o(5 * uni(rng), 5 * uni(rng), 10), d(uni(rng), uni(rng), -1);
    const SkinHit a = trace_wedge(o, d, 2.0, 0.0), b = trace_slab(o, d, 2.0);
    ASSERT_EQ(a.reason, b.reason);
    EXPECT_LT((a.skin_point - b.skin_point).norm(), 1e-13);
    EXPECT_EQ(a.transmittance, b.transmittance);
  }
}

// A pinhole camera looking down through a wedge: the image column where the
// part→skin critical angle is crossed is known in closed form; classification
// flips exactly there, both on pixel grid points and 1e-6 px either side.
TEST(Wedge, ImageCrossesCriticalAngleAtKnownPixel) {
  struct Case {
    double tilt_deg;
    Indices n;
  };
  for (const Case& c : {Case{-20, {1.0, 1.49, 1.0}}, Case{-50, {1.0, 1.49, 1.4}},
                        Case{20, {1.0, 1.49, 1.0}}}) {
    const double tilt = c.tilt_deg * kDeg, h = 5.0, f = 800.0, cx = 639.5;
    const Vec3 camera(0, 0, 30);
    const TirBounds bounds = wedge_contact_tir_angles(tilt, c.n);
    const double theta_c = std::asin(c.n.n_skin / c.n.n_part);
    // Independent: θ_t = tilt ± θ_c, Snell at the top plane.
    const double expect = std::asin(1.49 * std::sin(c.tilt_deg < 0 ? tilt + theta_c : tilt - theta_c));
    ASSERT_EQ(bounds.theta_pos_rad.has_value(), c.tilt_deg < 0);
    ASSERT_EQ(bounds.theta_neg_rad.has_value(), c.tilt_deg > 0);
    const double theta = c.tilt_deg < 0 ? *bounds.theta_pos_rad : *bounds.theta_neg_rad;
    EXPECT_NEAR(theta, expect, 1e-15);
    // The image: row through the principal point, dir_in_part = ((u − cx)/f, 0, −1).
    const double u_star = cx + f * std::tan(theta);
    std::cout << "tilt " << c.tilt_deg << "°, n_skin " << c.n.n_skin << ": TIR from θ = "
              << theta / kDeg << "°, pixel u* = " << u_star << std::endl;
    ASSERT_GT(u_star, 0.0);
    ASSERT_LT(u_star, 1280.0);
    const double sign = theta > 0 ? 1 : -1;  // TIR beyond u* in this direction
    auto trace_u = [&](double u) { return trace_wedge(camera, Vec3((u - cx) / f, 0, -1), h, tilt, c.n); };
    for (double u : {std::floor(u_star) - 1, std::floor(u_star), std::ceil(u_star), std::ceil(u_star) + 1,
                     u_star - 1e-6, u_star + 1e-6}) {
      const SkinHit hit = trace_u(u);
      const bool beyond = sign * (u - u_star) > 0;
      EXPECT_EQ(hit.reason, beyond ? Reason::contact_tir : Reason::ok) << "u = " << u;
      EXPECT_TRUE(hit.skin_point.allFinite());
      const double theta_t = std::asin(std::sin(std::atan((u - cx) / f)) / 1.49);
      EXPECT_NEAR(hit.contact_rad, std::abs(theta_t - tilt), 1e-12);
      EXPECT_EQ(hit.transmittance == 0, beyond);
    }
    // Bisection on the classification finds u* to 1e-9 px.
    double lo = cx, hi = cx + sign * 640;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (trace_u(mid).valid ? lo : hi) = mid;
    }
    EXPECT_NEAR(lo, u_star, 1e-9);
    // Angles within 1e-12 rad either side.
    const SkinHit below = trace_wedge(camera, Vec3(std::sin(theta - sign * 1e-12), 0, -std::cos(theta)), h, tilt, c.n);
    const SkinHit above = trace_wedge(camera, Vec3(std::sin(theta + sign * 1e-12), 0, -std::cos(theta)), h, tilt, c.n);
    EXPECT_EQ(below.reason, Reason::ok);
    EXPECT_EQ(above.reason, Reason::contact_tir);
  }
}

TEST(Wedge, BeyondTheRidgeMisses) {
  // Tilt 20°: the contact plane reaches the top plane at x = h / tan 20° ≈ 13.7.
  EXPECT_EQ(trace_wedge({20, 0, 30}, {0, 0, -1}, 5.0, 20 * kDeg).reason, Reason::miss);
  EXPECT_TRUE(trace_wedge({10, 0, 30}, {0, 0, -1}, 5.0, 20 * kDeg).valid);
  EXPECT_FALSE(wedge_contact_tir_angles(0.0, Indices{1.0, 1.49, 1.55}).theta_pos_rad.has_value());
  EXPECT_THROW(trace_wedge({0, 0, 30}, {0, 0, -1}, 5.0, kPi / 2), std::invalid_argument);
}

// -------------------------------------------------------------- spheres ----

Vec3 on_sphere_param(const Vec3& entry, double u, double v) {
  const Vec3 nrm = entry.normalized();
  const Vec3 e1 = nrm.unitOrthogonal(), e2 = nrm.cross(e1);
  return entry.norm() * (entry + u * e1 + v * e2).normalized();
}

TEST(Ball, MatchesRotationClosedForm) {
  // In the plane of incidence the chord inside a sphere subtends π − 2θ_t:
  // the skin point is the entry point rotated by that angle about entry × d_t.
  std::mt19937_64 rng(kSeed + 1);
  std::uniform_real_distribution<double> uni(-1, 1);
  const double r = 10;
  const Indices n{1.0, 1.49, 1.4};
  double worst = 0;
  int valid = 0;
  for (int k = 0; k < 2000; ++k) {
    const Vec3 o(3 * uni(rng), 3 * uni(rng), 40);
    const Vec3 d = (Vec3(9.9 * uni(rng), 9.9 * uni(rng), 0) - o).normalized();
    const SkinHit hit = trace_ball(o, d, r, n);
    const auto roots = textbook_roots(o, d, r);
    ASSERT_EQ(roots.has_value(), hit.reason != Reason::miss);
    if (!roots) continue;
    const Vec3 entry = o + roots->first * d;
    const double theta_i = std::acos(-d.dot(entry / r));
    const double theta_t = std::asin(std::sin(theta_i) / 1.49);
    // Refracted direction: rotate −normal by θ_t towards d inside the plane of incidence.
    const Vec3 axis = entry.cross(d).normalized();
    const Vec3 dt = Eigen::AngleAxisd(-theta_t, axis) * Vec3(-entry / r);
    const Vec3 skin = Eigen::AngleAxisd(kPi - 2 * theta_t, entry.cross(dt).normalized()) * entry;
    const bool tir = 1.49 * std::sin(theta_t) > 1.4;
    ASSERT_EQ(hit.reason, tir ? Reason::contact_tir : Reason::ok);
    valid += hit.valid;
    const double errs[] = {rel_err(hit.entry_point, entry, r), rel_err(hit.skin_point, skin, r),
                           rel_err(hit.refracted_dir, dt, 1), std::abs(hit.contact_rad - theta_t),
                           std::abs(hit.refraction_rad - theta_t)};
    for (double e : errs) worst = std::max(worst, e);
    for (double e : errs) ASSERT_LE(e, 1e-12) << "ray " << k;
  }
  std::cout << "ball: " << valid << " valid, worst deviation " << worst << std::endl;
  EXPECT_GT(valid, 1000);
}

TEST(SphericalShell, MatchesLawOfSines) {
  // Triangle centre–entry–skin: sin β = r_out·sin θ_t / r_in at the skin, and
  // the chord is r_out·cos θ_t − sqrt(r_in² − r_out²·sin²θ_t).
  std::mt19937_64 rng(kSeed + 2);
  std::uniform_real_distribution<double> uni(-1, 1);
  const double r_in = 20, r_out = 23, cap = 40;
  const Indices n{1.0, 1.49, 1.4};
  int counts[5] = {};
  double worst = 0;
  for (int k = 0; k < 4000; ++k) {
    const Vec3 o(4 * uni(rng), 4 * uni(rng), 60);
    const Vec3 d = (Vec3(17 * uni(rng), 17 * uni(rng), 18) - o).normalized();
    const SkinHit hit = trace_spherical_shell(o, d, r_in, r_out, cap, n);
    ++counts[static_cast<int>(hit.reason)];
    if (hit.reason != Reason::ok && hit.reason != Reason::contact_tir) continue;
    const double st = std::sin(hit.refraction_rad);
    EXPECT_NEAR(std::sin(hit.incidence_rad), 1.49 * st, 1e-14);
    const double beta = std::asin(r_out * st / r_in);
    const double chord = r_out * std::cos(hit.refraction_rad) - std::sqrt(r_in * r_in - r_out * r_out * st * st);
    const double errs[] = {std::abs(hit.contact_rad - beta),
                           std::abs((hit.skin_point - hit.entry_point).norm() - chord) / r_out,
                           std::abs(hit.skin_point.norm() - r_in) / r_in,
                           std::abs(hit.entry_point.norm() - r_out) / r_out};
    for (double e : errs) worst = std::max(worst, e);
    for (double e : errs) ASSERT_LE(e, 1e-12) << "ray " << k;
    // Within the cap at both ends.
    EXPECT_LE(std::acos(hit.entry_point.z() / r_out), cap * kDeg + 1e-12);
    EXPECT_LE(std::acos(hit.skin_point.z() / r_in), cap * kDeg + 1e-12);
  }
  std::cout << "shell: ok " << counts[0] << ", miss " << counts[1] << ", exit_elsewhere " << counts[3]
            << ", contact_tir " << counts[4] << "; worst deviation " << worst << std::endl;
  EXPECT_GT(counts[0], 1000);
  EXPECT_GT(counts[1], 100);
  EXPECT_GT(counts[3], 10);
}

TEST(SphericalShell, NamedCases) {
  const double r_in = 20, r_out = 23, cap = 30;
  // On the axis: straight down, normal incidence at both faces.
  const SkinHit axis = trace_spherical_shell({0, 0, 60}, {0, 0, -1}, r_in, r_out, cap);
  ASSERT_TRUE(axis.valid);
  EXPECT_EQ(axis.entry_point, Vec3(0, 0, r_out));
  EXPECT_EQ(axis.skin_point, Vec3(0, 0, r_in));
  EXPECT_EQ(axis.contact_normal, Vec3(0, 0, -1));
  // Aimed at the outer sphere outside the cap: no outer surface there.
  const Vec3 outside = r_out * Vec3(std::sin(35 * kDeg), 0, std::cos(35 * kDeg));
  EXPECT_EQ(trace_spherical_shell({0, 0, 60}, outside - Vec3(0, 0, 60), r_in, r_out, cap).reason, Reason::miss);
  // Entering just inside the rim and heading outwards: leaves through the rim.
  const Vec3 rim = r_out * Vec3(std::sin(29.5 * kDeg), 0, std::cos(29.5 * kDeg));
  const SkinHit through_rim = trace_spherical_shell({-30, 0, 60}, rim - Vec3(-30, 0, 60), r_in, r_out, cap);
  EXPECT_EQ(through_rim.reason, Reason::exit_elsewhere);
  EXPECT_TRUE(through_rim.entry_point.allFinite());
  // A thick shell: a steep ray passes beside the inner sphere (r_out sin θ_t > r_in).
  const Vec3 p = 20.0 * Vec3(std::sin(30 * kDeg), 0, std::cos(30 * kDeg));
  const SkinHit beside = trace_spherical_shell(p + 40 * Vec3(1, 0, 0.2).normalized(), Vec3(-1, 0, -0.2),
                                               5, 20, 80);
  EXPECT_EQ(beside.reason, Reason::exit_elsewhere);
  EXPECT_THROW(trace_spherical_shell({0, 0, 60}, {0, 0, -1}, 23, 20, 30), std::invalid_argument);
  EXPECT_THROW(trace_spherical_shell({0, 0, 60}, {0, 0, -1}, 20, 23, 90), std::invalid_argument);
  EXPECT_THROW(trace_spherical_shell({0, 0, 22}, {0, 0, -1}, 20, 23, 30), std::invalid_argument);
}

// ------------------------------------------------------------ cylinders ----

TEST(CylindricalShell, MatchesLawOfSinesInTheCrossSection) {
  std::mt19937_64 rng(kSeed + 3);
  std::uniform_real_distribution<double> uni(-1, 1);
  const double r_in = 30, r_out = 33;
  int valid = 0;
  for (int k = 0; k < 2000; ++k) {
    const double y = 15 * uni(rng);
    const Vec3 o(5 * uni(rng), y, 90);
    const Vec3 d = (Vec3(25 * uni(rng), y, 30) - o).normalized();  // d.y = 0: a 2-D problem
    const SkinHit hit = trace_cylindrical_shell(o, d, r_in, r_out, 120, 40);
    if (!hit.valid) continue;
    ++valid;
    const double st = std::sin(hit.refraction_rad);
    ASSERT_NEAR(std::sin(hit.contact_rad), r_out * st / r_in, 1e-13);
    const double chord = r_out * std::cos(hit.refraction_rad) - std::sqrt(r_in * r_in - r_out * r_out * st * st);
    ASSERT_NEAR((hit.skin_point - hit.entry_point).norm(), chord, 1e-12 * r_out);
    ASSERT_EQ(hit.skin_point.y(), y);
  }
  EXPECT_GT(valid, 1000);
}

// Builds the camera ray that reaches `skin` from entry `p` (outward normal m) by
// refracting the internal direction backwards.
Vec3 camera_dir_for(const Vec3& p, const Vec3& m, const Vec3& skin, const Indices& n) {
  const Vec3 dt = (skin - p).normalized();
  const auto back = optics::refract(-dt, m, n.n_part, n.n_medium);
  EXPECT_TRUE(back.has_value());
  return -*back;
}

TEST(CylindricalShell, BandEndsGapsAndEdges) {
  const Indices n{1.0, 1.49, 1.49};  // index-matched skin side: no contact TIR here
  const double r_in = 5, r_out = 20;
  // A 300° band (gap of 60° about −z). The chord from φ = 148° (outer) to
  // φ = −146° (inner) crosses the gap: both ends are on the band, the path is not.
  const Vec3 p = r_out * Vec3(std::sin(148 * kDeg), 0, std::cos(148 * kDeg));
  const Vec3 s = r_in * Vec3(std::sin(-146 * kDeg), 0, std::cos(-146 * kDeg));
  const Vec3 d = camera_dir_for(p, xz(p).normalized(), s, n);
  const Vec3 o = p - 50 * d;
  const SkinHit tube = trace_cylindrical_shell(o, d, r_in, r_out, 360, 10, n);
  ASSERT_TRUE(tube.valid) << to_string(tube.reason);
  EXPECT_LT((tube.skin_point - s).norm(), 1e-12);
  EXPECT_EQ(trace_cylindrical_shell(o, d, r_in, r_out, 300, 10, n).reason, Reason::exit_elsewhere);
  // From below through the gap of the 300° band: no outer surface there.
  EXPECT_EQ(trace_cylindrical_shell({0, 0, -50}, {0, 0, 1}, r_in, r_out, 300, 10, n).reason, Reason::miss);
  EXPECT_TRUE(trace_cylindrical_shell({0, 0, -50}, {0, 0, 1}, r_in, r_out, 360, 10, n).valid);
  // Across the width: enters near the edge y = 5 and leaves through it.
  const Vec3 q(0, 4.9, r_out);
  const Vec3 dy = camera_dir_for(q, Vec3::UnitZ(), Vec3(0, 8, r_in), n);
  EXPECT_EQ(trace_cylindrical_shell(q - 30 * dy, dy, r_in, r_out, 120, 10, n).reason, Reason::exit_elsewhere);
  EXPECT_TRUE(trace_cylindrical_shell(q - 30 * dy, dy, r_in, r_out, 120, 20, n).valid);
  // Along the axis: never meets the cylinder.
  EXPECT_EQ(trace_cylindrical_shell({0, -50, 40}, {0, 1, 0}, r_in, r_out, 120, 10, n).reason, Reason::miss);
  EXPECT_THROW(trace_cylindrical_shell({0, 0, 40}, {0, 0, -1}, r_in, r_out, 400, 10, n), std::invalid_argument);
  EXPECT_THROW(trace_cylindrical_shell({0, 0, 10}, {0, 0, -1}, r_in, r_out, 120, 10, n), std::invalid_argument);
}

// ------------------------------------------- properties of every shape ----

struct Scene {
  std::string name;
  double size;  // characteristic length (mm) at scale 1
  std::function<SkinHit(const Vec3& o, const Vec3& d, double s)> trace;
  // Point on the outer surface near `entry` displaced by (u, v) mm along it.
  std::function<Vec3(const Vec3& entry, double u, double v)> surface;
  std::function<Vec3(const Vec3& p)> outer_normal;
  // Parameter where the ray x + t·w from inside meets the outer surface (scale 1).
  std::function<double(const Vec3& x, const Vec3& w)> exit_outer;
  Vec3 camera;
  std::function<Vec3(std::mt19937_64&)> target;
};

std::vector<Scene> scenes() {
  const Indices n;
  std::vector<Scene> out;
  auto uni = [](std::mt19937_64& rng, double a) { return std::uniform_real_distribution<double>(-a, a)(rng); };
  out.push_back({"slab", 10,
                 [=](const Vec3& o, const Vec3& d, double s) { return trace_slab(o, d, 2 * s, n); },
                 [](const Vec3& e, double u, double v) { return Vec3(e + Vec3(u, v, 0)); },
                 [](const Vec3&) { return Vec3::UnitZ(); },
                 [](const Vec3& x, const Vec3& w) { return (2 - x.z()) / w.z(); }, Vec3(1, -2, 15),
                 [=](std::mt19937_64& r) { return Vec3(uni(r, 15), uni(r, 15), 2); }});
  out.push_back({"wedge", 10,
                 [=](const Vec3& o, const Vec3& d, double s) { return trace_wedge(o, d, 5 * s, -15 * kDeg, n); },
                 [](const Vec3& e, double u, double v) { return Vec3(e + Vec3(u, v, 0)); },
                 [](const Vec3&) { return Vec3::UnitZ(); },
                 [](const Vec3& x, const Vec3& w) { return (5 - x.z()) / w.z(); }, Vec3(0, 1, 30),
                 [=](std::mt19937_64& r) { return Vec3(uni(r, 20), uni(r, 20), 5); }});
  auto sphere_exit = [](double radius) {
    return [=](const Vec3& x, const Vec3& w) { return textbook_roots(x, w, radius)->second; };
  };
  out.push_back({"ball", 10,
                 [=](const Vec3& o, const Vec3& d, double s) { return trace_ball(o, d, 10 * s, n); },
                 on_sphere_param, [](const Vec3& p) { return Vec3(p.normalized()); }, sphere_exit(10),
                 Vec3(2, 1, 40), [=](std::mt19937_64& r) { return Vec3(uni(r, 9), uni(r, 9), 0); }});
  out.push_back({"spherical_shell", 23,
                 [=](const Vec3& o, const Vec3& d, double s) {
                   return trace_spherical_shell(o, d, 20 * s, 23 * s, 40, n);
                 },
                 on_sphere_param, [](const Vec3& p) { return Vec3(p.normalized()); }, sphere_exit(23),
                 Vec3(3, -2, 60), [=](std::mt19937_64& r) { return Vec3(uni(r, 14), uni(r, 14), 20); }});
  out.push_back({"cylindrical_shell", 33,
                 [=](const Vec3& o, const Vec3& d, double s) {
                   return trace_cylindrical_shell(o, d, 30 * s, 33 * s, 120, 40 * s, n);
                 },
                 [](const Vec3& e, double u, double v) {
                   const double r = xz(e).norm(), phi = std::atan2(e.x(), e.z()) + u / r;
                   return Vec3(r * std::sin(phi), e.y() + v, r * std::cos(phi));
                 },
                 [](const Vec3& p) { return Vec3(xz(p).normalized()); },
                 [](const Vec3& x, const Vec3& w) { return textbook_roots(xz(x), xz(w), 33)->second; },
                 Vec3(4, 3, 90), [=](std::mt19937_64& r) { return Vec3(uni(r, 25), uni(r, 20), 30); }});
  return out;
}

// Fermat: with the skin point fixed, the optical path through a point p of the
// outer surface is stationary at the traced entry point; central differences
// along the surface give a gradient ~0 there and clearly not 0 nearby.
TEST(Properties, FermatReciprocityScaleInvariance) {
  const Indices n;
  std::cout << "[ seed     ] " << kSeed + 4 << std::endl;
  for (const Scene& sc : scenes()) {
    std::mt19937_64 rng(kSeed + 4);
    int valid = 0;
    double worst_grad = 0, least_control = 1e9, worst_recip = 0, worst_scale = 0;
    for (int k = 0; k < 300; ++k) {
      const Vec3 o = sc.camera;
      const Vec3 d = (sc.target(rng) - o).normalized();
      const SkinHit hit = sc.trace(o, d, 1.0);
      if (!hit.valid) continue;
      ++valid;
      // Invariants of every hit.
      ASSERT_NEAR(hit.refracted_dir.norm(), 1.0, 1e-15);
      ASSERT_NEAR(n.n_medium * std::sin(hit.incidence_rad), n.n_part * std::sin(hit.refraction_rad), 1e-14);
      ASSERT_NEAR(n.n_part * std::sin(hit.contact_rad), n.n_skin * std::sin(hit.exit_rad), 1e-14);
      ASSERT_LT(hit.transmittance, 1.0);
      // Fermat.
      const Vec3 s = hit.skin_point;
      auto path = [&](const Vec3& p) { return n.n_medium * (p - o).norm() + n.n_part * (s - p).norm(); };
      auto gradient = [&](double u0, double v0) {
        const double step = 1e-4 * std::min(1.0, (s - hit.entry_point).norm());
        auto at = [&](double u, double v) { return path(sc.surface(hit.entry_point, u0 + u, v0 + v)); };
        return Vec2((at(step, 0) - at(-step, 0)) / (2 * step), (at(0, step) - at(0, -step)) / (2 * step)).norm();
      };
      worst_grad = std::max(worst_grad, gradient(0, 0));
      least_control = std::min(least_control, std::max(gradient(0.01 * sc.size, 0), gradient(0, 0.01 * sc.size)));
      // Reciprocity: from the skin point backwards along the ray we meet the
      // entry point, and refracting out there leads back through the camera.
      const Vec3 back_in = -hit.refracted_dir;
      const Vec3 q = s + sc.exit_outer(s, back_in) * back_in;
      const auto out = optics::refract(back_in, sc.outer_normal(q), n.n_part, n.n_medium);
      ASSERT_TRUE(out.has_value());
      worst_recip = std::max({worst_recip, rel_err(q, hit.entry_point, sc.size), rel_err(*out, -d, 1),
                              (o - q).cross(*out).norm() / (o - q).norm()});
      // Scale invariance: the same scene in µm-sized and m-sized units.
      for (double scale : {1e-3, 1e3}) {
        const SkinHit sh = sc.trace(scale * o, d, scale);
        ASSERT_EQ(sh.reason, hit.reason);
        worst_scale = std::max({worst_scale, rel_err(sh.skin_point / scale, s, sc.size),
                                rel_err(sh.entry_point / scale, hit.entry_point, sc.size),
                                std::abs(sh.incidence_rad - hit.incidence_rad),
                                std::abs(sh.contact_rad - hit.contact_rad),
                                std::abs(sh.optical_path_mm / scale - hit.optical_path_mm) / sc.size,
                                std::abs(sh.transmittance - hit.transmittance)});
      }
    }
    std::cout << sc.name << ": " << valid << " valid rays; max |grad L| " << worst_grad
              << " (min 0.01·size away: " << least_control << "), reciprocity " << worst_recip
              << ", scale invariance " << worst_scale << std::endl;
    EXPECT_GT(valid, 100) << sc.name;
    EXPECT_LT(worst_grad, 1e-7) << sc.name;
    EXPECT_GT(least_control, 1e-4) << sc.name;
    EXPECT_LT(worst_recip, 1e-12) << sc.name;
    EXPECT_LT(worst_scale, 1e-12) << sc.name;
  }
}

}  // namespace
}  // namespace clearfit::analytic
