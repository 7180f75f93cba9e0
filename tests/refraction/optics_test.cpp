// Optics primitives against independent facts: Snell's law in sine form,
// reversibility, the critical angle, Fresnel in its sine/tangent form.
#include <clearfit/refraction/optics.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

namespace clearfit::optics {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::uint64_t kSeed = 20240611;

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Vec3 v;
  do v = Vec3(g(rng), g(rng), g(rng));
  while (v.norm() < 1e-3);
  return v.normalized();
}

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

double sin_between(const Vec3& a, const Vec3& b) { return a.cross(b).norm(); }

TEST(SnellLaw, HoldsOnRandomCases) {
  std::cout << "[ seed     ] " << kSeed << std::endl;
  std::mt19937_64 rng(kSeed);
  std::uniform_real_distribution<double> eta_dist(1.0, 2.0);
  double worst_snell = 0, worst_coplanar = 0, worst_unit = 0, worst_back = 0;
  int transmitted = 0, reflected = 0, misclassified = 0, wrong_side = 0, back_missing = 0;
  for (int k = 0; k < 100000; ++k) {
    const Vec3 d = random_unit(rng), n = random_unit(rng);
    const double eta_i = eta_dist(rng), eta_t = (k % 10 == 0) ? eta_i : eta_dist(rng);
    const Transmission t = transmit(d, n, eta_i, eta_t);
    const double sin_i = sin_between(d, n);
    const double margin = eta_i * sin_i - eta_t;  // > 0: beyond the critical angle
    if (std::abs(margin) > 1e-12 && t.tir != (margin > 0)) ++misclassified;
    if (t.tir) {
      ++reflected;
      EXPECT_FALSE(refract(d, n, eta_i, eta_t).has_value());
      continue;
    }
    ++transmitted;
    const Vec3& w = t.direction;
    worst_snell = std::max(worst_snell, std::abs(eta_i * sin_i - eta_t * sin_between(w, n)));
    worst_coplanar = std::max(worst_coplanar, std::abs(w.dot(d.cross(n))));
    worst_unit = std::max(worst_unit, std::abs(w.norm() - 1.0));
    // The ray crosses the surface and keeps its tangential heading.
    const Vec3 d_tan = d - d.dot(n) * n, w_tan = w - w.dot(n) * n;
    if (w.dot(n) * d.dot(n) < 0 || w_tan.dot(d_tan) < 0) ++wrong_side;
    // Reversibility: back through the surface with the indices swapped gives −d.
    const auto back = refract(-w, n, eta_t, eta_i);
    if (!back) {
      ++back_missing;
      continue;
    }
    // Near grazing the return trip amplifies rounding by 1/cos θ_i (cos²θ is
    // recovered from 1 − sin²θ), so the error is weighted by cos θ_i.
    worst_back = std::max(worst_back, (*back + d).norm() * t.cos_i);
  }
  std::cout << "transmitted " << transmitted << ", reflected " << reflected
            << "; max |n1 sin1 - n2 sin2| " << worst_snell << ", coplanarity " << worst_coplanar
            << ", | |t|-1 | " << worst_unit << ", reversibility*cos_i " << worst_back << std::endl;
  EXPECT_GT(reflected, 10000);
  EXPECT_EQ(misclassified, 0);
  EXPECT_EQ(wrong_side, 0);
  EXPECT_EQ(back_missing, 0);
  EXPECT_LE(worst_snell, 1e-14);
  EXPECT_LE(worst_coplanar, 1e-14);
  EXPECT_LE(worst_unit, 1e-14);
  EXPECT_LE(worst_back, 1e-14);
}

TEST(SnellLaw, NormalIncidenceIsUndeviated) {
  const Vec3 n = Vec3(1, 2, 3).normalized();
  const Transmission t = transmit(-n, n, 1.0, 1.49);
  ASSERT_FALSE(t.tir);
  EXPECT_EQ(t.direction, Vec3(-n));
  EXPECT_EQ(t.cos_t, 1.0);
}

TEST(SnellLaw, NormalOrientationDoesNotMatter) {
  std::mt19937_64 rng(kSeed + 1);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 d = random_unit(rng), n = random_unit(rng);
    const Transmission a = transmit(d, n, 1.49, 1.2), b = transmit(d, -n, 1.49, 1.2);
    ASSERT_EQ(a.tir, b.tir);
    if (!a.tir) {
      EXPECT_EQ(a.direction, b.direction);
      EXPECT_GT(a.direction.dot(d), 0.0);  // it went through, not back
    }
  }
}

// Angles within 1e-12 rad (down to 1e-14) of the critical angle, both sides, in random frames.
TEST(SnellLaw, CriticalAngle) {
  std::mt19937_64 rng(kSeed + 2);
  const std::pair<double, double> pairs[] = {{1.49, 1.0}, {1.49, 1.4}, {1.6, 1.49}, {1.333, 1.0}};
  for (const auto& [eta_i, eta_t] : pairs) {
    const double theta_c = std::asin(eta_t / eta_i);
    ASSERT_TRUE(critical_angle(eta_i, eta_t).has_value());
    EXPECT_NEAR(*critical_angle(eta_i, eta_t), theta_c, 1e-15);
    const double eta = eta_i / eta_t;
    for (double delta : {1e-14, 1e-13, 1e-12, 3e-12, 1e-10, 1e-8, 1e-6, 1e-3}) {
      for (int k = 0; k < 20; ++k) {
        const Eigen::Matrix3d rot = random_rotation(rng);
        const Vec3 n = rot * Vec3::UnitZ();
        const double below = theta_c - delta, above = theta_c + delta;
        const Transmission in = transmit(rot * Vec3(std::sin(below), 0, -std::cos(below)), n, eta_i, eta_t);
        const Transmission out = transmit(rot * Vec3(std::sin(above), 0, -std::cos(above)), n, eta_i, eta_t);
        ASSERT_FALSE(in.tir) << "delta " << delta;
        ASSERT_TRUE(out.tir) << "delta " << delta;
        ASSERT_TRUE(in.direction.allFinite());
        EXPECT_EQ(out.direction, Vec3::Zero());
        // cos²θ_t = η²(sin²θ_c − sin²θ) = η² sin(θ_c + θ) sin(θ_c − θ), free of cancellation.
        const double cos2_t = eta * eta * std::sin(theta_c + below) * std::sin(delta);
        EXPECT_NEAR(in.cos_t * in.cos_t, cos2_t, 4e-15) << "delta " << delta;
        EXPECT_GT(in.cos_t, 0.0);
        EXPECT_NEAR(in.direction.norm(), 1.0, 1e-15);
        EXPECT_NEAR(eta_i * std::sin(below), eta_t * sin_between(in.direction, n), 1e-14);
      }
    }
    // Exactly at the critical angle as far as doubles go: no NaN, either outcome.
    const double s = eta_t / eta_i;
    const Transmission at = transmit(Vec3(s, 0, -std::sqrt(1 - s * s)), Vec3::UnitZ(), eta_i, eta_t);
    if (!at.tir) {
      EXPECT_TRUE(at.direction.allFinite());
      EXPECT_LT(std::abs(at.direction.z()), 1e-7);
    }
  }
}

TEST(SnellLaw, GrazingIncidence) {
  for (double cos_i : {1e-15, 0.0}) {
    const Vec3 d(std::sqrt(1 - cos_i * cos_i), 0, -cos_i);
    // Into the denser part: transmitted at the critical angle inside.
    const Transmission t = transmit(d, Vec3::UnitZ(), 1.0, 1.49);
    ASSERT_FALSE(t.tir);
    EXPECT_TRUE(t.direction.allFinite());
    EXPECT_NEAR(sin_between(t.direction, Vec3::UnitZ()), 1.0 / 1.49, 1e-15);
    EXPECT_LT(t.direction.z(), 0);
    EXPECT_NEAR(t.cos_t, std::sqrt(1 - 1 / (1.49 * 1.49)), 1e-15);
    // Out of the part: totally reflected.
    EXPECT_TRUE(transmit(d, Vec3::UnitZ(), 1.49, 1.0).tir);
    // Fresnel: almost everything reflected at grazing incidence.
    const FresnelTerms f = fresnel(cos_i, 1.0, 1.49);
    EXPECT_GE(f.R, 1 - 1e-13);
    EXPECT_LE(f.R, 1.0);
  }
}

TEST(SnellLaw, Reflect) {
  std::mt19937_64 rng(kSeed + 3);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 d = random_unit(rng), n = random_unit(rng);
    const Vec3 r = reflect(d, n);
    EXPECT_NEAR(r.norm(), 1.0, 1e-15);
    EXPECT_NEAR(r.dot(n), -d.dot(n), 1e-15);
    EXPECT_LT((r - d).cross(n).norm(), 1e-15);
    EXPECT_NEAR(angle_between(r, n), angle_between(-d, n), 1e-12);  // equal angles
  }
}

TEST(SnellLaw, InvalidIndicesThrow) {
  const Vec3 d(0, 0, -1), n(0, 0, 1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double bad : {0.0, -1.0, nan, inf}) {
    EXPECT_THROW(refract(d, n, bad, 1.0), std::invalid_argument);
    EXPECT_THROW(refract(d, n, 1.0, bad), std::invalid_argument);
    EXPECT_THROW(fresnel(0.5, bad, 1.0), std::invalid_argument);
    EXPECT_THROW(critical_angle(1.0, bad), std::invalid_argument);
  }
  EXPECT_THROW(fresnel(1.5, 1.0, 1.49), std::invalid_argument);
  EXPECT_THROW(fresnel(nan, 1.0, 1.49), std::invalid_argument);
  EXPECT_NO_THROW(Indices{}.validate());
  try {
    Indices{1.0, 0.9, 1.4}.validate();
    FAIL() << "n_part 0.9 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("n_part"), std::string::npos) << e.what();
  }
}

TEST(Fresnel, EnergyAndNormalIncidence) {
  for (double n1 : {1.0, 1.333, 1.49}) {
    for (double n2 : {1.0, 1.4, 1.49, 1.55}) {
      const FresnelTerms f0 = fresnel(1.0, n1, n2);
      const double r0 = (n1 - n2) / (n1 + n2);
      EXPECT_NEAR(f0.R, r0 * r0, 1e-16);
      EXPECT_NEAR(f0.R_s, f0.R_p, 1e-16);
      for (int deg = 0; deg <= 90; ++deg) {
        const FresnelTerms f = fresnel(std::cos(deg * kPi / 180), n1, n2);
        EXPECT_EQ(f.R + f.T, 1.0);
        EXPECT_GE(f.R, 0.0);
        EXPECT_LE(f.R, 1.0);
        EXPECT_GE(f.R_s, f.R_p - 1e-16);  // s is always reflected at least as much as p
        if (n1 == n2) {
          EXPECT_EQ(f.R, 0.0);
        }
      }
    }
  }
  EXPECT_NEAR(fresnel(1.0, 1.0, 1.49).R, 0.038725181851905606, 1e-16);
}

// The cosine form used in the code against the textbook sine/tangent form.
TEST(Fresnel, MatchesSineTangentForm) {
  double worst = 0;
  for (auto [n1, n2] : {std::pair{1.0, 1.49}, {1.49, 1.0}, {1.49, 1.4}, {1.333, 1.55}}) {
    for (double deg = 0.5; deg < 90; deg += 0.5) {
      const double ti = deg * kPi / 180, st = n1 * std::sin(ti) / n2;
      if (st >= 1) {
        EXPECT_TRUE(fresnel(std::cos(ti), n1, n2).tir);
        continue;
      }
      const double tt = std::asin(st);
      const double rs = std::pow(std::sin(ti - tt) / std::sin(ti + tt), 2);
      const double rp = std::pow(std::tan(ti - tt) / std::tan(ti + tt), 2);
      const FresnelTerms f = fresnel(std::cos(ti), n1, n2);
      worst = std::max({worst, std::abs(f.R_s - rs), std::abs(f.R_p - rp)});
      // Reciprocity: the same interface crossed backwards transmits the same fraction.
      EXPECT_NEAR(fresnel(std::cos(tt), n2, n1).T, f.T, 1e-13);
    }
  }
  std::cout << "max |R - R(sine/tangent form)| = " << worst << std::endl;
  EXPECT_LE(worst, 1e-13);
}

TEST(Fresnel, BrewsterAngle) {
  for (auto [n1, n2] : {std::pair{1.0, 1.49}, {1.49, 1.0}, {1.49, 1.4}}) {
    const double theta_b = std::atan(n2 / n1);
    const FresnelTerms f = fresnel(std::cos(theta_b), n1, n2);
    EXPECT_LT(f.R_p, 1e-28);
    EXPECT_GT(f.R_s, 1e-4);
    EXPECT_GT(fresnel(std::cos(theta_b + 0.01), n1, n2).R_p, 1e-7);
  }
}

TEST(Fresnel, TotalInternalReflection) {
  const double theta_c = *critical_angle(1.49, 1.0);
  const FresnelTerms beyond = fresnel(std::cos(theta_c + 1e-12), 1.49, 1.0);
  EXPECT_TRUE(beyond.tir);
  EXPECT_EQ(beyond.R, 1.0);
  EXPECT_EQ(beyond.T, 0.0);
  EXPECT_EQ(fresnel(0.0, 1.49, 1.0).R, 1.0);
  // Continuous towards the critical angle: R → 1.
  const FresnelTerms just_below = fresnel(std::cos(theta_c - 1e-9), 1.49, 1.0);
  EXPECT_FALSE(just_below.tir);
  EXPECT_GT(just_below.R, 0.999);
  // The Transmission overload agrees with the cosine one.
  const double theta = 0.3;
  const Transmission t = transmit(Vec3(std::sin(theta), 0, -std::cos(theta)), Vec3::UnitZ(), 1.0, 1.49);
  EXPECT_NEAR(fresnel(t, 1.0, 1.49).R, fresnel(std::cos(theta), 1.0, 1.49).R, 1e-16);
  EXPECT_TRUE(fresnel(Transmission{true}, 1.49, 1.0).tir);
}

TEST(CriticalAngle, NoneFromTheLessDenseSide) {
  EXPECT_FALSE(critical_angle(1.0, 1.49).has_value());
  EXPECT_FALSE(critical_angle(1.49, 1.49).has_value());
  EXPECT_NEAR(*critical_angle(1.49, 1.0), 0.7357467619614884, 1e-15);  // 42.155°
}

TEST(OpticalPath, Polyline) {
  const std::vector<Vec3> points = {{0, 0, 0}, {3, 4, 0}, {3, 4, 12}};
  const std::vector<double> eta = {1.0, 1.5};
  EXPECT_DOUBLE_EQ(optical_path(points, eta), 5.0 + 18.0);
  EXPECT_DOUBLE_EQ(optical_path(points[0], points[1], 1.333), 5 * 1.333);
  EXPECT_EQ(optical_path(std::span(points).first(1), {}), 0.0);
  EXPECT_THROW(optical_path(points, std::span(eta).first(1)), std::invalid_argument);
  EXPECT_THROW(optical_path({}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit::optics
