// Properties of the mesh-based trace that hold whatever the shape: reciprocity,
// Fermat's principle (flat normals), invariance under scaling and rigid
// motion, and a stress run of random rays from random poses.
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map.hpp>
#include <gtest/gtest.h>

#include "../support/trace_part.hpp"

#include <random>

using namespace clearfit;

namespace {

using Part = test::TracePart;

// Rays from random points above a dome or band towards random points of its
// contact surface: mostly valid, with grazing, TIR and edge cases mixed in.
std::vector<Ray> random_rays(const Mesh& m, int n, std::mt19937_64& rng, double distance) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> face(0, m.num_faces() - 1), corner(0, 2);
  std::vector<Ray> rays(n);
  for (int i = 0; i < n; ++i) {
    const Vec3 eye(u(rng) * distance, u(rng) * distance, distance * (1.2 + 0.5 * u(rng)));
    const int f = face(rng);
    Vec3 target;
    switch (i % 4) {
      case 0: target = m.corner(f, corner(rng)); break;                           // exactly at a vertex
      case 1: target = 0.5 * (m.corner(f, 0) + m.corner(f, 1)); break;           // on an edge
      default: {
        double a = std::abs(u(rng)), b = std::abs(u(rng));
        if (a + b > 1) a = 1 - a, b = 1 - b;
        target = m.corner(f, 0) + a * (m.corner(f, 1) - m.corner(f, 0)) + b * (m.corner(f, 2) - m.corner(f, 0));
      }
    }
    rays[i] = Ray{eye, target - eye};
  }
  return rays;
}

}  // namespace

TEST(MapProperties, ReciprocityTracingBackReachesTheCamera) {
  Part dome(shapes::spherical_shell(25, 27.5, 40, 24, 96));
  std::mt19937_64 rng(20261122);
  std::printf("  seed 20261122\n");
  const auto rays = random_rays(dome.mesh, 2000, rng, 40);
  std::vector<SkinSample> out(rays.size());
  MapOptions opt;
  trace_skin_rays(dome.scene(), rays, out, opt);
  int checked = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (out[i].status != PixelStatus::valid) continue;
    ++checked;
    // Back from the skin point along the refracted ray reaches the entry point...
    const Vec3 back = -out[i].refracted_dir;
    const Vec3 to_entry = out[i].entry_point - out[i].skin_point;
    EXPECT_LT(to_entry.cross(back).norm(), 1e-9 * to_entry.norm());
    // ...and refracting it out of the part with the same normal leads to the camera.
    const auto t = optics::transmit(back, out[i].entry_normal, opt.indices.n_part, opt.indices.n_medium);
    ASSERT_FALSE(t.tir);
    const Vec3 to_eye = rays[i].origin - out[i].entry_point;
    EXPECT_LT(to_eye.cross(t.direction).norm(), 1e-9 * to_eye.norm());
  }
  EXPECT_GT(checked, 500);
}

TEST(MapProperties, FermatPathIsStationaryWithFlatNormals) {
  Part dome(shapes::spherical_shell(25, 27.5, 40, 12, 48));
  std::mt19937_64 rng(7);
  const auto rays = random_rays(dome.mesh, 400, rng, 40);
  std::vector<SkinSample> out(rays.size());
  MapOptions opt;
  opt.normals = MapOptions::Normals::flat;
  trace_skin_rays(dome.scene(), rays, out, opt);
  const double nm = opt.indices.n_medium, np = opt.indices.n_part;
  int checked = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (out[i].status != PixelStatus::valid) continue;
    const RayHit h = dome.index->intersect(Ray{rays[i].origin, rays[i].direction});
    const Vec3 O = rays[i].origin, E = out[i].entry_point, S = out[i].skin_point;
    const Vec3 n = h.geometric_normal;
    const Vec3 t1 = n.unitOrthogonal(), t2 = n.cross(t1);
    auto path = [&](const Vec3& e) { return nm * (e - O).norm() + np * (S - e).norm(); };
    const double step = 1e-5;
    for (const Vec3& t : {t1, t2}) {
      const double grad = (path(E + step * t) - path(E - step * t)) / (2 * step);
      EXPECT_NEAR(grad, 0, 1e-6);
    }
    // Not stationary when the point is moved off it: the test can fail.
    EXPECT_GT(std::abs(path(E + 0.05 * t1) - path(E - 0.05 * t1)) + std::abs(path(E + 0.05 * t2) - path(E - 0.05 * t2)) +
                  path(E + 0.05 * t1) - path(E),
              0);
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(MapProperties, InvariantUnderScaleAndRigidMotion) {
  const Mesh base = shapes::cylindrical_shell(30, 32.5, 120, 20, 48, 4);
  Part part(base);
  std::mt19937_64 rng(99);
  const auto rays = random_rays(base, 3000, rng, 50);
  std::vector<SkinSample> ref(rays.size());
  trace_skin_rays(part.scene(), rays, ref);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 shift(120, -45, 7.5);
  struct Motion {
    double scale;
    bool rotate;
  };
  for (const Motion mo : {Motion{1e-3, false}, Motion{1e3, false}, Motion{1.0, true}}) {
    auto apply = [&](const Vec3& p) { return mo.rotate ? Vec3(R * p + shift) : Vec3(mo.scale * p); };
    Mesh moved = base;
    for (Vec3& v : moved.vertices) v = apply(v);
    Part other(std::move(moved));
    std::vector<Ray> rays2(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i)
      rays2[i] = Ray{apply(rays[i].origin), mo.rotate ? Vec3(R * rays[i].direction) : rays[i].direction};
    std::vector<SkinSample> out(rays.size());
    trace_skin_rays(other.scene(), rays2, out);
    int same = 0, valid = 0, other_face = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      same += out[i].status == ref[i].status;
      if (out[i].status != PixelStatus::valid || ref[i].status != PixelStatus::valid) continue;
      // Rays aimed exactly at a vertex or an edge (i % 4 < 2) may enter
      // through the neighbouring face after rounding, and at a crease that is
      // another outcome: the stress test covers them; compare the others.
      if (i % 4 < 2) continue;
      if (out[i].entry_face != ref[i].entry_face || out[i].face != ref[i].face) {
        ++other_face;
        continue;
      }
      ++valid;
      const Vec3 expected = apply(ref[i].skin_point);
      const double size = mo.rotate ? 50.0 : 50.0 * mo.scale;
      EXPECT_LT((out[i].skin_point - expected).norm(), 1e-9 * size) << "scale " << mo.scale;
      EXPECT_NEAR(out[i].transmittance, ref[i].transmittance, 1e-9);
    }
    EXPECT_LT(other_face, static_cast<int>(rays.size()) / 500) << "scale " << mo.scale;
    EXPECT_GE(same, static_cast<int>(rays.size()) * 95 / 100) << "scale " << mo.scale;
    EXPECT_GT(valid, 500);
  }
}

TEST(MapProperties, StressRandomPosesNoNaNEveryInvalidHasAReason) {
  // A million rays from random poses by default (CLEARFIT_RAY_TEST_SCALE scales it).
  const int n = static_cast<int>(1'000'000 * test::ray_test_scale());
  std::mt19937_64 rng(12345);
  std::printf("  seed 12345, %d rays\n", n);
  for (Mesh m : {shapes::spherical_shell(25, 27.5, 40, 16, 64), shapes::cylindrical_shell(30, 32.5, 200, 20, 64, 4)}) {
    Part part(std::move(m));
    const auto rays = random_rays(part.mesh, n / 2, rng, 60);
    std::vector<SkinSample> out(rays.size());
    trace_skin_rays(part.scene(), rays, out);
    long long counts[kPixelStatusCount] = {};
    for (const SkinSample& s : out) {
      const int k = static_cast<int>(s.status);
      ASSERT_GE(k, 0);
      ASSERT_LT(k, kPixelStatusCount);
      ++counts[k];
      if (s.status == PixelStatus::valid) {
        ASSERT_TRUE(s.skin_point.allFinite());
        ASSERT_TRUE(std::isfinite(s.transmittance) && s.transmittance > 0 && s.transmittance <= 1);
        ASSERT_TRUE(std::isfinite(s.incidence_deg) && std::isfinite(s.contact_deg));
        ASSERT_GE(s.face, 0);
      } else {
        ASSERT_FALSE(s.skin_point.allFinite());
      }
    }
    for (int k = 0; k < kPixelStatusCount; ++k)
      if (counts[k]) std::printf("  %-16s %lld\n", to_string(static_cast<PixelStatus>(k)), counts[k]);
    EXPECT_GT(counts[0], static_cast<long long>(rays.size()) / 4);
  }
}

TEST(MapProperties, GrazingAndCriticalContactAreClassified) {
  // A plate in air seen so steeply that the refracted ray meets the contact
  // face beyond the part→air critical angle: with an air gap (n_skin = 1) the
  // pixel sees a reflection (contact_tir), with skin in contact it sees skin.
  Part slab(shapes::slab(400, 400, 3, 2));
  MapOptions air;
  air.indices.n_skin = 1.0;
  const Vec3 eye(0, 0, 5);  // 2 mm above the plate: even 88° lands on it
  for (double angle_deg : {10.0, 45.0, 80.0, 88.0}) {
    const double a = angle_deg * M_PI / 180;
    const Vec3 dir(std::sin(a), 0, -std::cos(a));
    const SkinSample gap = trace_skin_ray(slab.scene(), eye, dir, air);
    const SkinSample skin = trace_skin_ray(slab.scene(), eye, dir);
    // Snell: sin θ_part = sin θ / 1.49 < 1/1.49 always, so leaving into air (n=1)
    // is never beyond critical for a parallel plate; into skin 1.4 neither.
    EXPECT_EQ(gap.status, PixelStatus::valid) << angle_deg;
    EXPECT_EQ(skin.status, PixelStatus::valid) << angle_deg;
    EXPECT_LT(skin.transmittance, 1.0);
    EXPECT_GT(skin.transmittance, gap.transmittance) << "skin contact transmits more than an air gap";
  }
}
