// clearfit map: the refraction map of a part seen by a camera (pixel -> skin point).
#include <clearfit/cli/commands.hpp>
#include <clearfit/output_folder.hpp>
#include <clearfit/cli/part_setup.hpp>
#include <clearfit/cli/scene.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <clearfit/refraction/map_cache.hpp>
#include <cstdlib>
#include <set>
#include <sstream>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

namespace clearfit::cli {

namespace {
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
          {"exact_reasons", opt.mode == MapOptions::Mode::exact || opt.exact_reasons},
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
    std::string scene_file;
    Scene scene;
    SceneFields::Options options;
    CacheOptions cache;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand("map", "Refraction map: for every camera pixel, the skin point it sees through the part");
  sub->add_option("--scene", o->scene_file, "Scene file (YAML) giving any of the options below; the command line wins");
  o->options = add_scene_options(*sub, o->scene, {"", "contact", "map", "outputs.map", "outputs.stats", "outputs.inverse", "outputs.texel_mm"});
  add_cache_options(*sub, o->cache);

  return [o]() {
    const OutputsSection& out = o->scene.outputs;
    // Folders of the scene's outputs that do not exist yet are created when the
    // outputs are written; the command line's must exist.
    std::set<std::string> may_create;
    if (!o->scene_file.empty()) {
      read_scene(o->scene_file, o->scene, o->options);
      for (const auto& [key, path] : {std::pair{"outputs.map", out.map}, {"outputs.stats", out.stats}, {"outputs.inverse", out.inverse}})
        if (!path.empty() && !given_on_command_line(o->options, key)) may_create.insert(path);
    } else {
      check_scene(o->scene, o->options);
    }
    if (out.map.empty())
      throw InputError("", "--out", "is required", "give it on the command line or as 'outputs.map' in a --scene file");
    // Output folders are checked before the work, so a bad path fails fast and leaves nothing.
    for (const std::string& path : {out.map, out.stats, out.inverse})
      if (!path.empty()) check_output_folder(path, may_create.count(path) > 0);
    const auto part = load_part_scene(o->scene, !out.inverse.empty(), std::cerr);
    std::string cache;
    const RefractionMap map = compute_part_map(*part, o->cache, &cache);
    const bool hit = cache == "hit";
    nlohmann::json stats = stats_json(map, o->scene.part.mesh, o->scene.part.camera, part->map_options, cache);
    std::optional<InverseMap> inverse;
    if (!out.inverse.empty()) {
      InverseMapOptions iopt;
      iopt.texel_mm = out.texel_mm;
      inverse = compute_inverse_map(map, iopt, &part->contact);
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
    std::vector<std::filesystem::path> created;
    try {
      for (const std::string& path : may_create)
        for (auto& c : create_output_folders(path)) created.push_back(std::move(c));
      write_skin_points_npy(map, out.map);
      written.push_back(out.map);
      if (inverse) {
        write_inverse_map_npy(*inverse, out.inverse);
        written.push_back(out.inverse);
      }
      if (!out.stats.empty()) write_file_atomically(out.stats, stats.dump(2) + "\n");
    } catch (...) {
      std::error_code ignored;
      for (const auto& w : written) std::filesystem::remove(w, ignored);
      for (auto it = created.rbegin(); it != created.rend(); ++it) std::filesystem::remove(*it, ignored);  // only if empty
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
    std::cout << "wrote " << out.map << (inverse ? ", " + out.inverse : "") << (out.stats.empty() ? "" : ", " + out.stats) << "\n";
    return 0;
  };
}

static const Registration registered{"map", 20, add_map};

}  // namespace clearfit::cli
