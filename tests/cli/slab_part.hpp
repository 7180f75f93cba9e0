#pragma once
// The small part the CLI tests film: a 24 × 18 × 3 mm slab (slab.obj) seen by a 160 × 120
// pinhole camera 60 mm away looking down its normal (cam.cameramodel), written into `dir`.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <filesystem>
#include <string>

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

/// A scene of that part (scene.yaml) with captures in sim/, outputs in out/ and a small simulation of one
/// pressed place; `captures`, `outputs` and `simulation` add keys to those sections.
inline std::string slab_scene(const std::string& captures = "", const std::string& outputs = "", const std::string& simulation = "") {
  return "mesh: slab.obj\nior: 1.49\ncontact: {group: contact}\ncamera: cam.cameramodel\n"
         "captures: {baseline: sim/baseline, worn: sim/worn, window_frames: 3" + captures + "}\n"
         "outputs: {folder: out, texel_mm: 0.2" + outputs + "}\n"
         "simulation:\n  format: png\n  timeline: {fps: 10, baseline_s: 0.5, press_s: 0.4}\n"
         "  pressure:\n    texel_mm: 0.2\n    sources:\n      - {name: a, type: gaussian, center_uv_mm: [12, 9], peak_kpa: 15, sigma_mm: 2}\n"
         "  presses: {diameters_mm: [2], levels: 6, repetitions: 2}\n" + simulation;
}

}  // namespace clearfit::cli_test
