// The exact map's fused pipeline (tiles of pixels, each cast twice in one go)
// and the ray index's skip face it relies on: the same answers as single rays
// and as the brute-force loop.
#include <clearfit/camera/pixel_unprojector.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map.hpp>
#include <clearfit/refraction/optics.hpp>
#include <gtest/gtest.h>

#include <array>

#include "../support/trace_part.hpp"

#include <algorithm>
#include <random>

using namespace clearfit;

namespace {

// Camera rays from above the dome at its vertices, edge midpoints and
// interiors, and the rays refracted into the part from where they enter
// (origin on the entry face, which is their skip face).
struct Leaving {
  std::vector<Ray> inward;
  std::vector<int> entry_face;
};
Leaving refracted_rays(const test::TracePart& part, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> face(0, part.mesh.num_faces() - 1);
  Leaving out;
  for (int i = 0; i < n; ++i) {
    const int f = face(rng);
    const Vec3 target = i % 3 == 0   ? part.mesh.corner(f, i % 2)
                        : i % 3 == 1 ? Vec3(0.5 * (part.mesh.corner(f, 0) + part.mesh.corner(f, 2)))
                                     : Vec3((part.mesh.corner(f, 0) + part.mesh.corner(f, 1) + part.mesh.corner(f, 2)) / 3);
    const Vec3 eye(20 * u(rng), 20 * u(rng), 90);
    const RayHit h = part.index->intersect(Ray{eye, target - eye});
    if (!h || !h.front_facing) continue;
    const auto d = optics::refract((target - eye).normalized(), h.shading_normal, 1.0, 1.49);
    if (!d || d->dot(h.geometric_normal) >= 0) continue;
    out.inward.push_back(Ray{h.point, *d, 1e-9});
    out.entry_face.push_back(h.face);
  }
  return out;
}

}  // namespace

// With t_min past the rounding of the start point, naming the face the ray
// leaves as its skip face changes nothing (the refraction map relies on this
// to stay bit-identical while saving Embree's re-cast past that face).
TEST(SkipFace, LeavingRayGetsTheSameHitWithAndWithoutItOnEveryBackend) {
  test::TracePart dome(shapes::spherical_shell(25, 27.5, 40, 24, 96));
  std::printf("  seed 7031\n");
  const Leaving rays = refracted_rays(dome, 3000, 7031);
  ASSERT_GT(rays.inward.size(), 2000u);
  std::vector<Ray> skipping = rays.inward;
  for (std::size_t i = 0; i < skipping.size(); ++i) skipping[i].skip_face = rays.entry_face[i];
  for (RayBackend b : {RayBackend::embree, RayBackend::cgal_aabb, RayBackend::brute_force}) {
    const auto index = make_ray_index(dome.mesh, b);
    std::vector<RayHit> plain(skipping.size()), skipped(skipping.size());
    index->intersect(rays.inward, plain);
    index->intersect(skipping, skipped);
    int hits = 0;
    for (std::size_t i = 0; i < skipping.size(); ++i) {
      ASSERT_EQ(skipped[i].face, plain[i].face) << to_string(b) << " ray " << i;
      if (!plain[i]) continue;
      ++hits;
      EXPECT_NE(skipped[i].face, rays.entry_face[i]);
      EXPECT_EQ(skipped[i].t, plain[i].t) << to_string(b) << " ray " << i;
      EXPECT_EQ(skipped[i].point, plain[i].point) << to_string(b) << " ray " << i;
    }
    EXPECT_GT(hits, 2000) << to_string(b);
  }
}

TEST(SkipFace, SkipsTheFaceTheRayWouldHitFirst) {
  test::TracePart dome(shapes::spherical_shell(25, 27.5, 40, 24, 96));
  std::mt19937_64 rng(7032);
  std::printf("  seed 7032\n");
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Ray> rays;
  for (int i = 0; i < 500; ++i) rays.push_back(Ray{Vec3(20 * u(rng), 20 * u(rng), 90), Vec3(0.05 * u(rng), 0.05 * u(rng), -1)});
  const auto brute = make_ray_index(dome.mesh, RayBackend::brute_force);
  std::vector<RayHit> first(rays.size());
  brute->intersect(rays, first);
  for (std::size_t i = 0; i < rays.size(); ++i) rays[i].skip_face = first[i].face;
  std::vector<RayHit> expected(rays.size()), got(rays.size());
  brute->intersect(rays, expected);
  dome.index->intersect(rays, got);
  int moved = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (!first[i]) continue;
    ++moved;
    EXPECT_NE(expected[i].face, first[i].face);
    EXPECT_GT(expected[i].t, first[i].t);  // through the shell: the next face is further on
    EXPECT_EQ(got[i].face, expected[i].face) << i;
    EXPECT_EQ(got[i].t, expected[i].t) << i;
  }
  EXPECT_GT(moved, 300);
}

// Every pixel of the exact map equals the same ray traced on its own (batch of
// one), whatever tile or chunk it was cast in: bit for bit.
TEST(MapPipeline, ExactMapEqualsSingleRayTraces) {
  test::TracePart dome(shapes::spherical_shell(25, 27.5, 40, 24, 96));
  CameraModel camera;
  camera.lensmodel = "LENSMODEL_OPENCV8";
  camera.width = 120, camera.height = 90;
  const double f = 0.9 * camera.width;
  camera.intrinsics = {f, f, 59.5, 44.5, -0.04, 0.01, 2e-4, -1e-4, 0.0, 0.005, 0.0, 0.0};
  Rigid3 cam_from_part;
  cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  cam_from_part.translation = Vec3(0.7, -0.3, 90);
  const RefractionMap map = compute_refraction_map(dome.scene(), camera, cam_from_part);
  const Rigid3 part_from_cam = cam_from_part.inverse();
  const PixelUnprojector unprojector(camera);
  int valid = 0, compared = 0;
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const std::size_t p = map.index(x, y);
      if (map.status[p] == PixelStatus::outside) continue;
      // The map's own route from pixel to ray (PixelUnprojector: within 1e-9
      // rad of mrcal_unproject, tests/camera); here the trace is compared.
      Vec3 ray;
      unprojector.unproject(std::span<const Vec2>(std::array{Vec2(x, y)}), std::span<Vec3>(&ray, 1));
      ray.normalize();
      const SkinSample s = trace_skin_ray(dome.scene(), part_from_cam.translation, part_from_cam.rotation * ray);
      ++compared;
      ASSERT_EQ(map.status[p], s.status) << x << "," << y;
      if (s.status != PixelStatus::valid) continue;
      ++valid;
      EXPECT_EQ(map.skin_point[p], s.skin_point) << x << "," << y;
      EXPECT_EQ(map.face[p], s.face);
      EXPECT_EQ(map.transmittance[p], static_cast<float>(s.transmittance));
    }
  std::printf("  %d pixels compared, %d valid\n", compared, valid);
  EXPECT_GT(valid, 2000);
}
