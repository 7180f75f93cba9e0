#pragma once
// The scene file (YAML): everything a run needs, named once. Paths in it are
// relative to the file. Every key can also be given on the command line, which
// wins. Unknown keys and wrong types are errors naming the key and the line.
//
//   mesh: wristband.obj          # part mesh
//   units: mm                    # of the mesh file's numbers (STL/OBJ/PLY/OFF)
//   ior: 1.49                    # part
//   medium_ior: 1.0              # camera side
//   skin_ior: 1.4
//   contact: {group: contact}    # or {faces: faces.txt} or {normal: [0, 0, -1], angle_deg: 30}
//   camera: camera.cameramodel
//   pose: pose.json              # optional; default: the cameramodel's extrinsics
//   map: {normals: smooth, mode: adaptive, grid_step: 16, tolerance_um: 1.0, chart: auto}
//   outputs: {map: out/map.npy, stats: out/map-stats.json, inverse: out/inverse.npy, texel_mm: 0.05}
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace clearfit::cli {

struct SceneFile {
  std::filesystem::path path;
  std::optional<std::string> mesh, units, camera, pose;
  std::optional<double> ior, medium_ior, skin_ior;
  std::optional<std::string> contact_group, contact_faces;
  std::optional<std::vector<double>> contact_normal;
  std::optional<double> contact_angle_deg;
  std::optional<std::string> normals, mode, chart;
  std::optional<int> grid_step;
  std::optional<double> tolerance_um;
  std::optional<std::string> out_map, out_stats, out_inverse;
  std::optional<double> texel_mm;
};

/// Reads and checks a scene file; paths come back resolved against its folder.
/// Throws InputError (file, "line N, key 'k'", what was expected).
SceneFile read_scene(const std::filesystem::path& path);

}  // namespace clearfit::cli
