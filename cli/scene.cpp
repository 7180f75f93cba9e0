#include "scene.hpp"

#include <clearfit/error.hpp>
#include <yaml-cpp/yaml.h>

#include <set>

namespace clearfit::cli {

SceneFile read_scene(const std::filesystem::path& file) {
  if (std::filesystem::is_directory(file)) throw InputError(file.string(), "", "is a directory, expected a scene file (YAML)");
  if (!std::filesystem::exists(file)) throw InputError(file.string(), "", "scene file not found");
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::ParserException& e) {
    throw InputError(file.string(), "line " + std::to_string(e.mark.line + 1) + ", column " + std::to_string(e.mark.column + 1),
                     "not valid YAML: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), "", std::string("cannot read the scene file: ") + e.what());
  }
  SceneReader r(file);
  SceneFile s;
  s.path = file;
  if (!root || root.IsNull()) throw InputError(file.string(), "", "is empty", "see the scene file format in README.md");
  r.only_keys(root, "", {"mesh", "units", "ior", "medium_ior", "skin_ior", "contact", "camera", "pose", "map", "outputs",
                    "captures", "calibration", "assess", "simulation"});
  s.root = root;
  s.mesh = r.path(root, "mesh", "mesh");
  s.units = r.get<std::string>(root, "units", "units", "a unit (um, mm, cm, m, in, ft)");
  s.camera = r.path(root, "camera", "camera");
  s.pose = r.path(root, "pose", "pose");
  s.ior = r.get<double>(root, "ior", "ior", "a number");
  s.medium_ior = r.get<double>(root, "medium_ior", "medium_ior", "a number");
  s.skin_ior = r.get<double>(root, "skin_ior", "skin_ior", "a number");
  if (const YAML::Node c = root["contact"]) {
    r.only_keys(c, "contact", {"group", "faces", "normal", "angle_deg"});
    s.contact_group = r.get<std::string>(c, "group", "contact.group", "a group name");
    s.contact_faces = r.path(c, "faces", "contact.faces");
    s.contact_angle_deg = r.get<double>(c, "angle_deg", "contact.angle_deg", "a number of degrees");
    if (const YAML::Node n = c["normal"]) {
      if (!n.IsSequence() || n.size() != 3) r.fail(n, "contact.normal", "expected three numbers [x, y, z]");
      std::vector<double> v;
      for (const auto& e : n) {
        try {
          v.push_back(e.as<double>());
        } catch (const YAML::Exception&) {
          r.fail(e, "contact.normal", "expected a number, got '" + e.Scalar() + "'");
        }
      }
      s.contact_normal = v;
    }
  }
  if (const YAML::Node m = root["map"]) {
    r.only_keys(m, "map", {"normals", "mode", "grid_step", "tolerance_um", "chart", "exact_reasons"});
    s.normals = r.get<std::string>(m, "normals", "map.normals", "smooth or flat");
    s.mode = r.get<std::string>(m, "mode", "map.mode", "exact, grid or adaptive");
    s.chart = r.get<std::string>(m, "chart", "map.chart", "auto, planar, lscm, arap or none");
    s.grid_step = r.get<int>(m, "grid_step", "map.grid_step", "a whole number of pixels");
    s.tolerance_um = r.get<double>(m, "tolerance_um", "map.tolerance_um", "a number of micrometres");
    s.exact_reasons = r.get<bool>(m, "exact_reasons", "map.exact_reasons", "true or false");
  }
  if (const YAML::Node o = root["outputs"]) {
    r.only_keys(o, "outputs", {"map", "stats", "inverse", "texel_mm", "folder"});
    s.out_folder = r.path(o, "folder", "outputs.folder");
    s.out_inverse = r.path(o, "inverse", "outputs.inverse");
    s.texel_mm = r.get<double>(o, "texel_mm", "outputs.texel_mm", "a length in mm");
    s.out_map = r.path(o, "map", "outputs.map");
    s.out_stats = r.path(o, "stats", "outputs.stats");
  }
  return s;
}

}  // namespace clearfit::cli
