#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/refraction/map.hpp>

#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>

namespace clearfit {

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

void MapOptions::validate() const { indices.validate(); }

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Ray directions depend only on the camera's intrinsics: computed once per
// camera per process and shared.
std::shared_ptr<const RayGrid> camera_rays(const CameraModel& camera) {
  static std::mutex mutex;
  static std::map<std::uint64_t, std::shared_ptr<const RayGrid>> cache;
  const std::uint64_t key = camera.intrinsics_hash();
  {
    std::lock_guard lock(mutex);
    if (auto it = cache.find(key); it != cache.end()) return it->second;
  }
  auto grid = std::make_shared<const RayGrid>(unproject_image(camera, 1));
  std::lock_guard lock(mutex);
  if (cache.size() > 8) cache.clear();
  return cache.emplace(key, std::move(grid)).first->second;
}

// Pixel bound of the part's image: the box around the projected vertices,
// widened by a margin for lens curvature between vertices. Empty optional:
// no bound (some vertex is behind the camera or does not project).
struct PixelBox {
  double x0, y0, x1, y1;
};
std::optional<PixelBox> part_bound(const Mesh& mesh, const CameraModel& camera, const Rigid3& cam_from_part) {
  std::vector<Vec3> in_cam(mesh.vertices.size());
  for (std::size_t i = 0; i < in_cam.size(); ++i) {
    in_cam[i] = cam_from_part.apply(mesh.vertices[i]);
    if (!(in_cam[i].z() > 0)) return std::nullopt;
  }
  const std::vector<Vec2> q = camera.project(in_cam);
  PixelBox box{1e300, 1e300, -1e300, -1e300};
  for (const Vec2& p : q) {
    if (!p.allFinite()) return std::nullopt;
    box.x0 = std::min(box.x0, p.x());
    box.y0 = std::min(box.y0, p.y());
    box.x1 = std::max(box.x1, p.x());
    box.y1 = std::max(box.y1, p.y());
  }
  const double margin = 4.0 + 0.01 * std::max(box.x1 - box.x0, box.y1 - box.y0);
  return PixelBox{box.x0 - margin, box.y0 - margin, box.x1 + margin, box.y1 + margin};
}

// Smallest t at which a ray leaving a point computed on `face` can no longer
// re-hit that face's plane through rounding: the point is off the plane by at
// most ~8 ulp of the largest coordinate involved; along a direction making
// cosine `cos_n` with the plane's normal that becomes a distance / cos_n.
double leave_surface_t(const Mesh& mesh, int face, const Vec3& point, double cos_n, double dir_norm) {
  double scale = point.cwiseAbs().maxCoeff();
  for (int k = 0; k < 3; ++k) scale = std::max(scale, mesh.corner(face, k).cwiseAbs().maxCoeff());
  const double err = 16 * std::numeric_limits<double>::epsilon() * scale;
  return err / std::max(cos_n, 1e-6) / dir_norm;
}

constexpr float fnan = std::numeric_limits<float>::quiet_NaN();

}  // namespace

RefractionMap compute_refraction_map(const TraceScene& scene, const CameraModel& camera,
                                     const Rigid3& cam_from_part, const MapOptions& options) {
  const auto t_start = Clock::now();
  options.validate();
  if (!scene.mesh || !scene.contact || !scene.index)
    throw std::invalid_argument("compute_refraction_map: TraceScene needs mesh, contact and index");
  const Mesh& mesh = *scene.mesh;
  const ContactSurface& contact = *scene.contact;
  if (contact.faces.empty())
    throw InputError(mesh.source, "contact surface", "has no faces", "choose the faces the skin touches");
  if (static_cast<int>(contact.is_contact.size()) != mesh.num_faces())
    throw std::invalid_argument("compute_refraction_map: contact surface belongs to another mesh");
  camera.validate();

  const int W = camera.width, H = camera.height;
  const std::size_t N = static_cast<std::size_t>(W) * H;
  RefractionMap map;
  map.width = W;
  map.height = H;
  map.status.assign(N, PixelStatus::outside);
  map.skin_point.assign(N, Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  map.face.assign(N, -1);
  map.bary.assign(N, Eigen::Vector2f::Constant(fnan));
  map.chart_uv.assign(N, Eigen::Vector2f::Constant(fnan));
  map.incidence_deg.assign(N, fnan);
  map.contact_deg.assign(N, fnan);
  map.transmittance.assign(N, fnan);
  MapStats& st = map.stats;
  st.pixels = static_cast<long long>(N);

  // Whole part behind the camera: a pose error, not a physical outcome.
  bool any_in_front = false;
  for (const Vec3& v : mesh.vertices) any_in_front |= cam_from_part.apply(v).z() > 0;
  if (!any_in_front)
    throw InputError("", "pose (cam_from_part)", "puts the whole part behind the camera (every vertex has z <= 0 in the camera frame)",
                     "check the pose's direction and units (mm)");

  auto t0 = Clock::now();
  const std::shared_ptr<const RayGrid> rays = camera_rays(camera);
  st.unproject_ms = ms_since(t0);

  t0 = Clock::now();
  std::optional<PixelBox> box;
  if (options.cull) box = part_bound(mesh, camera, cam_from_part);
  std::vector<std::uint32_t> active;
  active.reserve(N);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (!box || (x >= box->x0 && x <= box->x1 && y >= box->y0 && y <= box->y1))
        active.push_back(static_cast<std::uint32_t>(map.index(x, y)));
  st.cull_ms = ms_since(t0);
  st.traced = static_cast<long long>(active.size());

  t0 = Clock::now();
  const Rigid3 part_from_cam = cam_from_part.inverse();
  const Vec3 eye = part_from_cam.translation;
  const optics::Indices& n = options.indices;
  const bool index_matched = options.fast_paths && n.n_medium == n.n_part;
  st.fast_path = index_matched ? "index-matched" : "none";
  const bool smooth = options.normals == MapOptions::Normals::smooth;
  const CornerNormals& normals = scene.index->normals();

  std::vector<Ray> first(active.size());
  tbb::parallel_for(std::size_t(0), active.size(), [&](std::size_t i) {
    const Vec3& r = rays->rays[active[i]];
    first[i].origin = eye;
    first[i].direction = r.allFinite() ? Vec3(part_from_cam.rotation * r) : Vec3::Zero();
  });
  std::vector<RayHit> hit1(active.size());
  scene.index->intersect(first, hit1);

  // Refract at entry; collect the rays that go on.
  std::vector<Ray> second(active.size());
  std::vector<char> goes_on(active.size(), 0);
  std::vector<double> entry_T(active.size(), 0);
  auto normal_at = [&](const RayHit& h) { return smooth ? h.shading_normal : h.geometric_normal; };
  tbb::parallel_for(std::size_t(0), active.size(), [&](std::size_t i) {
    const std::uint32_t p = active[i];
    const RayHit& h = hit1[i];
    if (first[i].direction.isZero()) { map.status[p] = PixelStatus::no_ray; return; }
    if (!h) { map.status[p] = PixelStatus::miss; return; }
    if (!h.front_facing) { map.status[p] = PixelStatus::back_face; return; }
    if (contact.is_contact[h.face]) { map.status[p] = PixelStatus::contact_first; return; }
    const Vec3 d = first[i].direction.normalized();
    Vec3 nrm = normal_at(h);
    if (nrm.dot(d) >= 0) nrm = h.geometric_normal;  // shading normal turned away near a silhouette
    map.incidence_deg[p] = static_cast<float>(optics::angle_between(-d, nrm) * 180 / M_PI);
    Vec3 d2 = d;
    double T = 1, cos_n = std::abs(d.dot(h.geometric_normal));
    if (!index_matched) {
      const optics::Transmission t = optics::transmit(d, nrm, n.n_medium, n.n_part);
      if (t.tir) { map.status[p] = PixelStatus::entry_tir; return; }
      T = optics::fresnel(t, n.n_medium, n.n_part).T;
      d2 = t.direction;
      cos_n = std::abs(d2.dot(h.geometric_normal));
    }
    entry_T[i] = T;
    second[i].origin = h.point;
    second[i].direction = d2;
    second[i].t_min = leave_surface_t(mesh, h.face, h.point, cos_n, 1.0);
    goes_on[i] = 1;
  });
  std::vector<RayHit> hit2(active.size());
  {
    // Cast only the rays that go on, compacted.
    std::vector<std::uint32_t> which;
    for (std::size_t i = 0; i < active.size(); ++i)
      if (goes_on[i]) which.push_back(static_cast<std::uint32_t>(i));
    std::vector<Ray> compact(which.size());
    for (std::size_t k = 0; k < which.size(); ++k) compact[k] = second[which[k]];
    std::vector<RayHit> out(which.size());
    scene.index->intersect(compact, out);
    for (std::size_t k = 0; k < which.size(); ++k) hit2[which[k]] = out[k];
  }
  tbb::parallel_for(std::size_t(0), active.size(), [&](std::size_t i) {
    if (!goes_on[i]) return;
    const std::uint32_t p = active[i];
    const RayHit& h = hit2[i];
    if (!h || !contact.is_contact[h.face]) { map.status[p] = PixelStatus::exits_elsewhere; return; }
    const Vec3 d2 = second[i].direction;
    Vec3 nrm = normal_at(h);
    if (nrm.dot(d2) <= 0) nrm = h.geometric_normal;
    map.contact_deg[p] = static_cast<float>(optics::angle_between(d2, nrm) * 180 / M_PI);
    double T = entry_T[i];
    if (!index_matched || n.n_part != n.n_skin) {
      const optics::Transmission t = optics::transmit(d2, nrm, n.n_part, n.n_skin);
      if (t.tir) { map.status[p] = PixelStatus::contact_tir; return; }
      T *= optics::fresnel(t, n.n_part, n.n_skin).T;
    }
    map.status[p] = PixelStatus::valid;
    map.skin_point[p] = h.point;
    map.face[p] = h.face;
    map.bary[p] = Eigen::Vector2f(static_cast<float>(h.bary[1]), static_cast<float>(h.bary[2]));
    map.transmittance[p] = static_cast<float>(T);
    if (scene.chart && !scene.chart->uv.empty()) {
      const auto& f = mesh.faces[h.face];
      const Vec2 uv = h.bary[0] * scene.chart->uv[f[0]] + h.bary[1] * scene.chart->uv[f[1]] +
                      h.bary[2] * scene.chart->uv[f[2]];
      map.chart_uv[p] = uv.cast<float>();
    }
  });
  st.trace_ms = ms_since(t0);

  for (PixelStatus s : map.status) ++st.by_status[static_cast<int>(s)];
  st.coverage = static_cast<double>(st.by_status[0]) / static_cast<double>(std::max<long long>(1, st.pixels));
  st.total_ms = ms_since(t_start);
  return map;
}

void write_skin_points_npy(const RefractionMap& map, const std::filesystem::path& path) {
  std::ostringstream dict;
  dict << "{'descr': '<f4', 'fortran_order': False, 'shape': (" << map.height << ", " << map.width << ", 3), }";
  std::string header = dict.str();
  const std::size_t unpadded = 10 + header.size() + 1;  // magic(6) + version(2) + length(2) + '\n'
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');
  write_file_atomically(path, [&](std::ostream& out) {
    out.write("\x93NUMPY\x01\x00", 8);
    const auto len = static_cast<std::uint16_t>(header.size());
    const char le[2] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
    out.write(le, 2);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    std::vector<float> row(static_cast<std::size_t>(map.width) * 3);
    for (int y = 0; y < map.height; ++y) {
      for (int x = 0; x < map.width; ++x)
        for (int k = 0; k < 3; ++k) row[3 * x + k] = static_cast<float>(map.skin_point[map.index(x, y)][k]);
      out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size() * sizeof(float)));
    }
  });
}

}  // namespace clearfit
