#include "part_setup.hpp"

#include <clearfit/error.hpp>
#include <clearfit/geometry/validate.hpp>
#include <clearfit/refraction/map_cache.hpp>
#include <cmath>
#include <cstdlib>
#include <ostream>
#include <sstream>

namespace clearfit::cli {
namespace {

void check_index(const char* option, double value) {
  if (!(std::isfinite(value) && value >= 1.0))
    throw InputError("", option, "must be a finite index of refraction >= 1, got " + (std::ostringstream() << value).str(),
                     "air 1.0, water 1.333, acrylic 1.49, clear resins 1.49-1.55");
}

std::filesystem::path default_cache_dir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return std::filesystem::path(xdg) / "clearfit";
  if (const char* home = std::getenv("HOME"); home && *home) return std::filesystem::path(home) / ".cache" / "clearfit";
  return {};
}

}  // namespace

void add_part_options(CLI::App& sub, PartOptions& o) {
  sub.add_option("--mesh", o.mesh, "Part mesh (.stl .obj .ply .off .3mf .gltf .glb)");
  sub.add_option("--camera", o.camera, "Camera model (mrcal .cameramodel)");
  sub.add_option("--pose", o.pose, "Pose file (clearfit.pose/1 JSON) with cam_from_part; default: the cameramodel's extrinsics");
  sub.add_option("--ior", o.ior, "Index of refraction of the part")->capture_default_str();
  sub.add_option("--medium-ior", o.medium_ior, "Index of the camera-side medium (air 1.0, water 1.333, oil ~1.5)")->capture_default_str();
  sub.add_option("--skin-ior", o.skin_ior, "Index beyond the contact surface (skin)")->capture_default_str();
  add_mesh_options(sub, o.mesh_opt);
  add_contact_options(sub, o.contact);
  sub.add_option("--normals", o.normals, "Shading normals at the surfaces")->check(CLI::IsMember({"smooth", "flat"}))->capture_default_str();
  sub.add_option("--mode", o.mode, "exact: every pixel traced; grid: cells of --grid-step px interpolated; adaptive: cells refined until within --tolerance-um")
      ->check(CLI::IsMember({"exact", "grid", "adaptive"}))->capture_default_str();
  sub.add_option("--grid-step", o.grid_step, "Starting cell size for grid/adaptive, pixels (power of two, 2..256)")->capture_default_str();
  sub.add_option("--tolerance-um", o.tolerance_um, "Adaptive: accepted interpolation error on the skin, micrometres")->capture_default_str();
  sub.add_flag("--exact-reasons", o.exact_reasons,
               "Grid/adaptive: resolve boundaries between two invalid reasons pixel by pixel too (default: validity "
               "boundaries only; elsewhere a pixel takes its nearest traced node's reason)");
  sub.add_option("--chart", o.chart, "Chart of the contact surface used for interpolation (none: interpolate in 3D)")
      ->check(CLI::IsMember({"auto", "planar", "lscm", "arap", "none"}))->capture_default_str();
  sub.add_option("--cache", o.cache, "Cache folder for maps (default: $XDG_CACHE_HOME/clearfit or ~/.cache/clearfit)");
  sub.add_flag("--no-cache", o.no_cache, "Neither read nor write the map cache");
}

void take_scene_part_options(const SceneFile& sc, const CLI::App& sub, PartOptions& o) {
  auto take = [&](const char* option, auto& field, const auto& value) { take_from_scene(sub, option, field, value); };
  take("--mesh", o.mesh, sc.mesh);
  take("--units", o.mesh_opt.units, sc.units);
  take("--camera", o.camera, sc.camera);
  take("--pose", o.pose, sc.pose);
  take("--ior", o.ior, sc.ior);
  take("--medium-ior", o.medium_ior, sc.medium_ior);
  take("--skin-ior", o.skin_ior, sc.skin_ior);
  const bool cli_contact = sub.count("--contact-group") + sub.count("--contact-faces") + sub.count("--contact-normal") > 0;
  if (!cli_contact) {
    if (sc.contact_group) o.contact.group = *sc.contact_group;
    if (sc.contact_faces) o.contact.faces_file = *sc.contact_faces;
    if (sc.contact_normal) o.contact.normal = *sc.contact_normal;
  }
  take("--contact-angle", o.contact.angle_deg, sc.contact_angle_deg);
  take("--normals", o.normals, sc.normals);
  take("--mode", o.mode, sc.mode);
  take("--chart", o.chart, sc.chart);
  take("--grid-step", o.grid_step, sc.grid_step);
  take("--tolerance-um", o.tolerance_um, sc.tolerance_um);
  take("--exact-reasons", o.exact_reasons, sc.exact_reasons);
  auto member = [&](const std::string& key, const std::string& v, std::initializer_list<const char*> ok) {
    for (const char* k : ok)
      if (v == k) return;
    throw InputError(sc.path.string(), "key '" + key + "'", "'" + v + "' is not one of the allowed values");
  };
  member("map.normals", o.normals, {"smooth", "flat"});
  member("map.mode", o.mode, {"exact", "grid", "adaptive"});
  member("map.chart", o.chart, {"auto", "planar", "lscm", "arap", "none"});
}

void check_part_options(const PartOptions& o) {
  for (auto [value, option, key] : {std::tuple{&o.mesh, "--mesh", "mesh"}, {&o.camera, "--camera", "camera"}})
    if (value->empty())
      throw InputError("", std::string(option), "is required", std::string("give it on the command line or as '") + key + "' in a --scene file");
  check_index("--ior", o.ior);
  check_index("--medium-ior", o.medium_ior);
  check_index("--skin-ior", o.skin_ior);
  if (o.grid_step < 2 || o.grid_step > 256 || (o.grid_step & (o.grid_step - 1)) != 0)
    throw InputError("", "--grid-step " + std::to_string(o.grid_step), "must be a power of two from 2 to 256");
  if (!(std::isfinite(o.tolerance_um) && o.tolerance_um > 0))
    throw InputError("", "--tolerance-um", "must be a positive number of micrometres");
}

std::unique_ptr<LoadedPart> load_part_scene(const PartOptions& o, bool need_chart, std::ostream& log) {
  check_part_options(o);
  auto part = std::make_unique<LoadedPart>();
  part->mesh = load_part(o.mesh, o.mesh_opt);
  for (const std::string& change : repair_mesh(part->mesh)) log << "clearfit: warning: " << o.mesh << ": " << change << "\n";
  auto selector = make_contact_selector(o.contact);
  if (!selector)
    throw InputError(o.mesh, "contact surface", "not given",
                     "name it with --contact-group, --contact-faces or --contact-normal/--contact-angle");
  part->contact = select_contact(part->mesh, *selector);
  part->camera = read_cameramodel(o.camera);
  part->cam_from_part = o.pose.empty() ? part->camera.cam_from_part : read_pose_json(o.pose);
  part->pose_source = o.pose.empty() ? o.camera + " (extrinsics)" : o.pose;

  MapOptions& opt = part->map_options;
  opt.indices.n_part = o.ior;
  opt.indices.n_medium = o.medium_ior;
  opt.indices.n_skin = o.skin_ior;
  opt.normals = o.normals == "flat" ? MapOptions::Normals::flat : MapOptions::Normals::smooth;
  opt.mode = o.mode == "grid" ? MapOptions::Mode::grid : o.mode == "adaptive" ? MapOptions::Mode::adaptive : MapOptions::Mode::exact;
  opt.grid_step = o.grid_step;
  opt.tolerance_um = o.tolerance_um;
  opt.exact_reasons = o.exact_reasons;
  if (need_chart && o.chart == "none")
    throw InputError("", "--chart none", "this command needs a chart of the contact surface", "drop --chart none");
  if (o.chart != "none" && (opt.mode != MapOptions::Mode::exact || need_chart)) {
    ChartOptions copt;
    copt.method = parse_chart_method(o.chart);
    try {
      part->chart = compute_chart(part->mesh, part->contact, copt);
    } catch (const InputError& e) {
      if (need_chart)
        throw InputError(o.mesh, "contact surface", std::string("cannot be charted: ") + e.what(),
                         "the contact surface must be a topological disk per component");
      if (o.chart != "auto") throw;
      log << "clearfit: warning: no chart of the contact surface (" << e.what()
          << "); interpolating in 3D, which needs smaller cells on curved parts\n";
    }
  }
  part->normals = compute_corner_normals(part->mesh, NormalOptions{});
  part->index = make_ray_index(part->mesh, RayBackend::embree, &part->normals);
  return part;
}

RefractionMap compute_part_map(const LoadedPart& part, const PartOptions& o, std::string* cache_state) {
  const std::filesystem::path cache_dir =
      o.no_cache ? std::filesystem::path() : o.cache.empty() ? default_cache_dir() : std::filesystem::path(o.cache);
  bool hit = false;
  RefractionMap map;
  try {
    map = compute_refraction_map_cached(part.trace_scene(), part.camera, part.cam_from_part, part.map_options,
                                        cache_dir, &hit);
  } catch (const InputError& e) {
    if (e.element().rfind("pose", 0) != 0) throw;
    throw InputError(part.pose_source, "cam_from_part", e.what());
  }
  if (map.stats.by_status[0] == 0)
    throw InputError(part.pose_source, "cam_from_part",
                     "no pixel of " + o.camera + " sees the contact surface through the part",
                     "check the pose, the camera model and the contact surface");
  if (cache_state) *cache_state = cache_dir.empty() ? "off" : hit ? "hit" : "miss";
  return map;
}

}  // namespace clearfit::cli
