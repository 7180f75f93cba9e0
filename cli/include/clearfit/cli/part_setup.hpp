#pragma once
// What every command that traces the part needs (map, simulate, assess): the
// part, its contact surface, the camera and pose, the indices and the map
// options (the scene's top-level keys and map section, scene.hpp) loaded into
// a ready-to-trace part, and its refraction map through the cache.
#include <clearfit/cli/options.hpp>
#include <clearfit/cli/scene.hpp>

#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose_file.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/geometry/normals.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/refraction/map.hpp>
#include <iosfwd>
#include <memory>
#include <optional>

namespace clearfit::cli {

/// The map cache: command-line only (not a scene key).
struct CacheOptions {
  std::string folder;  ///< empty: $XDG_CACHE_HOME/clearfit or ~/.cache/clearfit
  bool off = false;
};

/// The scene keys every command that traces the part shows as options:
/// --mesh --units --camera --pose --ior --medium-ior --skin-ior --contact-*
/// --normals --mode --grid-step --tolerance-um --exact-reasons --chart.
inline const std::vector<std::string> kPartKeys{"", "contact", "map"};
/// Registers --cache and --no-cache.
void add_cache_options(CLI::App& sub, CacheOptions& o);

/// A part ready to trace. Not copyable: the ray index points into the mesh.
struct LoadedPart {
  Mesh mesh;
  ContactSurface contact;
  CameraModel camera;
  Rigid3 cam_from_part;
  std::string pose_source;    ///< where cam_from_part came from
  std::optional<PoseCovariance> pose_covariance;  ///< from the pose file, when it carries one
  std::string camera_source;  ///< the camera model's file
  std::optional<ProjectionUncertainty> projection_uncertainty;  ///< from the camera model, when it carries one
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
/// InputError when the mesh or the camera is not given.
std::unique_ptr<LoadedPart> load_part_scene(const Scene& scene, bool need_chart, std::ostream& log);

/// The refraction map through the cache;
/// InputError naming the pose when no pixel sees the contact surface.
/// `*cache_state` (optional): "hit", "miss" or "off".
RefractionMap compute_part_map(const LoadedPart& part, const CacheOptions& cache, std::string* cache_state = nullptr);

}  // namespace clearfit::cli
