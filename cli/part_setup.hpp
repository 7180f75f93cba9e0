#pragma once
// What every command that traces the part needs (map, simulate, assess): the
// part, its contact surface, the camera and pose, the indices and the map
// options — as command-line options, filled from a scene file where the
// command line is silent — and the loaded, ready-to-trace scene.
#include "options.hpp"
#include "scene.hpp"

#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/geometry/normals.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/refraction/map.hpp>
#include <iosfwd>
#include <memory>
#include <optional>

namespace clearfit::cli {

struct PartOptions {
  std::string mesh, camera, pose, normals = "smooth", mode = "exact", chart = "auto", cache;
  int grid_step = 32;
  double tolerance_um = 1.0;
  bool no_cache = false, exact_reasons = false;
  MeshOptions mesh_opt;
  ContactOptions contact;
  double ior = 1.49, medium_ior = 1.0, skin_ior = 1.4;
};

/// Sets `field` from a scene value when the command line did not give `option`.
template <class T, class V>
void take_from_scene(const CLI::App& sub, const char* option, T& field, const std::optional<V>& value) {
  if (value && sub.count(option) == 0) field = *value;
}

/// Registers --mesh --units --contact-* --camera --pose --ior --medium-ior
/// --skin-ior --normals --mode --grid-step --tolerance-um --chart --cache --no-cache.
void add_part_options(CLI::App& sub, PartOptions& o);
/// Fills the options the command line did not give from the scene file, and
/// checks the scene's enumerated values (InputError naming the key).
void take_scene_part_options(const SceneFile& scene, const CLI::App& sub, PartOptions& o);
/// Checks required options and value ranges (InputError naming the option).
void check_part_options(const PartOptions& o);

/// A part ready to trace. Not copyable: the ray index points into the mesh.
struct LoadedPart {
  Mesh mesh;
  ContactSurface contact;
  CameraModel camera;
  Rigid3 cam_from_part;
  std::string pose_source;  ///< where cam_from_part came from
  std::optional<Chart> chart;
  CornerNormals normals;
  std::unique_ptr<RayIndex> index;
  MapOptions map_options;
  TraceScene trace_scene() const { return {&mesh, &contact, index.get(), chart ? &*chart : nullptr}; }
  LoadedPart() = default;
  LoadedPart(const LoadedPart&) = delete;
  LoadedPart& operator=(const LoadedPart&) = delete;
};

/// Loads and repairs the mesh (repairs reported on `log`), selects the contact
/// surface, reads the camera and pose, charts the contact surface when
/// `need_chart` (InputError if it cannot be charted) or when the map mode
/// interpolates (a warning on `log` if it cannot), builds the ray index.
std::unique_ptr<LoadedPart> load_part_scene(const PartOptions& o, bool need_chart, std::ostream& log);

/// The refraction map through the cache (PartOptions::cache / no_cache);
/// InputError naming the pose when no pixel sees the contact surface.
/// `*cache_state` (optional): "hit", "miss" or "off".
RefractionMap compute_part_map(const LoadedPart& part, const PartOptions& o, std::string* cache_state = nullptr);

}  // namespace clearfit::cli
