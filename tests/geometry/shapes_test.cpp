// The analytic test parts against closed forms for their own tessellation.
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "../support/mesh_checks.hpp"

using namespace clearfit;
constexpr double pi = std::numbers::pi;

TEST(Shapes, BoxAreaVolumeClosedOutward) {
  for (int n : {1, 3}) {
    Mesh m = shapes::box({2, 3, 5}, n);
    EXPECT_TRUE(test::closed_and_consistent(m));
    EXPECT_EQ(m.num_faces(), 12 * n * n);
    EXPECT_NEAR(surface_area(m), 2 * (6 + 15 + 10), 1e-12);
    EXPECT_NEAR(signed_volume(m), 30, 1e-12);
    m.check_consistent();
  }
}

TEST(Shapes, SlabGroupsAndNormals) {
  Mesh m = shapes::slab(20, 10, 2, 4);
  EXPECT_TRUE(test::closed_and_consistent(m));
  EXPECT_NEAR(signed_volume(m), 400, 1e-10);
  for (int f = 0; f < m.num_faces(); ++f) {
    const std::string& g = m.groups[m.face_group[f]];
    if (g == "contact") EXPECT_NEAR(m.face_normal(f).z(), -1, 1e-15);
    if (g == "outer") EXPECT_NEAR(m.face_normal(f).z(), 1, 1e-15);
    if (g == "side") EXPECT_NEAR(m.face_normal(f).z(), 0, 1e-15);
  }
}

TEST(Shapes, CylindricalShellMatchesPolygonalClosedForm) {
  const double r_in = 30, r_out = 32.5, w = 12;
  for (double span : {90.0, 200.0, 360.0}) {
    const int n = 48;
    Mesh m = shapes::cylindrical_shell(r_in, r_out, span, w, n, 3);
    EXPECT_TRUE(test::closed_and_consistent(m)) << span;
    const double s = span * pi / 180;
    // Each of the n segments is a chord; the cross-section is n trapezoids.
    const double section = n * 0.5 * (r_out * r_out - r_in * r_in) * std::sin(s / n);
    EXPECT_NEAR(signed_volume(m), w * section, 1e-9 * w * section) << span;
    double inner = 0;
    for (int f = 0; f < m.num_faces(); ++f)
      if (m.groups[m.face_group[f]] == "contact") {
        inner += m.face_area(f);
        // The contact surface faces the axis (into the wrist).
        const Vec3 c = (m.corner(f, 0) + m.corner(f, 1) + m.corner(f, 2)) / 3;
        EXPECT_LT(m.face_normal(f).dot(Vec3(c.x(), 0, c.z())), 0);
      }
    EXPECT_NEAR(inner, w * n * 2 * r_in * std::sin(s / (2 * n)), 1e-9 * inner);
  }
}

TEST(Shapes, IcosphereVolumeConvergesQuadratically) {
  double previous_error = 0;
  for (int s = 1; s <= 5; ++s) {
    Mesh m = shapes::icosphere(2.0, s);
    EXPECT_TRUE(test::closed_and_consistent(m));
    for (const Vec3& v : m.vertices) EXPECT_NEAR(v.norm(), 2.0, 1e-14);
    const double error = 4.0 / 3 * pi * 8 - signed_volume(m);
    EXPECT_GT(error, 0);
    if (s > 1) {
      const double order = std::log2(previous_error / error);
      EXPECT_NEAR(order, 2.0, 0.15) << "subdivision " << s;
    }
    previous_error = error;
  }
}

TEST(Shapes, SphericalShellIsClosedAndConverges) {
  const double r_in = 20, r_out = 22, cap = 40 * pi / 180;
  const double exact = 2 * pi / 3 * (std::pow(r_out, 3) - std::pow(r_in, 3)) * (1 - std::cos(cap));
  double previous = 1e9;
  for (int n : {8, 16, 32}) {
    Mesh m = shapes::spherical_shell(r_in, r_out, 40, n, 4 * n);
    EXPECT_TRUE(test::closed_and_consistent(m)) << n;
    const double error = std::abs(signed_volume(m) - exact) / exact;
    EXPECT_LT(error, previous / 3) << n;
    previous = error;
  }
  EXPECT_LT(previous, 2e-3);
}

TEST(Shapes, RejectsBadParameters) {
  EXPECT_THROW(shapes::box({0, 1, 1}), std::invalid_argument);
  EXPECT_THROW(shapes::cylindrical_shell(3, 2, 90, 1, 8, 1), std::invalid_argument);
  EXPECT_THROW(shapes::spherical_shell(1, 2, 95, 4, 8), std::invalid_argument);
}
