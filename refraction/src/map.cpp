// The refraction map: the public entry points and the order of the stages
// (map_stages.hpp): rays and the part's bound, then the exact trace or the
// quadtree, then the statistics.
#include "map_stages.hpp"

#include <clearfit/error.hpp>
#include <clearfit/npy.hpp>
#include <clearfit/refraction/map.hpp>

#include <tbb/parallel_for.h>

#include <algorithm>

namespace clearfit {

using namespace refraction_detail;

const char* to_string(PixelStatus s) {
  switch (s) {
    case PixelStatus::valid: return "valid";
    case PixelStatus::outside: return "outside";
    case PixelStatus::miss: return "miss";
    case PixelStatus::no_ray: return "no_ray";
    case PixelStatus::contact_first: return "contact_first";
    case PixelStatus::back_face: return "back_face";
    case PixelStatus::entry_tir: return "entry_tir";
    case PixelStatus::exits_elsewhere: return "exits_elsewhere";
    case PixelStatus::contact_tir: return "contact_tir";
  }
  return "?";
}

void MapOptions::validate() const {
  indices.validate();
  auto fail = [](const std::string& what) { throw std::invalid_argument("MapOptions::" + what); };
  if (grid_step < 2 || grid_step > 256 || (grid_step & (grid_step - 1)) != 0)
    fail("grid_step = " + std::to_string(grid_step) + ": must be a power of two in [2, 256]");
  if (!(tolerance_um > 0) || !std::isfinite(tolerance_um))
    fail("tolerance_um = " + std::to_string(tolerance_um) + ": must be a finite number > 0");
}

void trace_skin_rays(const TraceScene& scene, std::span<const Ray> rays, std::span<SkinSample> out,
                     const MapOptions& options) {
  options.validate();
  check_scene(scene);
  if (rays.size() != out.size()) throw std::invalid_argument("trace_skin_rays: rays and out differ in size");
  std::vector<Ray> first(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) first[i] = Ray{rays[i].origin, rays[i].direction};
  Tracer(scene, options).trace(first, out);
}

SkinSample trace_skin_ray(const TraceScene& scene, const Vec3& origin, const Vec3& direction, const MapOptions& options) {
  const Ray ray{origin, direction};
  SkinSample s;
  trace_skin_rays(scene, std::span<const Ray>(&ray, 1), std::span<SkinSample>(&s, 1), options);
  return s;
}

RefractionMap compute_refraction_map(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                                     const MapOptions& options) {
  const auto t_start = Clock::now();
  options.validate();
  check_scene(scene);
  camera.validate();
  const Mesh& mesh = *scene.mesh;
  RefractionMap map;
  allocate(map, camera.width, camera.height);  // filled in parallel below (every pixel written once)
  MapStats& st = map.stats;
  st.pixels = static_cast<long long>(map.status.size());
  st.mode = options.mode == MapOptions::Mode::exact ? "exact" : options.mode == MapOptions::Mode::grid ? "grid" : "adaptive";

  bool any_in_front = false;
  for (const Vec3& v : mesh.vertices) any_in_front |= cam_from_part.apply(v).z() > 0;
  if (!any_in_front)
    throw PoseError("", "pose (cam_from_part)",
                    "puts the whole part behind the camera (every vertex has z <= 0 in the camera frame)",
                    "check the pose's direction and units (mm)");

  const std::shared_ptr<CameraRays> rays = camera_rays(camera);
  auto t0 = Clock::now();
  PixelBox box{0, 0, camera.width - 1, camera.height - 1};
  if (options.cull)
    if (auto b = part_bound(mesh, camera, cam_from_part)) box = *b;
  st.cull_ms = ms_since(t0);

  t0 = Clock::now();
  const Tracer tracer(scene, options);
  st.fast_path = tracer.fast_path();
  const MapRun run{scene, options, tracer, *rays, cam_from_part.inverse(), box, map};
  if (options.mode == MapOptions::Mode::exact) trace_exact(run);
  else refine_quadtree(run);
  measure_seen_fraction(run);
  st.trace_ms = ms_since(t0) - st.unproject_ms;
  count_statuses(map);
  st.total_ms = ms_since(t_start);
  return map;
}

void write_skin_points_npy(const RefractionMap& map, const std::filesystem::path& path) {
  npy::write_float32(path, {static_cast<std::size_t>(map.height), static_cast<std::size_t>(map.width), 3},
                     [&](std::size_t y, float* out) {
                       for (int x = 0; x < map.width; ++x)
                         for (int k = 0; k < 3; ++k)
                           out[3 * x + k] = static_cast<float>(map.skin_point[map.index(x, static_cast<int>(y))][k]);
                     });
}

}  // namespace clearfit
