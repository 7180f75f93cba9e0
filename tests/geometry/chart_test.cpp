// compute_chart against shapes with known developments: a flat slab (exact
// projection), a cylindrical band (developable: unrolls without distortion), a
// spherical cap (not developable: distortion must show) and closed surfaces
// (must be refused).
#include <clearfit/error.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

namespace clearfit {
namespace {

constexpr double kPi = std::numbers::pi;

ContactSurface contact_group(const Mesh& m) {
  ContactSelector s;
  s.group = "contact";
  return select_contact(m, s);
}

std::vector<int> contact_vertices(const Mesh& m, const ContactSurface& c) {
  std::vector<int> v;
  for (int f : c.faces) v.insert(v.end(), m.faces[f].begin(), m.faces[f].end());
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

Mesh merged(Mesh a, const Mesh& b) {
  const int nv = a.num_vertices(), nf = a.num_faces();
  a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto f : b.faces) a.faces.push_back({f[0] + nv, f[1] + nv, f[2] + nv});
  for (int f = 0; f < b.num_faces(); ++f)
    a.file_face.push_back(nf + f), a.face_group.push_back(b.face_group[f]);
  return a;
}

TEST(ChartOptions, DefaultsPassAndBadValuesNameTheField) {
  EXPECT_NO_THROW(ChartOptions{}.validate());
  ChartOptions o;
  o.planar_tolerance_mm = -1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.component_gap_mm = std::nan("");
  try {
    o.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("component_gap_mm"), std::string::npos);
  }
  EXPECT_EQ(to_string(ChartMethod::lscm), "lscm");
}

TEST(Chart, SlabContactIsAnExactProjection) {
  const Mesh slab = shapes::slab(30, 20, 2.5, 5);
  const ContactSurface contact = contact_group(slab);
  const Chart c = compute_chart(slab, contact);
  EXPECT_EQ(c.method, ChartMethod::planar);
  EXPECT_EQ(c.faces, contact.faces);
  EXPECT_NEAR(c.area_ratio_min, 1, 1e-12);
  EXPECT_NEAR(c.area_ratio_max, 1, 1e-12);
  EXPECT_LT(c.angle_error_max_deg, 1e-9);
  // Axes: u along the long side (+x), normal out of the contact face (-z), v = n × u.
  EXPECT_TRUE(c.axis_u.isApprox(Vec3::UnitX(), 1e-12));
  EXPECT_TRUE(c.axis_v.isApprox(-Vec3::UnitY(), 1e-12));
  EXPECT_TRUE(c.uv_min.isZero(1e-12));
  EXPECT_TRUE(c.uv_max.isApprox(Vec2(30, 20), 1e-12));
  const auto verts = contact_vertices(slab, contact);
  for (int v = 0; v < slab.num_vertices(); ++v)
    EXPECT_EQ(std::isnan(c.uv[v].x()), !std::binary_search(verts.begin(), verts.end(), v));
  for (int v : verts)  // the frame maps chart points back onto the part
    EXPECT_LT((c.origin + c.uv[v].x() * c.axis_u + c.uv[v].y() * c.axis_v - slab.vertices[v]).norm(), 1e-12);
}

TEST(Chart, TiltedPlateKeepsEveryDistance) {
  const unsigned seed = 20261122;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Mesh plate = shapes::slab(40, 12, 3, 6);
  const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
  const Vec3 shift(g(rng) * 100, g(rng) * 100, g(rng) * 100);
  for (auto& v : plate.vertices) v = q * v + shift;
  const ContactSurface contact = contact_group(plate);
  const Chart c = compute_chart(plate, contact);
  ASSERT_EQ(c.method, ChartMethod::planar);
  const auto verts = contact_vertices(plate, contact);
  double worst = 0;
  for (int a : verts)
    for (int b : verts)
      worst = std::max(worst,
                       std::abs((c.uv[a] - c.uv[b]).norm() - (plate.vertices[a] - plate.vertices[b]).norm()));
  EXPECT_LT(worst, 1e-11);
  EXPECT_TRUE(c.axis_u.isApprox(q * Vec3::UnitX(), 1e-9) || c.axis_u.isApprox(-(q * Vec3::UnitX()), 1e-9));
  EXPECT_NEAR(c.axis_u.cross(c.axis_v).dot(q * -Vec3::UnitZ()), 1, 1e-12);  // normal out of the contact side
}

// A wristband's inner surface is developable: it unrolls into a rectangle
// whose width is the polygon's perimeter (r_in * span in the limit).
void check_cylinder(ChartMethod method, double tolerance) {
  const double r_in = 30, r_out = 33, span_deg = 120, width = 20;
  const int n = 48;
  const Mesh band = shapes::cylindrical_shell(r_in, r_out, span_deg, width, n, 6);
  const ContactSurface contact = contact_group(band);
  ChartOptions o;
  o.method = method;
  const Chart c = compute_chart(band, contact, o);
  EXPECT_EQ(c.method, method == ChartMethod::automatic ? ChartMethod::lscm : method);
  EXPECT_EQ(c.components, 1);
  std::printf("%s: area ratio %.9f..%.9f, angle error mean %.2e max %.2e deg\n",
              std::string(to_string(c.method)).c_str(), c.area_ratio_min, c.area_ratio_max,
              c.angle_error_mean_deg, c.angle_error_max_deg);
  EXPECT_NEAR(c.area_ratio_min, 1, tolerance);
  EXPECT_NEAR(c.area_ratio_max, 1, tolerance);
  EXPECT_LT(c.angle_error_max_deg, tolerance * 180 / kPi);
  const double h = span_deg / n / 2 * kPi / 180, chord = 2 * r_in * std::sin(h);
  const Vec2 size = c.uv_max - c.uv_min;
  EXPECT_NEAR(size.x(), n * chord, tolerance * n * chord);
  EXPECT_NEAR(size.y(), width, tolerance * width);
  EXPECT_NEAR(size.x(), r_in * span_deg * kPi / 180,
              r_in * span_deg * kPi / 180 * (1 - std::sin(h) / h) + 1e-9);
  // Every distance in the chart equals the distance along the unrolled band.
  const auto verts = contact_vertices(band, contact);
  double worst = 0;
  for (int a : verts)
    for (int b : verts) {
      auto step = [&](int v) { return std::atan2(band.vertices[v].x(), band.vertices[v].z()) / (2 * h); };
      const double along = std::abs(step(a) - step(b)) * chord,
                   across = band.vertices[a].y() - band.vertices[b].y();
      worst = std::max(worst, std::abs((c.uv[a] - c.uv[b]).norm() - std::hypot(along, across)));
    }
  EXPECT_LT(worst, tolerance * n * chord);
}

TEST(Chart, CylindricalBandUnrollsWithLscm) { check_cylinder(ChartMethod::automatic, 1e-6); }
TEST(Chart, CylindricalBandUnrollsWithArap) { check_cylinder(ChartMethod::arap, 1e-4); }

TEST(Chart, CylindricalBandIsNotFlat) {
  const Mesh band = shapes::cylindrical_shell(30, 33, 120, 20, 24, 3);
  ChartOptions o;
  o.method = ChartMethod::planar;
  try {
    compute_chart(band, contact_group(band), o);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is not flat"), std::string::npos) << e.what();
  }
}

TEST(Chart, SphericalCapShowsBoundedDistortion) {
  const double cap_deg = 40;
  const Mesh dome = shapes::spherical_shell(40, 43, cap_deg, 10, 40);
  const ContactSurface contact = contact_group(dome);
  const Chart lscm = compute_chart(dome, contact);
  ChartOptions o;
  o.method = ChartMethod::arap;
  const Chart arap = compute_chart(dome, contact, o);
  for (const Chart* c : {&lscm, &arap})
    std::printf("%s: area ratio %.4f..%.4f, angle error mean %.3f max %.3f deg\n",
                std::string(to_string(c->method)).c_str(), c->area_ratio_min, c->area_ratio_max,
                c->angle_error_mean_deg, c->angle_error_max_deg);
  EXPECT_EQ(lscm.method, ChartMethod::lscm);
  // A conformal map of a cap scales areas like stereographic projection,
  // 1/cos⁴(φ/2) from the pole: rim/pole = 1/cos⁴(cap/2).
  const double expected_spread = 1 / std::pow(std::cos(cap_deg / 2 * kPi / 180), 4);
  EXPECT_NEAR(lscm.area_ratio_max / lscm.area_ratio_min, expected_spread, 0.1 * (expected_spread - 1));
  EXPECT_LT(lscm.area_ratio_min, 1);
  EXPECT_GT(lscm.area_ratio_max, 1);
  EXPECT_GT(lscm.angle_error_max_deg, 0.01);
  EXPECT_LT(lscm.angle_error_max_deg, 10);
  // ARAP trades angles for areas.
  EXPECT_LT(arap.area_ratio_max / arap.area_ratio_min, lscm.area_ratio_max / lscm.area_ratio_min);
  EXPECT_GT(arap.area_ratio_min, 0);
}

TEST(Chart, ClosedSphereIsRefused) {
  const Mesh sphere = shapes::icosphere(10, 2);
  std::vector<char> all(sphere.num_faces(), 1);
  const ContactSurface everything = make_contact_surface(sphere, all, "all faces");
  try {
    compute_chart(sphere, everything);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("0 borders and Euler characteristic V - E + F = 2"),
              std::string::npos)
        << e.what();
  }
}

TEST(Chart, ClosedTubeIsRefused) {
  const Mesh tube = shapes::cylindrical_shell(30, 33, 360, 20, 24, 2);
  try {
    compute_chart(tube, contact_group(tube));
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("2 borders and Euler characteristic V - E + F = 0"),
              std::string::npos)
        << e.what();
  }
}

TEST(Chart, TwoBandsAreLaidSideBySide) {
  const Mesh one = shapes::cylindrical_shell(30, 33, 90, 20, 16, 2);
  Mesh other = shapes::cylindrical_shell(20, 22, 60, 10, 12, 2);
  for (auto& v : other.vertices) v += Vec3(100, 0, 0);
  const Mesh both = merged(one, other);
  const ContactSurface contact = contact_group(both);
  ASSERT_EQ(contact.components, 2);
  ChartOptions o;
  o.component_gap_mm = 3;
  const Chart c = compute_chart(both, contact, o);
  EXPECT_EQ(c.components, 2);
  double first_max = -1e9, second_min = 1e9;
  for (int v = 0; v < both.num_vertices(); ++v) {
    if (std::isnan(c.uv[v].x())) continue;
    if (v < one.num_vertices())
      first_max = std::max(first_max, c.uv[v].x());
    else
      second_min = std::min(second_min, c.uv[v].x());
  }
  EXPECT_NEAR(second_min - first_max, 3, 1e-9);
  EXPECT_NEAR(c.area_ratio_min, 1, 1e-6);
  EXPECT_NEAR(c.area_ratio_max, 1, 1e-6);
  EXPECT_TRUE(c.uv_min.isZero(1e-12));
}

}  // namespace
}  // namespace clearfit
