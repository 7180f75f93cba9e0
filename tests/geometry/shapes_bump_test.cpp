// The freeform bump plate: closed and outward-oriented, its groups, and its
// volume (divergence theorem over the mesh) against a Simpson-rule integral
// of the height field sampled at a much finer tessellation's top vertices.
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "../support/mesh_checks.hpp"

using namespace clearfit;

namespace {

constexpr double kSx = 60, kSy = 40, kThickness = 3, kBumpHeight = 2;
constexpr int kBumps = 12;
constexpr unsigned kSeed = 7;

Mesh plate(int n) { return shapes::bump_plate(kSx, kSy, kThickness, n, kBumps, kBumpHeight, kSeed); }

// Composite Simpson weights for an even number of intervals.
double simpson_weight(int i, int n) { return i == 0 || i == n ? 1.0 : (i % 2 ? 4.0 : 2.0); }

// Integral of the top height over the plate from the top vertices of `m`
// (every vertex with z > 0; an (n+1) x (n+1) grid), Simpson in x and y.
double simpson_volume(const Mesh& m, int n) {
  std::vector<Vec3> top;
  for (const Vec3& v : m.vertices)
    if (v.z() > 0) top.push_back(v);
  EXPECT_EQ(top.size(), static_cast<std::size_t>((n + 1) * (n + 1)));
  std::sort(top.begin(), top.end(), [](const Vec3& a, const Vec3& b) { return a.y() != b.y() ? a.y() < b.y() : a.x() < b.x(); });
  double sum = 0;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) sum += simpson_weight(i, n) * simpson_weight(j, n) * top[j * (n + 1) + i].z();
  return sum * (kSx / n / 3) * (kSy / n / 3);
}

}  // namespace

TEST(BumpPlate, ClosedOutwardWithGroups) {
  for (int n : {1, 7, 40}) {
    const Mesh m = plate(n);
    m.check_consistent();
    EXPECT_TRUE(test::closed_and_consistent(m)) << n;
    EXPECT_EQ(m.num_faces(), 4 * n * n + 8 * n) << n;
    EXPECT_GT(signed_volume(m), 0) << n;
    double top_max = 0;
    for (int f = 0; f < m.num_faces(); ++f) {
      const std::string& g = m.groups[m.face_group[f]];
      const Vec3 nrm = m.face_normal(f);
      if (g == "contact") {
        EXPECT_NEAR(nrm.z(), -1, 1e-15);
        for (int k = 0; k < 3; ++k) EXPECT_EQ(m.corner(f, k).z(), 0.0);
      } else if (g == "outer") {
        EXPECT_GT(nrm.z(), 0);
        for (int k = 0; k < 3; ++k) {
          EXPECT_GE(m.corner(f, k).z(), kThickness);
          top_max = std::max(top_max, m.corner(f, k).z());
        }
      } else {
        ASSERT_EQ(g, "side");
        EXPECT_NEAR(nrm.z(), 0, 1e-15);
        // Walls face away from the plate's centre.
        const Vec3 c = (m.corner(f, 0) + m.corner(f, 1) + m.corner(f, 2)) / 3;
        EXPECT_GT(nrm.x() * c.x() + nrm.y() * c.y(), 0);
      }
    }
    if (n == 40) {  // the bumps are there and overlap at most a few deep
      EXPECT_GT(top_max, kThickness + 0.4 * kBumpHeight);
      EXPECT_LT(top_max, kThickness + 4 * kBumpHeight);
    }
  }
}

TEST(BumpPlate, SameSeedSamePlateOtherSeedOther) {
  const Mesh a = plate(10), b = plate(10);
  const Mesh c = shapes::bump_plate(kSx, kSy, kThickness, 10, kBumps, kBumpHeight, kSeed + 1);
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_NE(a.vertices, c.vertices);
  const Mesh flat = shapes::bump_plate(kSx, kSy, kThickness, 10, kBumps, 0.0, kSeed);
  EXPECT_NEAR(signed_volume(flat), kSx * kSy * kThickness, 1e-9);
  EXPECT_THROW(shapes::bump_plate(kSx, kSy, 0, 10, 3, 1, 1), std::invalid_argument);
  EXPECT_THROW(shapes::bump_plate(kSx, kSy, 1, 10, 3, -1, 1), std::invalid_argument);
}

TEST(BumpPlate, VolumeConvergesToTheHeightFieldIntegral) {
  const int n_ref = 400;
  const double reference = simpson_volume(plate(n_ref), n_ref);
  std::printf("  seed %u, reference volume %.9f mm^3\n", kSeed, reference);
  double previous = 0;
  for (int n : {16, 32, 64, 128}) {
    const double v = signed_volume(plate(n));
    const double err = std::abs(v - reference);
    const double order = previous > 0 ? std::log2(previous / err) : NAN;
    std::printf("  n %4d  volume %.6f  error %.3e  order %.2f\n", n, v, err, order);
    EXPECT_LT(err, 2e-3 * reference) << n;
    if (previous > 0) {
      EXPECT_GT(order, 1.6) << n;  // piecewise-linear surface: second order
    }
    previous = err;
  }
  EXPECT_LT(previous, 4e-5 * reference);
}

// The random freeform family: closed and outward for every kind and several
// seeds, the part between its surfaces (positive volume, thickness within the
// drawn range), and the same part for the same seed.
TEST(RandomFreeform, ClosedOutwardAndReproducible) {
  for (const auto kind : {shapes::Freeform::height_field, shapes::Freeform::shell})
    for (unsigned seed : {1u, 2u, 3u, 99u}) {
      const Mesh m = shapes::random_freeform(kind, seed, 24);
      m.check_consistent();
      EXPECT_TRUE(test::closed_and_consistent(m)) << shapes::to_string(kind) << " " << seed;
      EXPECT_EQ(m.num_faces(), 4 * 24 * 24 + 8 * 24);
      // Volume against area x mean thickness: 2.5 mm ± 25 %, over 40 x [25, 40] mm.
      const double v = signed_volume(m);
      EXPECT_GT(v, 0.75 * 2.5 * 40 * 25 * 0.9) << shapes::to_string(kind) << " " << seed;
      EXPECT_LT(v, 1.25 * 2.5 * 40 * 40 * 1.1) << shapes::to_string(kind) << " " << seed;
      const Mesh again = shapes::random_freeform(kind, seed, 24);
      EXPECT_EQ(again.vertices, m.vertices);
    }
  EXPECT_NE(shapes::random_freeform(shapes::Freeform::shell, 1, 8).vertices,
            shapes::random_freeform(shapes::Freeform::shell, 2, 8).vertices);
  EXPECT_THROW(shapes::random_freeform(shapes::Freeform::shell, 1, 0), std::invalid_argument);
}
