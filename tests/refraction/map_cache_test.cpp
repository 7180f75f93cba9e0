// The on-disk map cache: identical inputs hit, any changed input misses, a
// damaged entry is ignored.
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map_cache.hpp>
#include <gtest/gtest.h>

#include <fstream>

using namespace clearfit;

TEST(MapCache, HitsOnlyWhenNothingChanged) {
  Mesh mesh = shapes::cylindrical_shell(30, 32.5, 100, 20, 48, 4);
  ContactSelector sel;
  sel.group = "contact";
  const ContactSurface contact = select_contact(mesh, sel);
  const auto index = make_ray_index(mesh);
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_PINHOLE";
  cam.intrinsics = {60, 60, 31.5, 23.5};
  cam.width = 64;
  cam.height = 48;
  Rigid3 pose;
  pose.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  pose.translation = Vec3(0, 0, 110);
  const TraceScene scene{&mesh, &contact, index.get(), nullptr};
  const auto dir = std::filesystem::temp_directory_path() / "clearfit_map_cache_test";
  std::filesystem::remove_all(dir);

  bool hit = true;
  MapOptions opt;
  const RefractionMap first = compute_refraction_map_cached(scene, cam, pose, opt, dir, &hit);
  EXPECT_FALSE(hit);
  const RefractionMap again = compute_refraction_map_cached(scene, cam, pose, opt, dir, &hit);
  EXPECT_TRUE(hit);
  ASSERT_EQ(again.status.size(), first.status.size());
  for (std::size_t i = 0; i < first.status.size(); ++i) {
    EXPECT_EQ(again.status[i], first.status[i]);
    if (first.status[i] == PixelStatus::valid) EXPECT_EQ(again.skin_point[i], first.skin_point[i]);
  }
  EXPECT_EQ(again.stats.by_status[0], first.stats.by_status[0]);
  EXPECT_EQ(again.stats.mode, "exact");

  const std::uint64_t key = map_inputs_hash(scene, cam, pose, opt);
  MapOptions other = opt;
  other.indices.n_part = 1.5;
  EXPECT_NE(map_inputs_hash(scene, cam, pose, other), key);
  Rigid3 moved = pose;
  moved.translation.z() += 1e-9;
  EXPECT_NE(map_inputs_hash(scene, cam, moved, opt), key);
  CameraModel cam2 = cam;
  cam2.intrinsics[0] += 1e-9;
  EXPECT_NE(map_inputs_hash(scene, cam2, pose, opt), key);
  Mesh mesh2 = mesh;
  mesh2.vertices[5].x() += 1e-9;
  const auto index2 = make_ray_index(mesh2);
  EXPECT_NE(map_inputs_hash({&mesh2, &contact, index2.get(), nullptr}, cam, pose, opt), key);

  // A damaged entry is recomputed, not trusted.
  for (const auto& e : std::filesystem::directory_iterator(dir)) std::filesystem::resize_file(e.path(), 40);
  compute_refraction_map_cached(scene, cam, pose, opt, dir, &hit);
  EXPECT_FALSE(hit);
  std::filesystem::remove_all(dir);
}
