#pragma once
// The small part the CLI tests film: a 24 × 18 × 3 mm slab (slab.obj) seen by a 160 × 120
// pinhole camera 60 mm away looking down its normal (cam.cameramodel), written into `dir`.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <filesystem>

namespace clearfit::cli_test {

inline void write_slab_part(const std::filesystem::path& dir) {
  save_mesh(shapes::slab(24, 18, 3, 2), dir / "slab.obj");
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_PINHOLE";
  cam.intrinsics = {300, 300, 79.5, 59.5};
  cam.width = 160, cam.height = 120;
  cam.cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  cam.cam_from_part.translation = Vec3(0, 0, 60);
  write_cameramodel(cam, dir / "cam.cameramodel");
}

}  // namespace clearfit::cli_test
