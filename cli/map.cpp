// clearfit map: the refraction map of a part seen by a camera (pixel -> skin point).
#include "commands.hpp"
#include "options.hpp"
#include "scene.hpp"

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <clearfit/refraction/map_cache.hpp>
#include <cstdlib>
#include <sstream>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

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

nlohmann::json stats_json(const RefractionMap& map, const std::string& mesh, const std::string& camera,
                          const MapOptions& opt, const std::string& cache) {
  const MapStats& s = map.stats;
  nlohmann::json by_status;
  for (int k = 0; k < kPixelStatusCount; ++k) by_status[to_string(static_cast<PixelStatus>(k))] = s.by_status[k];
  return {{"schema", "clearfit.map-stats/1"},
          {"mesh", mesh},
          {"camera", camera},
          {"image", {{"width", map.width}, {"height", map.height}}},
          {"indices", {{"medium", opt.indices.n_medium}, {"part", opt.indices.n_part}, {"skin", opt.indices.n_skin}}},
          {"normals", opt.normals == MapOptions::Normals::smooth ? "smooth" : "flat"},
          {"mode", s.mode},
          {"grid_step", opt.mode == MapOptions::Mode::exact ? nlohmann::json(nullptr) : nlohmann::json(opt.grid_step)},
          {"tolerance_um", opt.mode == MapOptions::Mode::adaptive ? nlohmann::json(opt.tolerance_um) : nlohmann::json(nullptr)},
          {"interpolated", s.interpolated},
          {"cache", cache},
          {"fast_path", s.fast_path},
          {"pixels", s.pixels},
          {"traced", s.traced},
          {"coverage", s.coverage},
          {"by_status", by_status},
          {"estimated_max_error_um", s.max_error_um},
          {"timings_ms", {{"unproject", s.unproject_ms}, {"cull", s.cull_ms}, {"trace", s.trace_ms}, {"total", s.total_ms}}}};
}
}  // namespace

Run add_map(CLI::App& app) {
  struct Opts {
    std::string scene, mesh, camera, pose, out, stats, inverse, normals = "smooth", mode = "exact", chart = "auto", cache;
    int grid_step = 32;
    double tolerance_um = 1.0, texel_mm = 0.05;
    bool no_cache = false;
    MeshOptions mesh_opt;
    ContactOptions contact;
    double ior = 1.49, medium_ior = 1.0, skin_ior = 1.4;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand("map", "Refraction map: for every camera pixel, the skin point it sees through the part");
  sub->add_option("--scene", o->scene, "Scene file (YAML) giving any of the options below; the command line wins");
  sub->add_option("--mesh", o->mesh, "Part mesh (.stl .obj .ply .off .3mf .gltf .glb)");
  sub->add_option("--camera", o->camera, "Camera model (mrcal .cameramodel)");
  sub->add_option("--pose", o->pose, "Pose file (clearfit.pose/1 JSON) with cam_from_part; default: the cameramodel's extrinsics");
  sub->add_option("--ior", o->ior, "Index of refraction of the part")->capture_default_str();
  sub->add_option("--medium-ior", o->medium_ior, "Index of the camera-side medium (air 1.0, water 1.333, oil ~1.5)")->capture_default_str();
  sub->add_option("--skin-ior", o->skin_ior, "Index beyond the contact surface (skin)")->capture_default_str();
  add_mesh_options(*sub, o->mesh_opt);
  add_contact_options(*sub, o->contact);
  sub->add_option("--normals", o->normals, "Shading normals at the surfaces")->check(CLI::IsMember({"smooth", "flat"}))->capture_default_str();
  sub->add_option("--mode", o->mode, "exact: every pixel traced; grid: cells of --grid-step px interpolated; adaptive: cells refined until within --tolerance-um")
      ->check(CLI::IsMember({"exact", "grid", "adaptive"}))->capture_default_str();
  sub->add_option("--grid-step", o->grid_step, "Starting cell size for grid/adaptive, pixels (power of two, 2..256)")->capture_default_str();
  sub->add_option("--tolerance-um", o->tolerance_um, "Adaptive: accepted interpolation error on the skin, micrometres")->capture_default_str();
  sub->add_option("--chart", o->chart, "Chart of the contact surface used for interpolation (none: interpolate in 3D)")
      ->check(CLI::IsMember({"auto", "planar", "lscm", "arap", "none"}))->capture_default_str();
  sub->add_option("--cache", o->cache, "Cache folder for maps (default: $XDG_CACHE_HOME/clearfit or ~/.cache/clearfit)");
  sub->add_flag("--no-cache", o->no_cache, "Neither read nor write the map cache");
  sub->add_option("--out", o->out, "Output MAP.npy: float32 H x W x 3 skin points (part frame, mm), NaN where invalid");
  sub->add_option("--stats", o->stats, "Output STATS.json: coverage, invalid pixels by reason, fast path, timings");
  sub->add_option("--inverse", o->inverse, "Output INV.npy: the inverse map for cv::remap, float32 T_h x T_w x 2 camera pixels per chart texel, NaN where invalid");
  sub->add_option("--texel-mm", o->texel_mm, "Texel size of the inverse map on the chart, mm")->capture_default_str();

  return [o, sub]() {
    if (!o->scene.empty()) {
      // Scene values fill what the command line did not give.
      const SceneFile sc = read_scene(o->scene);
      auto take = [&](const char* option, auto& field, const auto& value) {
        if (value && sub->count(option) == 0) field = *value;
      };
      take("--mesh", o->mesh, sc.mesh);
      take("--units", o->mesh_opt.units, sc.units);
      take("--camera", o->camera, sc.camera);
      take("--pose", o->pose, sc.pose);
      take("--ior", o->ior, sc.ior);
      take("--medium-ior", o->medium_ior, sc.medium_ior);
      take("--skin-ior", o->skin_ior, sc.skin_ior);
      const bool cli_contact = sub->count("--contact-group") + sub->count("--contact-faces") + sub->count("--contact-normal") > 0;
      if (!cli_contact) {
        if (sc.contact_group) o->contact.group = *sc.contact_group;
        if (sc.contact_faces) o->contact.faces_file = *sc.contact_faces;
        if (sc.contact_normal) o->contact.normal = *sc.contact_normal;
      }
      take("--contact-angle", o->contact.angle_deg, sc.contact_angle_deg);
      take("--normals", o->normals, sc.normals);
      take("--mode", o->mode, sc.mode);
      take("--chart", o->chart, sc.chart);
      take("--grid-step", o->grid_step, sc.grid_step);
      take("--tolerance-um", o->tolerance_um, sc.tolerance_um);
      take("--out", o->out, sc.out_map);
      take("--stats", o->stats, sc.out_stats);
      take("--inverse", o->inverse, sc.out_inverse);
      take("--texel-mm", o->texel_mm, sc.texel_mm);
      // The scene's output folders are created (nothing is written into them yet).
      for (const auto& out : {sc.out_map, sc.out_stats, sc.out_inverse})
        if (out && !std::filesystem::path(*out).parent_path().empty())
          std::filesystem::create_directories(std::filesystem::path(*out).parent_path());
      auto member = [&](const std::string& key, const std::string& v, std::initializer_list<const char*> ok) {
        for (const char* k : ok)
          if (v == k) return;
        throw InputError(o->scene, "key '" + key + "'", "'" + v + "' is not one of the allowed values");
      };
      member("map.normals", o->normals, {"smooth", "flat"});
      member("map.mode", o->mode, {"exact", "grid", "adaptive"});
      member("map.chart", o->chart, {"auto", "planar", "lscm", "arap", "none"});
    }
    for (auto [value, option, key] : {std::tuple{&o->mesh, "--mesh", "mesh"}, {&o->camera, "--camera", "camera"},
                                      {&o->out, "--out", "outputs.map"}})
      if (value->empty())
        throw InputError("", std::string(option), "is required", std::string("give it on the command line or as '") + key + "' in a --scene file");
    check_index("--ior", o->ior);
    check_index("--medium-ior", o->medium_ior);
    check_index("--skin-ior", o->skin_ior);
    Mesh mesh = load_part(o->mesh, o->mesh_opt);
    for (const std::string& change : repair_mesh(mesh)) std::cerr << "clearfit: warning: " << o->mesh << ": " << change << "\n";
    auto selector = make_contact_selector(o->contact);
    if (!selector)
      throw InputError(o->mesh, "contact surface", "not given",
                       "name it with --contact-group, --contact-faces or --contact-normal/--contact-angle");
    const ContactSurface contact = select_contact(mesh, *selector);
    const CameraModel camera = read_cameramodel(o->camera);
    const Rigid3 cam_from_part = o->pose.empty() ? camera.cam_from_part : read_pose_json(o->pose);

    MapOptions opt;
    opt.indices.n_part = o->ior;
    opt.indices.n_medium = o->medium_ior;
    opt.indices.n_skin = o->skin_ior;
    opt.normals = o->normals == "flat" ? MapOptions::Normals::flat : MapOptions::Normals::smooth;
    opt.mode = o->mode == "grid" ? MapOptions::Mode::grid : o->mode == "adaptive" ? MapOptions::Mode::adaptive : MapOptions::Mode::exact;
    opt.grid_step = o->grid_step;
    opt.tolerance_um = o->tolerance_um;
    if (opt.grid_step < 2 || opt.grid_step > 256 || (opt.grid_step & (opt.grid_step - 1)) != 0)
      throw InputError("", "--grid-step " + std::to_string(o->grid_step), "must be a power of two from 2 to 256");
    if (!(std::isfinite(opt.tolerance_um) && opt.tolerance_um > 0))
      throw InputError("", "--tolerance-um", "must be a positive number of micrometres");
    std::optional<Chart> chart;
    if (!o->inverse.empty() && o->chart == "none")
      throw InputError("", "--inverse", "needs a chart of the contact surface", "drop --chart none");
    if (!(std::isfinite(o->texel_mm) && o->texel_mm > 0))
      throw InputError("", "--texel-mm", "must be a positive length in mm");
    if (o->chart != "none" && (opt.mode != MapOptions::Mode::exact || !o->inverse.empty())) {
      ChartOptions copt;
      copt.method = parse_chart_method(o->chart);
      try {
        chart = compute_chart(mesh, contact, copt);
      } catch (const InputError& e) {
        if (o->chart != "auto") throw;
        std::cerr << "clearfit: warning: no chart of the contact surface (" << e.what()
                  << "); interpolating in 3D, which needs smaller cells on curved parts\n";
      }
    }
    NormalOptions nopt;
    const CornerNormals normals = compute_corner_normals(mesh, nopt);
    const auto index = make_ray_index(mesh, RayBackend::embree, &normals);
    const std::filesystem::path cache_dir = o->no_cache ? std::filesystem::path() : o->cache.empty() ? default_cache_dir() : std::filesystem::path(o->cache);
    bool hit = false;
    // Output folders are checked before the work, so a bad path fails fast and leaves nothing.
    for (const std::string& out : {o->out, o->stats, o->inverse})
      if (!out.empty()) {
        const auto parent = std::filesystem::path(out).parent_path();
        if (!parent.empty() && !std::filesystem::is_directory(parent))
          throw InputError(out, "", "the folder " + parent.string() + " does not exist", "create it first");
      }
    const std::string pose_source = o->pose.empty() ? o->camera + " (extrinsics)" : o->pose;
    RefractionMap map;
    try {
      map = compute_refraction_map_cached({&mesh, &contact, index.get(), chart ? &*chart : nullptr}, camera,
                                          cam_from_part, opt, cache_dir, &hit);
    } catch (const InputError& e) {
      if (e.element().rfind("pose", 0) != 0) throw;
      throw InputError(pose_source, "cam_from_part", e.what());
    }
    if (map.stats.by_status[0] == 0)
      throw InputError(pose_source, "cam_from_part",
                       "no pixel of " + o->camera + " sees the contact surface through the part",
                       "check the pose, the camera model and the contact surface");
    const std::string cache = cache_dir.empty() ? "off" : hit ? "hit" : "miss";

    nlohmann::json stats = stats_json(map, o->mesh, o->camera, opt, cache);
    std::optional<InverseMap> inverse;
    if (!o->inverse.empty()) {
      if (!chart)
        throw InputError(o->mesh, "contact surface", "cannot be charted, so no inverse map can be made",
                         "the contact surface must be a topological disk per component");
      InverseMapOptions iopt;
      iopt.texel_mm = o->texel_mm;
      inverse = compute_inverse_map(map, iopt, &contact);
      const InverseMap& inv = *inverse;
      stats["inverse"] = {{"width", inv.width},
                          {"height", inv.height},
                          {"texel_mm", inv.texel_mm},
                          {"uv_origin_mm", {inv.uv_origin.x(), inv.uv_origin.y()}},
                          {"texels_valid", inv.error.texels_valid},
                          {"round_trip", {{"max_uv_um", inv.error.max_uv_um}, {"max_px", inv.error.max_px}, {"p99_px", inv.error.p99_px}}},
                          {"ms", inv.raster_ms + inv.error_ms}};
    }
    // Both outputs are rendered before either is written, so a failure leaves neither.
    // All outputs or none: a failure removes what this run already wrote.
    std::vector<std::string> written;
    try {
      write_skin_points_npy(map, o->out);
      written.push_back(o->out);
      if (inverse) {
        write_inverse_map_npy(*inverse, o->inverse);
        written.push_back(o->inverse);
      }
      if (!o->stats.empty()) write_file_atomically(o->stats, stats.dump(2) + "\n");
    } catch (...) {
      std::error_code ignored;
      for (const auto& w : written) std::filesystem::remove(w, ignored);
      throw;
    }
    std::cout << "map " << map.width << " x " << map.height << ": " << map.stats.by_status[0] << " valid pixels ("
              << static_cast<int>(map.stats.coverage * 1000) / 10.0 << " %), traced " << map.stats.traced
              << ", fast path " << map.stats.fast_path << ", mode " << map.stats.mode
              << (hit ? ", from the cache" : ", " + std::to_string(static_cast<int>(map.stats.total_ms)) + " ms") << "\n";
    for (int k = 1; k < kPixelStatusCount; ++k)
      if (map.stats.by_status[k] > 0)
        std::cout << "  " << to_string(static_cast<PixelStatus>(k)) << ": " << map.stats.by_status[k] << "\n";
    if (inverse)
      std::cout << "inverse map " << inverse->width << " x " << inverse->height << " texels of " << inverse->texel_mm
                << " mm, " << inverse->error.texels_valid << " valid; round trip max " << inverse->error.max_px << " px\n";
    std::cout << "wrote " << o->out << (inverse ? ", " + o->inverse : "") << (o->stats.empty() ? "" : ", " + o->stats) << "\n";
    return 0;
  };
}

static const Registration registered{"map", 20, add_map};

}  // namespace clearfit::cli
