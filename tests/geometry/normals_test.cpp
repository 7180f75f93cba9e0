// Crease-split vertex normals against the exact normals of analytic surfaces.
#include <clearfit/geometry/normals.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace clearfit;

TEST(Normals, BoxKeepsFaceNormalsAtCreases) {
  Mesh m = shapes::box({1, 2, 3}, 3);
  CornerNormals n = compute_corner_normals(m);
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR((n.corner[f][k] - m.face_normal(f)).norm(), 0, 1e-14);
}

TEST(Normals, SmoothAcrossCreasesAboveTheThreshold) {
  // With a 100° threshold the box's 90° edges are smoothed: a corner vertex
  // gets the normalised mean of its three faces (angle weights are equal).
  Mesh m = shapes::box({1, 1, 1}, 1);
  NormalOptions opt;
  opt.crease_angle_deg = 100;
  CornerNormals n = compute_corner_normals(m, opt);
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Vec3 expected = m.corner(f, k).normalized();  // corners at (±.5, ±.5, ±.5)
      EXPECT_NEAR((n.corner[f][k] - expected).norm(), 0, 1e-12);
    }
}

TEST(Normals, SphereNormalsConvergeToRadial) {
  // (Subdivision 1 is exactly radial by symmetry; from 2 on the error must
  // shrink steadily: at least 1.6x per level, first order or better.)
  double previous = 1;
  for (int s = 2; s <= 5; ++s) {
    Mesh m = shapes::icosphere(5, s);
    CornerNormals n = compute_corner_normals(m);
    double worst = 0;
    for (int f = 0; f < m.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) worst = std::max(worst, (n.corner[f][k] - m.corner(f, k).normalized()).norm());
    EXPECT_LT(worst * 1.6, previous) << "subdivision " << s;
    previous = worst;
  }
  EXPECT_LT(previous, 1.5e-3);
}

TEST(Normals, ShellSurfacesKeepTheirOwnNormals) {
  // The inner (contact) and outer surfaces of a band meet the side walls at 90°:
  // their corner normals must not lean towards the walls (no y component) and
  // stay within half a segment angle of the radial direction.
  const int n_around = 64;
  const double half_segment = 120.0 / n_around / 2 * M_PI / 180;
  Mesh m = shapes::cylindrical_shell(30, 33, 120, 10, n_around, 4);
  CornerNormals n = compute_corner_normals(m);
  for (int f = 0; f < m.num_faces(); ++f) {
    const std::string& g = m.groups[m.face_group[f]];
    if (g == "side") continue;
    for (int k = 0; k < 3; ++k) {
      Vec3 radial(m.corner(f, k).x(), 0, m.corner(f, k).z());
      radial.normalize();
      if (g == "contact") radial = -radial;
      EXPECT_NEAR(n.corner[f][k].y(), 0.0, 1e-12);
      EXPECT_GE(n.corner[f][k].dot(radial), std::cos(half_segment) - 1e-12);
    }
  }
}

TEST(Normals, AreaWeightingAndInterpolation) {
  Mesh m = shapes::icosphere(1, 2);
  NormalOptions opt;
  opt.weighting = NormalOptions::Weighting::area;
  CornerNormals n = compute_corner_normals(m, opt);
  const Vec3 mid = n.interpolate(0, 1.0 / 3, 1.0 / 3, 1.0 / 3);
  EXPECT_NEAR(mid.norm(), 1.0, 1e-14);
  EXPECT_GT(mid.dot(m.face_normal(0)), 0.99);
  opt.crease_angle_deg = -1;
  EXPECT_THROW(compute_corner_normals(m, opt), std::invalid_argument);
}

TEST(Normals, DegenerateFaceGetsNoNaN) {
  Mesh m = shapes::box({1, 1, 1});
  m.vertices.push_back({0, 0, 0.5});
  m.faces.push_back({m.faces[0][0], m.faces[0][0], m.num_vertices() - 1});  // repeated vertex
  m.file_face.push_back(m.num_faces() - 1);
  m.face_group.push_back(0);
  CornerNormals n = compute_corner_normals(m);
  for (const auto& c : n.corner)
    for (const Vec3& v : c) EXPECT_TRUE(v.allFinite());
}

TEST(Normals, ZeroAreaTriangleAlongACreaseDoesNotSmoothIt) {
  // A top triangle of a box split at the midpoint p of its edge on the rim,
  // closed by the zero-area triangle (a, b, p) that lies along the crease
  // between the top and a side. It must neither join the top to the side nor
  // lend a normal of either sign: every top corner keeps +z, every side corner
  // its own normal. (Found by the numerical-limits sweep: such triangles tilted
  // the top's normals by up to 45 degrees at the rim.)
  for (double along : {0.5, 0.3}) {  // an exact midpoint, and a point computed with rounding
    Mesh m = shapes::box({1, 1, 1});
    const int top = static_cast<int>(std::find(m.groups.begin(), m.groups.end(), "top") - m.groups.begin());
    const int f = static_cast<int>(std::find(m.face_group.begin(), m.face_group.end(), top) - m.face_group.begin());
    int r = 0;  // rotate the corners so that (a, b) is the edge on the rim, not the diagonal
    while (std::abs((0.5 * (m.corner(f, r) + m.corner(f, (r + 1) % 3))).head<2>().cwiseAbs().maxCoeff() - 0.5) > 1e-12) ++r;
    const int a = m.faces[f][r], b = m.faces[f][(r + 1) % 3], c = m.faces[f][(r + 2) % 3];
    m.vertices.push_back((1 - along) * m.vertices[a] + along * m.vertices[b]);
    const int p = m.num_vertices() - 1;
    m.faces[f] = {a, p, c};
    for (const std::array<int, 3>& t : {std::array<int, 3>{p, b, c}, {a, b, p}}) {
      m.faces.push_back(t);
      m.face_group.push_back(top);
      m.file_face.push_back(m.num_faces() - 1);
    }
    const CornerNormals n = compute_corner_normals(m);
    for (int g = 0; g < m.num_faces(); ++g) {
      const Vec3 own = m.face_normal(g);
      if (m.face_area(g) < 1e-12) continue;  // the zero-area triangle itself
      for (int k = 0; k < 3; ++k)
        EXPECT_LT((n.corner[g][k] - own).norm(), 1e-12) << "along " << along << ", face " << g << " corner " << k << ": "
                                                        << n.corner[g][k].transpose() << " vs " << own.transpose();
    }
  }
}
