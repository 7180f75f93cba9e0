// validate_mesh / repair_mesh against analytic shapes and named defects.
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/geometry/validate.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace clearfit {
namespace {

constexpr double kPi = std::numbers::pi;

// A mesh of loose triangles given by their corner points; vertices are shared
// where the same point appears twice.
Mesh soup(const std::vector<std::array<Vec3, 3>>& triangles) {
  Mesh m;
  auto vertex = [&](const Vec3& p) {
    for (int i = 0; i < m.num_vertices(); ++i)
      if (m.vertices[i] == p) return i;
    m.vertices.push_back(p);
    return m.num_vertices() - 1;
  };
  for (const auto& t : triangles) m.faces.push_back({vertex(t[0]), vertex(t[1]), vertex(t[2])});
  for (int f = 0; f < m.num_faces(); ++f) m.file_face.push_back(f);
  return m;
}

void flip(Mesh& m, int f) { std::swap(m.faces[f][1], m.faces[f][2]); }

// Appends `b` to `a` (vertices renumbered, file faces continue).
Mesh merged(Mesh a, const Mesh& b) {
  const int nv = a.num_vertices(), nf = a.num_faces();
  a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto f : b.faces) a.faces.push_back({f[0] + nv, f[1] + nv, f[2] + nv});
  for (int f = 0; f < b.num_faces(); ++f) a.file_face.push_back(nf + f);
  a.face_group.clear();
  a.groups.clear();
  return a;
}

Mesh translated(Mesh m, const Vec3& d) {
  for (auto& v : m.vertices) v += d;
  return m;
}

ContactSurface contact_group(const Mesh& m, const std::string& name = "contact") {
  ContactSelector s;
  s.group = name;
  return select_contact(m, s);
}

TEST(ValidateOptions, DefaultsPassAndBadValuesNameTheField) {
  EXPECT_NO_THROW(ValidationOptions{}.validate());
  ValidationOptions o;
  o.sliver_min_angle_deg = -1;
  try {
    o.validate();
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sliver_min_angle_deg"), std::string::npos);
  }
}

TEST(Validate, BoxAreaVolumeClosedOutward) {
  const Vec3 size(2, 3, 4);
  const Mesh box = shapes::box(size, 3);
  const ValidationReport r = validate_mesh(box);
  EXPECT_TRUE(r.ok()) << (r.warnings.empty() ? "" : r.warnings[0]);
  EXPECT_TRUE(r.closed);
  EXPECT_EQ(r.boundary_loops, 0);
  EXPECT_TRUE(r.consistently_oriented);
  ASSERT_TRUE(r.outward.has_value());
  EXPECT_TRUE(*r.outward);
  EXPECT_NEAR(r.area_mm2, 2 * (2 * 3 + 3 * 4 + 4 * 2), 1e-9);
  ASSERT_TRUE(r.volume_mm3.has_value());
  EXPECT_NEAR(*r.volume_mm3, 24, 1e-9);
  EXPECT_EQ(r.components, 1);
  EXPECT_TRUE(r.self_intersections_checked);
  EXPECT_EQ(r.self_intersection_count, 0);  // neighbours along edges and vertices do not count
  EXPECT_TRUE(r.degenerate_faces.empty());
  EXPECT_TRUE(r.sliver_faces.empty());
  EXPECT_TRUE(r.bbox_min.isApprox(-size / 2));
  EXPECT_TRUE(r.bbox_max.isApprox(size / 2));
  EXPECT_TRUE(r.warnings.empty());
  Mesh copy = box;
  EXPECT_TRUE(repair_mesh(copy).empty());
  EXPECT_EQ(copy.faces, box.faces);
}

TEST(Validate, InsideOutBoxIsReportedAndRepaired) {
  Mesh box = shapes::box(Vec3(2, 3, 4), 2);
  for (int f = 0; f < box.num_faces(); ++f) flip(box, f);
  const ValidationReport r = validate_mesh(box);
  EXPECT_TRUE(r.consistently_oriented);
  ASSERT_TRUE(r.outward.has_value());
  EXPECT_FALSE(*r.outward);
  EXPECT_FALSE(r.ok());
  EXPECT_NEAR(r.volume_mm3.value(), 24, 1e-9);  // the enclosed volume, whatever the orientation
  EXPECT_LT(signed_volume(box), 0);
  const auto changes = repair_mesh(box);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_NE(changes[0].find("reversed " + std::to_string(box.num_faces()) + " faces"), std::string::npos)
      << changes[0];
  EXPECT_TRUE(validate_mesh(box).ok());
  EXPECT_NEAR(signed_volume(box), 24, 1e-9);
}

TEST(Validate, OneFlippedFaceIsInconsistentAndRepaired) {
  Mesh box = shapes::box(Vec3(1, 1, 1), 2);
  flip(box, 5);
  const ValidationReport r = validate_mesh(box);
  EXPECT_FALSE(r.consistently_oriented);
  EXPECT_FALSE(r.outward.has_value());
  EXPECT_FALSE(r.ok());
  const auto changes = repair_mesh(box);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0],
            "reversed 1 face to agree with their neighbours (one orientation per piece): file faces 5");
  EXPECT_TRUE(validate_mesh(box).ok());
}

TEST(Validate, OpenStripIsMadeConsistentKeepingTheMajority) {
  // Four triangles in a row in the z = 0 plane, the third one flipped.
  std::vector<std::array<Vec3, 3>> t;
  for (int i = 0; i < 2; ++i) {
    const Vec3 a(i, 0, 0), b(i + 1, 0, 0), c(i + 1, 1, 0), d(i, 1, 0);
    t.push_back({a, b, c});
    t.push_back({a, c, d});
  }
  Mesh m = soup(t);
  flip(m, 2);
  EXPECT_FALSE(validate_mesh(m).consistently_oriented);
  const auto changes = repair_mesh(m);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_NE(changes[0].find("file faces 2"), std::string::npos);
  for (int f = 0; f < m.num_faces(); ++f) EXPECT_GT(m.face_normal(f).z(), 0.99);
  const auto r = validate_mesh(m);
  EXPECT_TRUE(r.consistently_oriented);
  EXPECT_FALSE(r.outward.has_value());  // open: no inside
}

TEST(Validate, BoxWithMissingFacesHasBoundaryLoops) {
  Mesh box = shapes::box(Vec3(1, 1, 1), 2);
  Mesh one = box;
  one.faces.erase(one.faces.begin() + 3);
  one.file_face.erase(one.file_face.begin() + 3);
  one.face_group.erase(one.face_group.begin() + 3);
  ValidationReport r = validate_mesh(one);
  EXPECT_FALSE(r.closed);
  EXPECT_EQ(r.boundary_loops, 1);
  EXPECT_FALSE(r.volume_mm3.has_value());
  EXPECT_FALSE(r.outward.has_value());
  EXPECT_FALSE(r.ok());
  EXPECT_NE(r.warnings.at(0).find("1 boundary loop"), std::string::npos) << r.warnings[0];

  // Remove the face nearest the centre of each of the six sides (n = 3: it
  // touches no other side): six separate holes.
  const Mesh six = shapes::box(Vec3(1, 1, 1), 3);
  std::vector<int> nearest(six.groups.size(), -1);
  auto off_centre = [&](int f) {
    const Vec3 c = (six.corner(f, 0) + six.corner(f, 1) + six.corner(f, 2)) / 3;
    return (c - 0.5 * six.face_normal(f)).norm();
  };
  for (int f = 0; f < six.num_faces(); ++f) {
    int& best = nearest[six.face_group[f]];
    if (best < 0 || off_centre(f) < off_centre(best)) best = f;
  }
  Mesh holes;
  holes.vertices = six.vertices;
  for (int f = 0; f < six.num_faces(); ++f)
    if (std::find(nearest.begin(), nearest.end(), f) == nearest.end())
      holes.faces.push_back(six.faces[f]), holes.file_face.push_back(f);
  r = validate_mesh(holes);
  EXPECT_EQ(r.boundary_loops, 6);
  EXPECT_EQ(r.components, 1);
  EXPECT_EQ(r.non_manifold_vertices, 0);
}

TEST(Validate, DuplicateFaceIsFoundInAnyVertexOrder) {
  Mesh box = shapes::box(Vec3(1, 1, 1), 1);
  const auto f = box.faces[4];
  box.faces.push_back({f[2], f[0], f[1]});
  box.file_face.push_back(box.num_faces() - 1);
  box.face_group.push_back(box.face_group[4]);
  const ValidationReport r = validate_mesh(box);
  ASSERT_EQ(r.duplicate_faces.size(), 1u);
  EXPECT_EQ(r.duplicate_faces[0], (std::array<int, 2>{4, 12}));
  EXPECT_EQ(r.non_manifold_edges, 3);
  EXPECT_EQ(r.self_intersection_count, 0);  // the duplicate is reported as such, not twice
  EXPECT_FALSE(r.ok());
}

TEST(Validate, DegenerateFacesAreReportedByFileIndexAndDropped) {
  Mesh box = shapes::box(Vec3(1, 1, 1), 1);
  // As if the importer had already dropped every odd file triangle.
  for (int f = 0; f < box.num_faces(); ++f) box.file_face[f] = 2 * f;
  const int v0 = box.faces[0][0], v1 = box.faces[0][1];
  box.vertices.push_back(0.5 * (box.vertices[v0] + box.vertices[v1]));  // midpoint of an edge
  const int mid = box.num_vertices() - 1;
  box.faces.push_back({v0, v0, v1});   // repeated vertex
  box.faces.push_back({v0, mid, v1});  // collinear: zero area
  box.file_face.push_back(24);
  box.file_face.push_back(26);
  box.face_group.push_back(-1);
  box.face_group.push_back(-1);
  ValidationReport r = validate_mesh(box);
  EXPECT_EQ(r.degenerate_faces, (std::vector<int>{24, 26}));
  EXPECT_TRUE(r.sliver_faces.empty());  // degenerate faces are not also slivers
  EXPECT_FALSE(r.ok());
  const auto changes = repair_mesh(box);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0], "dropped 2 degenerate faces (no area, or a repeated vertex): file faces 24, 26");
  EXPECT_EQ(box.num_faces(), 12);
  EXPECT_EQ(box.file_face.back(), 22);
  EXPECT_EQ(box.face_group.size(), 12u);
  r = validate_mesh(box);
  EXPECT_TRUE(r.ok()) << r.warnings.at(0);
}

TEST(Validate, SliverIsFlaggedByItsSmallestAngle) {
  // Smallest angle of the sliver: atan(0.05 / 5) = 0.573°.
  const Mesh m = soup(
      {{Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(5, 0.05, 0)}, {Vec3(0, 0, 0), Vec3(5, -5, 0), Vec3(10, 0, 0)}});
  EXPECT_EQ(validate_mesh(m).sliver_faces, (std::vector<int>{0}));
  ValidationOptions o;
  o.sliver_min_angle_deg = 0.5;
  EXPECT_TRUE(validate_mesh(m, nullptr, o).sliver_faces.empty());
}

TEST(Validate, NonManifoldEdgeOfThreeTriangles) {
  const Vec3 a(0, 0, 0), b(1, 0, 0);
  const Mesh m = soup({{a, b, Vec3(0.5, 1, 0)}, {b, a, Vec3(0.5, -1, 0)}, {a, b, Vec3(0.5, 0, 1)}});
  const ValidationReport r = validate_mesh(m);
  EXPECT_EQ(r.non_manifold_edges, 1);
  EXPECT_EQ(r.non_manifold_vertices, 0);
  EXPECT_EQ(r.components, 1);
  EXPECT_EQ(r.self_intersection_count, 0);
  EXPECT_FALSE(r.ok());
}

TEST(Validate, BowtieVertexHasTwoFans) {
  const Vec3 o(0, 0, 0);
  const Mesh m = soup({{o, Vec3(1, 0, 0), Vec3(1, 1, 0)}, {o, Vec3(-1, 0, 0), Vec3(-1, -1, 0)}});
  const ValidationReport r = validate_mesh(m);
  EXPECT_EQ(r.non_manifold_vertices, 1);
  EXPECT_EQ(r.non_manifold_edges, 0);
  EXPECT_EQ(r.components, 2);
  EXPECT_EQ(r.boundary_loops, 2);
  EXPECT_EQ(r.self_intersection_count, 0);
}

TEST(Validate, UnweldedSeamIsNamed) {
  Mesh m = soup({{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}});
  m.vertices.insert(m.vertices.end(),
                    {Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)});  // same points, new indices
  m.faces.push_back({3, 4, 5});
  m.file_face.push_back(1);
  const ValidationReport r = validate_mesh(m);
  EXPECT_EQ(r.boundary_loops, 2);
  EXPECT_EQ(r.components, 2);
  EXPECT_NE(r.warnings.back().find("2 vertices sit exactly on another vertex"), std::string::npos)
      << r.warnings.back();
}

TEST(Validate, SelfIntersectionCasesAgainstGeometry) {
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  // Crossing: a vertical triangle pierces the horizontal one.
  EXPECT_EQ(validate_mesh(soup({{a, b, c}, {Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1), Vec3(3, 3, 0.1)}}))
                .self_intersection_count,
            1);
  // Far apart: none.
  EXPECT_EQ(validate_mesh(soup({{a, b, c}, {Vec3(5, 5, -1), Vec3(5, 5, 1), Vec3(6, 6, 0)}}))
                .self_intersection_count,
            0);
  // Shared edge, coplanar, folded over onto the same side: overlap.
  EXPECT_EQ(validate_mesh(soup({{a, b, c}, {b, a, Vec3(1, 1, 0)}})).self_intersection_count, 1);
  // Shared edge, coplanar, on opposite sides: a normal neighbour.
  EXPECT_EQ(validate_mesh(soup({{a, b, c}, {b, a, Vec3(1, -1, 0)}})).self_intersection_count, 0);
  // Shared vertex, the other triangle's far edge pokes through.
  EXPECT_EQ(
      validate_mesh(soup({{a, b, c}, {a, Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1)}})).self_intersection_count,
      1);
  // Shared vertex only touching there.
  EXPECT_EQ(validate_mesh(soup({{a, b, c}, {a, Vec3(-1, 0, 1), Vec3(0, -1, 1)}})).self_intersection_count, 0);
  ValidationOptions off;
  off.check_self_intersections = false;
  const auto r = validate_mesh(soup({{a, b, c}, {b, a, Vec3(1, 1, 0)}}), nullptr, off);
  EXPECT_FALSE(r.self_intersections_checked);
  EXPECT_EQ(r.self_intersection_count, 0);
}

TEST(Validate, TwoIntersectingBoxes) {
  const Mesh a = shapes::box(Vec3(2, 2, 2), 2);
  const Mesh both = merged(a, translated(a, Vec3(1, 0.5, 0.25)));
  const ValidationReport r = validate_mesh(both);
  EXPECT_EQ(r.components, 2);
  EXPECT_TRUE(r.closed);
  EXPECT_GT(r.self_intersection_count, 0);
  EXPECT_EQ(r.self_intersection_count, static_cast<int>(r.self_intersections.size()));
  for (auto [f, g] : r.self_intersections) {  // every pair has one face of each box
    EXPECT_LT(f, a.num_faces());
    EXPECT_GE(g, a.num_faces());
  }
  EXPECT_FALSE(r.ok());
  // Moved apart they no longer intersect: two components, all fine.
  const ValidationReport apart = validate_mesh(merged(a, translated(a, Vec3(3, 0, 0))));
  EXPECT_EQ(apart.components, 2);
  EXPECT_EQ(apart.self_intersection_count, 0);
  EXPECT_TRUE(apart.ok());
  EXPECT_NEAR(apart.volume_mm3.value(), 16, 1e-9);
}

TEST(Validate, HollowBoxNeedsItsCavityFacingInward) {
  const Mesh outer = shapes::box(Vec3(4, 4, 4), 1), inner = shapes::box(Vec3(2, 2, 2), 1);
  Mesh cavity = inner;  // normals out of the material point into the cavity
  for (int f = 0; f < cavity.num_faces(); ++f) flip(cavity, f);
  ValidationReport r = validate_mesh(merged(outer, cavity));
  EXPECT_TRUE(r.outward.value());
  EXPECT_NEAR(r.volume_mm3.value(), 64 - 8, 1e-9);
  Mesh wrong = merged(outer, inner);
  r = validate_mesh(wrong);
  EXPECT_FALSE(r.outward.value());
  EXPECT_NEAR(r.volume_mm3.value(), 64 - 8, 1e-9);
  const auto changes = repair_mesh(wrong);
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_NE(
      changes[0].find(
          "reversed 12 faces so the normals point out of the part: file faces 12, 13, 14, 15, 16 and 7 more"),
      std::string::npos)
      << changes[0];
  EXPECT_TRUE(validate_mesh(wrong).ok());
}

TEST(Validate, IcosphereVolumeConvergesToTheBall) {
  const double radius = 3, ball = 4.0 / 3.0 * kPi * radius * radius * radius;
  double previous = 1;
  for (int s = 1; s <= 5; ++s) {
    const ValidationReport r = validate_mesh(shapes::icosphere(radius, s));
    ASSERT_TRUE(r.ok());
    const double error = (ball - r.volume_mm3.value()) / ball;
    EXPECT_GT(error, 0);               // inscribed polyhedron
    EXPECT_LT(error, previous / 3.5);  // second order: about 4x per subdivision
    previous = error;
  }
  EXPECT_LT(previous, 2e-3);
}

TEST(Validate, SlabThicknessFromTheContactSurface) {
  const Mesh slab = shapes::slab(30, 20, 2.5, 4);
  const ContactSurface contact = contact_group(slab);
  const ValidationReport r = validate_mesh(slab, &contact);
  EXPECT_TRUE(r.ok());
  EXPECT_NEAR(r.thickness_min_mm.value(), 2.5, 1e-12);
  EXPECT_NEAR(r.thickness_max_mm.value(), 2.5, 1e-12);
  EXPECT_NEAR(r.volume_mm3.value(), 30 * 20 * 2.5, 1e-9);
}

TEST(Validate, CylindricalShellThicknessIsTheWallWithinTessellation) {
  const double r_in = 30, r_out = 33, span = 120;
  const int n = 24;
  const Mesh shell = shapes::cylindrical_shell(r_in, r_out, span, 20, n, 3);
  const ContactSurface contact = contact_group(shell);
  const ValidationReport r = validate_mesh(shell, &contact);
  EXPECT_TRUE(r.ok());
  // Inner and outer facets are parallel planes at r cos(h), h half a facet's angle.
  const double h = span / n / 2 * kPi / 180;
  EXPECT_NEAR(r.thickness_min_mm.value(), (r_out - r_in) * std::cos(h), 1e-9);
  EXPECT_NEAR(r.thickness_max_mm.value(), (r_out - r_in) * std::cos(h), 1e-9);
  EXPECT_NEAR(r.thickness_max_mm.value(), r_out - r_in, (r_out - r_in) * (1 - std::cos(h)) + 1e-12);
  const double exact_volume = span / 360 * kPi * (r_out * r_out - r_in * r_in) * 20;
  EXPECT_NEAR(r.volume_mm3.value() / exact_volume, std::sin(2 * h) / (2 * h), 1e-12);  // polygon sectors
}

}  // namespace
}  // namespace clearfit
