// Contact mechanics against closed forms (Sneddon punch, Hertz, Boussinesq).
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/indenter_field.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace clearfit::contact {
namespace {
constexpr double kPi = std::numbers::pi;

// ∫ p(r) 2πr dr over the disc, with r = a·sin θ (removes the rim singularity).
template <class P>
double disc_force_n(P pressure_kpa, double a, int n = 20000) {
  double sum = 0;
  const double dth = kPi / 2 / n;
  for (int i = 0; i < n; ++i) {
    const double th = (i + 0.5) * dth, r = a * std::sin(th);
    sum += pressure_kpa(r) * 2 * kPi * r * a * std::cos(th) * dth;
  }
  return sum / 1000;  // kPa·mm² → N
}
}  // namespace

TEST(FlatPunch, PressureIntegratesBackToTheForce) {
  const FlatPunch punch{2.0, 0.7, 0};
  EXPECT_NEAR(disc_force_n([&](double r) { return punch.pressure_kpa(r); }, 2.0), 0.7, 1e-4);
  EXPECT_NEAR(punch.pressure_kpa(0), mean_pressure_kpa(0.7, 2.0) / 2, 1e-12);  // p(0) = p_mean / 2
  EXPECT_EQ(punch.pressure_kpa(2.0), 0.0);
  EXPECT_EQ(punch.pressure_kpa(2.1), 0.0);
}

TEST(FlatPunch, CappedFieldCarriesTheClosedFormFraction) {
  const FlatPunch punch{2.5, 1.0, 3.0};
  const double pm = mean_pressure_kpa(1.0, 2.5);
  EXPECT_NEAR(punch.pressure_kpa(2.4999), 3 * pm, 1e-9);
  EXPECT_NEAR(disc_force_n([&](double r) { return punch.pressure_kpa(r); }, 2.5), punch.capped_force_fraction(), 1e-4);
  EXPECT_NEAR(punch.capped_force_fraction(), 1 - 1 / 12.0, 1e-15);
}

TEST(FlatPunch, AxisStressPeaksAtASqrt3) {
  // Sneddon: σz(0, z) = F(a² + 3z²)/(2π(a² + z²)²): p(0) = p_mean/2 at z = 0, maximum 9F/(16πa²)
  // = 1.125·p(0) = 0.5625·p_mean at z = a/√3 (SKIN.md's "1.125·p_mean" is 1.125 times the centre pressure).
  const FlatPunch punch{2.5, 1.0, 0};
  const double pm = mean_pressure_kpa(1.0, 2.5), zmax = 2.5 / std::sqrt(3.0);
  EXPECT_NEAR(punch.axis_sigma_z_kpa(0), pm / 2, 1e-9);
  EXPECT_NEAR(punch.axis_sigma_z_kpa(zmax), 0.5625 * pm, 1e-9);
  for (double dz : {-0.05, 0.05}) EXPECT_LT(punch.axis_sigma_z_kpa(zmax + dz), punch.axis_sigma_z_kpa(zmax));
  // Boussinesq superposition of the surface pressure reproduces the closed form.
  for (double z : {0.3, zmax, 2.0}) {
    const Stress s = punch_stress(punch, 0.0, z, 0.48);
    EXPECT_NEAR(-s[2], punch.axis_sigma_z_kpa(z), 1e-3 * pm) << "z " << z;
  }
}

TEST(FlatPunch, VonMisesRingAtTheRimNearlyZeroUnderTheCentre) {
  const FlatPunch punch{2.5, 1.0, 0};
  const double pm = mean_pressure_kpa(1.0, 2.5), z = 0.2;
  double peak = 0, peak_r = 0;
  for (double r = 2.0; r <= 2.8; r += 0.025) {  // the ring (a coarser scan of 0..3 mm finds the same peak)
    const double vm = von_mises(punch_stress(punch, r, z, 0.48, 300, 360));
    if (vm > peak) peak = vm, peak_r = r;
  }
  const double centre = von_mises(punch_stress(punch, 0, z, 0.48, 300, 360));
  std::printf("punch a=2.5 z=0.2 nu=0.48: centre %.3f p_mean, peak %.3f p_mean at r=%.3f\n", centre / pm, peak / pm, peak_r);
  EXPECT_LT(centre, 0.1 * pm);
  EXPECT_GT(peak, 1.0 * pm);
  EXPECT_NEAR(peak_r, 2.5, 0.2);
}

TEST(Hertz, ClosedFormsAndForce) {
  const HertzSphere h{10.0, 0.5, 200.0};
  const double a = h.contact_radius_mm();
  EXPECT_NEAR(a * a * a, 3 * 0.5 * 10.0 / (4 * 0.2), 1e-12);
  EXPECT_NEAR(h.peak_pressure_kpa(), 1.5 * mean_pressure_kpa(0.5, a), 1e-9);
  EXPECT_NEAR(disc_force_n([&](double r) { return h.pressure_kpa(r); }, a), 0.5, 1e-6);
  EXPECT_EQ(h.pressure_kpa(a * 1.01), 0.0);
}

// The sphere's profile per newton as the calibration fits it (indenter_field.hpp): unblurred, Hertz's closed
// form (HertzSphere at the contact radius its force makes); blurred, the force is kept (∫ 2πr p dr = 1 N) and
// the value at a radius equals a brute-force 2-D convolution of the closed form with the Gaussian; the
// table and the one-radius evaluation agree.
TEST(IndenterProfile, HertzKeepsTheForceAndMatchesABruteForceBlur) {
  const HertzSphere h{10.0, 0.3, 180.0};
  const double a = h.contact_radius_mm(), s = 0.3;
  const clearfit::IndenterProfile sharp(clearfit::PressureField::hertz, a, 0), blurred(clearfit::PressureField::hertz, a, s);
  for (double r : {0.0, 0.3 * a, 0.7 * a, 0.99 * a}) EXPECT_NEAR(sharp.kpa_per_newton(r) * h.force_n, h.pressure_kpa(r), 1e-9 * h.peak_pressure_kpa());
  double force = 0;  // kPa·mm² → N: /1000
  const double dr = 1e-3;
  for (double r = dr / 2; r < a + 8 * s; r += dr) force += 2 * std::numbers::pi * r * blurred.kpa_per_newton(r) * dr / 1000;
  EXPECT_NEAR(force, 1.0, 2e-3);
  for (double r : {0.0, 0.5 * a, a, a + 0.4}) {
    double sum = 0;  // ∫∫ p(|x'|) G(x − x') dx' on a 0.005 mm grid, x = (r, 0)
    const double step = 0.005;
    for (double x = -a; x <= a; x += step)
      for (double y = -a; y <= a; y += step) {
        const double rr = std::hypot(x, y);
        if (rr >= a) continue;
        const double d2 = (x - r) * (x - r) + y * y;
        sum += sharp.kpa_per_newton(rr) * std::exp(-d2 / (2 * s * s)) / (2 * std::numbers::pi * s * s) * step * step;
      }
    EXPECT_NEAR(blurred.kpa_per_newton(r), sum, 2e-3 * blurred.kpa_per_newton(0)) << "r " << r;
    EXPECT_NEAR(clearfit::blurred_hertz_kpa_per_newton(r, a, s), blurred.kpa_per_newton(r), 1e-3 * blurred.kpa_per_newton(0)) << "r " << r;
  }
}

TEST(Boussinesq, PointLoadAxisAndEquilibrium) {
  // σz = −3Fz³/(2πρ⁵); the vertical stress over any horizontal plane carries F.
  const double F = 1.0, z = 0.5;
  EXPECT_NEAR(boussinesq_point(F, 0, 0, z, 0.3)[2], -3 * F / (2 * kPi * z * z) * 1000, 1e-9);
  double sum = 0;
  const double h = 0.01;
  // radial integral ∫ σz 2πr dr
  for (double r = 0.5 * h / 10; r < 200; r += h / 10) sum += boussinesq_point(F, r, 0, z, 0.3)[2] * 2 * kPi * r * h / 10;
  EXPECT_NEAR(-sum / 1000, F, 2e-3);
}

TEST(VonMisesAtDepth, GridConvolutionMatchesHertzAxisClosedForm) {
  // Hertz, on the axis (Johnson eq. 4.40): σz = −p0/(1 + ζ²), σr = σθ = p0(−(1+ν)(1 − ζ·atan(1/ζ)) + 1/(2(1 + ζ²))),
  // ζ = z/a; von Mises = |σz − σr|.
  const HertzSphere h{8.0, 0.4, 150.0};
  const double a = h.contact_radius_mm(), p0 = h.peak_pressure_kpa(), nu = 0.3;
  ChartField p;
  p.grid = ChartGrid::covering(Vec2(-4, -4), Vec2(4, 4), 0.04);
  p.value.resize(p.grid.size());
  for (int j = 0; j < p.grid.height; ++j)
    for (int i = 0; i < p.grid.width; ++i) p.value[p.grid.index(i, j)] = static_cast<float>(h.pressure_kpa(p.grid.uv(i, j).norm()));
  const int ci = static_cast<int>(std::lround(-p.grid.uv_origin.x() / 0.04)), cj = static_cast<int>(std::lround(-p.grid.uv_origin.y() / 0.04));
  ASSERT_NEAR(p.grid.uv(ci, cj).norm(), 0, 1e-9);
  for (double zeta : {0.2, 0.48, 1.0}) {
    const double z = zeta * a;
    const double sz = -p0 / (1 + zeta * zeta);
    const double sr = p0 * (-(1 + nu) * (1 - zeta * std::atan(1 / zeta)) + 0.5 / (1 + zeta * zeta));
    const ChartField vm = von_mises_at_depth(p, z, nu, 4.0);
    EXPECT_NEAR(vm.value[p.grid.index(ci, cj)], std::abs(sz - sr), 0.02 * p0) << "z/a " << zeta << ", a " << a;
  }
  // The closed form's maximum shear 0.31·p0 near z = 0.48a (ν = 0.3): von Mises = 2τ on the axis.
  const double zeta = 0.48, sz = -1 / (1 + zeta * zeta), sr = -(1 + nu) * (1 - zeta * std::atan(1 / zeta)) + 0.5 / (1 + zeta * zeta);
  EXPECT_NEAR(0.5 * std::abs(sz - sr), 0.31, 0.005);
}

}  // namespace clearfit::contact
