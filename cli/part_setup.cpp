#include <clearfit/cli/part_setup.hpp>

#include <clearfit/error.hpp>
#include <clearfit/geometry/validate.hpp>
#include <clearfit/refraction/map_cache.hpp>
#include <cmath>
#include <cstdlib>
#include <ostream>
#include <sstream>

namespace clearfit::cli {
namespace {

std::filesystem::path default_cache_dir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return std::filesystem::path(xdg) / "clearfit";
  if (const char* home = std::getenv("HOME"); home && *home) return std::filesystem::path(home) / ".cache" / "clearfit";
  return {};
}

}  // namespace

void add_cache_options(CLI::App& sub, CacheOptions& o) {
  sub.add_option("--cache", o.folder, "Cache folder for maps (default: $XDG_CACHE_HOME/clearfit or ~/.cache/clearfit)");
  sub.add_flag("--no-cache", o.off, "Neither read nor write the map cache");
}

std::unique_ptr<LoadedPart> load_part_scene(const Scene& scene, bool need_chart, std::ostream& log) {
  const PartSection& o = scene.part;
  for (auto [value, option, key] : {std::tuple{&o.mesh, "--mesh", "mesh"}, {&o.camera, "--camera", "camera"}})
    if (value->empty())
      throw InputError("", std::string(option), "is required", std::string("give it on the command line or as '") + key + "' in a --scene file");
  auto part = std::make_unique<LoadedPart>();
  part->mesh = load_part(o.mesh, o.units);
  for (const std::string& change : repair_mesh(part->mesh)) log << "clearfit: warning: " << o.mesh << ": " << change << "\n";
  auto selector = make_contact_selector(o.contact);
  if (!selector)
    throw InputError(o.mesh, "contact surface", "not given",
                     "name it with --contact-group, --contact-faces or --contact-normal/--contact-angle");
  part->contact = select_contact(part->mesh, *selector);
  part->camera = read_cameramodel(o.camera);
  part->camera_source = o.camera;
  part->projection_uncertainty = read_projection_uncertainty(o.camera);
  if (o.pose.empty()) {
    part->cam_from_part = part->camera.cam_from_part;
  } else {
    PoseFile pose = read_pose_file(o.pose);
    part->cam_from_part = pose.cam_from_part;
    part->pose_covariance = pose.covariance;
  }
  part->pose_source = o.pose.empty() ? o.camera + " (extrinsics)" : o.pose;
  part->map_options = scene.map_options();
  const std::string& chart = scene.map.chart;
  if (need_chart && chart == "none")
    throw InputError("", "--chart none", "this command needs a chart of the contact surface", "drop --chart none");
  if (chart != "none" && (part->map_options.mode != MapOptions::Mode::exact || need_chart)) {
    ChartOptions copt;
    copt.method = parse_chart_method(chart);
    try {
      part->chart = compute_chart(part->mesh, part->contact, copt);
    } catch (const InputError& e) {
      if (need_chart)
        throw InputError(o.mesh, "contact surface", std::string("cannot be charted: ") + e.what(),
                         "the contact surface must be a topological disk per component");
      if (chart != "auto") throw;
      log << "clearfit: warning: no chart of the contact surface (" << e.what()
          << "); interpolating in 3D, which needs smaller cells on curved parts\n";
    }
  }
  part->normals = compute_corner_normals(part->mesh, NormalOptions{});
  part->index = make_ray_index(part->mesh, RayBackend::embree, &part->normals);
  return part;
}

RefractionMap compute_part_map(const LoadedPart& part, const CacheOptions& cache, std::string* cache_state) {
  const std::filesystem::path cache_dir =
      cache.off ? std::filesystem::path() : cache.folder.empty() ? default_cache_dir() : std::filesystem::path(cache.folder);
  bool hit = false;
  RefractionMap map;
  try {
    map = compute_refraction_map_cached(part.trace_scene(), part.camera, part.cam_from_part, part.map_options,
                                        cache_dir, &hit);
  } catch (const PoseError& e) {
    throw InputError(part.pose_source, "cam_from_part", e.what());
  }
  if (map.stats.by_status[0] == 0)
    throw InputError(part.pose_source, "cam_from_part",
                     "no pixel of " + part.camera_source + " sees the contact surface through the part",
                     "check the pose, the camera model and the contact surface");
  if (cache_state) *cache_state = cache_dir.empty() ? "off" : hit ? "hit" : "miss";
  return map;
}

}  // namespace clearfit::cli
