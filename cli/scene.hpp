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
//   map: {normals: smooth, mode: adaptive, grid_step: 16, tolerance_um: 1.0, chart: auto, exact_reasons: false}
//   outputs: {map: out/map.npy, stats: out/map-stats.json, inverse: out/inverse.npy, texel_mm: 0.05,
//             folder: out}
//   captures / calibration / assess / simulation: sections read by the commands that use
//   them (assess, simulate), with SceneReader for located errors.
#include <clearfit/error.hpp>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <set>
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
  std::optional<bool> exact_reasons;
  std::optional<std::string> out_map, out_stats, out_inverse;
  std::optional<double> texel_mm;
  std::optional<std::string> out_folder;
  YAML::Node root;  ///< the whole file, for the sections other commands read
};

/// Reads keys of one scene file with errors that name the file, line and key.
class SceneReader {
 public:
  explicit SceneReader(std::filesystem::path file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key, const std::string& problem) const {
    const std::string where = (node.Mark().line >= 0 ? "line " + std::to_string(node.Mark().line + 1) + ", " : "") + "key '" + key + "'";
    throw InputError(file_.string(), where, problem, "see the scene file format in README.md");
  }
  void only_keys(const YAML::Node& map, const std::string& prefix, const std::set<std::string>& allowed) const {
    if (!map.IsMap()) fail(map, prefix, "expected a mapping of keys to values");
    for (const auto& kv : map) {
      const auto key = kv.first.as<std::string>();
      if (!allowed.count(key)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(kv.first, prefix.empty() ? key : prefix + "." + key, "unknown key (expected one of: " + list + ")");
      }
    }
  }
  template <class T>
  std::optional<T> get(const YAML::Node& map, const std::string& key, const std::string& full, const char* what) const {
    const YAML::Node n = map[key];
    if (!n) return std::nullopt;
    if (!n.IsScalar()) fail(n, full, std::string("expected ") + what);
    try {
      return n.as<T>();
    } catch (const YAML::Exception&) {
      fail(n, full, std::string("expected ") + what + ", got '" + n.Scalar() + "'");
    }
  }
  std::optional<std::string> path(const YAML::Node& map, const std::string& key, const std::string& full) const {
    auto s = get<std::string>(map, key, full, "a file path");
    if (!s) return s;
    std::filesystem::path p(*s);
    return (p.is_absolute() ? p : file_.parent_path() / p).lexically_normal().string();
  }

 const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
};




/// Reads and checks a scene file; paths come back resolved against its folder.
/// Throws InputError (file, "line N, key 'k'", what was expected).
SceneFile read_scene(const std::filesystem::path& path);

}  // namespace clearfit::cli
