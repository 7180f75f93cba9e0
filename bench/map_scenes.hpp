#pragma once
// Scenes, the floor and the error figures shared by `clearfit bench map`
// (cli/bench.cpp) and the Google Benchmark program bench/map_bench.cpp.
//
// A scene: one of the analytic parts (slab, band, dome, bump field) with its
// contact group, an Embree ray index, and an OPENCV8 camera (f = 0.9 width,
// mild distortion) above it on +z looking down, at the distance where the
// part fills 90 % of the image in its tighter direction.
// The floor: the two batched RayIndex::intersect calls an exact map cannot
// avoid, over the pixels the exact map traced: the camera rays, then the
// refracted rays from the entry points with the entry face as skip face
// (built outside the timer).
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map.hpp>
#include <clearfit/refraction/optics.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <optional>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

namespace clearfit::bench {

/// The default shapes: the analytic parts, then the random freeform family
/// (shapes::random_freeform), seeds 6-8: the adaptive criterion was tuned on
/// seeds 1-5 and these were fixed before any of their figures was seen.
inline const std::vector<std::string>& shape_names() {
  static const std::vector<std::string> names = {"slab",    "band",    "dome",    "cap",     "bumps",   "field:6",
                                                 "field:7", "field:8", "shell:6", "shell:7", "shell:8"};
  return names;
}

/// A name make_scene() accepts.
inline bool known_shape(const std::string& name) {
  static const std::regex freeform(R"((field|shell):[0-9]{1,9}(:[0-9]{1,4})?)");
  return std::find(shape_names().begin(), shape_names().end(), name) != shape_names().end() ||
         std::regex_match(name, freeform);
}

/// The spherical-cap shell of `clearfit-bench robustness` (inner radius 30 mm,
/// the wristband's, 2.5 mm thick, 30° half-angle; 37k triangles), "cap" here.
inline Mesh cap_shell() { return shapes::spherical_shell(30, 32.5, 30, 48, 192); }

struct Scene {
  std::string name;
  Mesh mesh;
  ContactSurface contact;
  std::unique_ptr<RayIndex> index;
  std::optional<Chart> chart;  ///< as `clearfit map` computes it (map.chart auto), unless asked for none
  double build_ms = 0;         ///< mesh + ray index
  double index_ms = 0;         ///< the ray index alone
  double chart_ms = 0;
  TraceScene trace() const { return {&mesh, &contact, index.get(), chart ? &*chart : nullptr}; }
};

/// The benchmark parts (mm), 37k-130k triangles: slab, band, dome, cap, bumps, and
/// the random freeform family field:SEED[:N] and shell:SEED[:N]
/// (shapes::random_freeform with N quads per edge, default 160: 103k
/// triangles; N = 224 gives 202k). Throws std::invalid_argument for an
/// unknown name. With `chart`, the contact surface's chart as `clearfit map`
/// computes it by default (grid and adaptive maps then interpolate chart
/// coordinates and put the points back on the mesh); without, they
/// interpolate the 3D points (`map.chart: none`).
inline std::unique_ptr<Scene> make_scene(const std::string& name, bool chart = true) {
  const auto t0 = std::chrono::steady_clock::now();
  auto s = std::make_unique<Scene>();
  s->name = name;
  if (name == "slab") s->mesh = shapes::slab(60, 40, 3, 100);
  else if (name == "band") s->mesh = shapes::cylindrical_shell(32, 34.5, 100, 40, 400, 60);
  else if (name == "dome") s->mesh = shapes::spherical_shell(25, 27.5, 40, 64, 512);
  else if (name == "cap") s->mesh = cap_shell();
  else if (name == "bumps") s->mesh = shapes::bump_plate(60, 40, 3, 140, 12, 2.0, 7);
  else if (name.starts_with("field:") || name.starts_with("shell:")) {
    const auto kind = name.starts_with("shell:") ? shapes::Freeform::shell : shapes::Freeform::height_field;
    const std::string rest = name.substr(6);
    const auto colon = rest.find(':');
    try {
      const unsigned seed = static_cast<unsigned>(std::stoul(rest.substr(0, colon)));
      const int n = colon == std::string::npos ? 160 : std::stoi(rest.substr(colon + 1));
      s->mesh = shapes::random_freeform(kind, seed, n);
    } catch (const std::logic_error&) {
      throw std::invalid_argument("bench: shape '" + name + "': expected field:SEED[:N] or shell:SEED[:N]");
    }
  } else
    throw std::invalid_argument("bench: unknown shape '" + name +
                                "' (slab, band, dome, cap, bumps, field:SEED[:N], shell:SEED[:N])");
  ContactSelector sel;
  sel.group = "contact";
  s->contact = select_contact(s->mesh, sel);
  const auto ti = std::chrono::steady_clock::now();
  s->index = make_ray_index(s->mesh, RayBackend::embree);
  s->index_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - ti).count();
  s->build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (chart) {
    const auto t1 = std::chrono::steady_clock::now();
    s->chart = compute_chart(s->mesh, s->contact);
    s->chart_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
  }
  return s;
}

/// OPENCV8 camera, f = 0.9 width, principal point at the centre, mild barrel
/// distortion (about 2 px at the corners of a 640x480 image).
inline CameraModel make_camera(int width, int height) {
  CameraModel c;
  c.lensmodel = "LENSMODEL_OPENCV8";
  const double f = 0.9 * width;
  c.intrinsics = {f, f, (width - 1) / 2.0, (height - 1) / 2.0, -0.04, 0.01, 2e-4, -1e-4, 0.0, 0.005, 0.0, 0.0};
  c.width = width;
  c.height = height;
  return c;
}

/// Camera on the +z axis looking down (cam_from_part rotation diag(1, -1, -1)),
/// as close as keeps every vertex within 90 % of the image (pinhole estimate).
inline Rigid3 frame_part(const Mesh& mesh, const CameraModel& camera) {
  const double f = camera.intrinsics[0];
  const double hx = 0.45 * camera.width / f, hy = 0.45 * camera.height / f;  // tan of the usable half angles
  double zc = -1e300;
  for (const Vec3& v : mesh.vertices) zc = std::max({zc, v.z() + std::abs(v.x()) / hx, v.z() + std::abs(v.y()) / hy});
  Rigid3 cam_from_part;
  cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  cam_from_part.translation = Vec3(0, 0, zc);
  return cam_from_part;
}

struct Floor {
  double ms = 0, cast1_ms = 0, cast2_ms = 0;  ///< best of the repeats (both casts timed in the same repeat)
  long long rays1 = 0, rays2 = 0;
  /// Both casts again, the refracted rays without their entry face as skip
  /// face (the floor's definition before RayIndex had skip faces: Embree then
  /// re-casts each refracted ray that re-finds its entry face in float).
  double recast_ms = 0;
  /// CPU time of the process (all threads) for the two casts, best of the
  /// repeats: steadier than wall time on a shared machine.
  double cpu_ms = 0;
};

/// CPU time used by the process so far (all threads), ms.
inline double process_cpu_ms() { return 1e3 * static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

/// The floor of the exact map `exact` of this scene and camera: the pixels it
/// traced (status other than `outside`) cast once from the camera, then their
/// refracted rays (front-facing non-contact first hits) cast again, skipping
/// their entry face.
/// `rays` is unproject_image(camera) (not timed).
inline Floor measure_floor(const Scene& scene, const RayGrid& rays, const Rigid3& cam_from_part,
                           const RefractionMap& exact, const optics::Indices& n, int repeat) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Rigid3 part_from_cam = cam_from_part.inverse();
  std::vector<Ray> first;
  for (std::size_t p = 0; p < exact.status.size(); ++p)
    if (exact.status[p] != PixelStatus::outside && rays.rays[p].allFinite())
      first.push_back({part_from_cam.translation, part_from_cam.rotation * rays.rays[p]});
  std::vector<RayHit> hit1(first.size());
  scene.index->intersect(first, hit1);
  std::vector<Ray> second;
  for (std::size_t i = 0; i < first.size(); ++i) {
    const RayHit& h = hit1[i];
    if (!h || !h.front_facing || scene.contact.is_contact[h.face]) continue;
    Vec3 nrm = h.shading_normal;
    const Vec3 d = first[i].direction.normalized();
    if (nrm.dot(d) >= 0) nrm = h.geometric_normal;
    if (auto t = optics::refract(d, nrm, n.n_medium, n.n_part)) second.push_back({h.point, *t, 1e-7, kInf, h.face});
  }
  std::vector<Ray> second_recast = second;
  for (Ray& r : second_recast) r.skip_face = -1;
  std::vector<RayHit> hit2(second.size());
  Floor fl;
  fl.rays1 = static_cast<long long>(first.size());
  fl.rays2 = static_cast<long long>(second.size());
  fl.ms = fl.recast_ms = fl.cpu_ms = 1e300;
  using Clock = std::chrono::steady_clock;
  for (int r = 0; r < std::max(1, repeat); ++r) {
    const double c0 = process_cpu_ms();
    const auto t0 = Clock::now();
    scene.index->intersect(first, hit1);
    const auto t1 = Clock::now();
    scene.index->intersect(second, hit2);
    const auto t2 = Clock::now();
    fl.cpu_ms = std::min(fl.cpu_ms, process_cpu_ms() - c0);
    scene.index->intersect(first, hit1);
    scene.index->intersect(second_recast, hit2);
    const auto t4 = Clock::now();
    auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
    if (ms(t0, t2) < fl.ms) fl.ms = ms(t0, t2), fl.cast1_ms = ms(t0, t1), fl.cast2_ms = ms(t1, t2);
    fl.recast_ms = std::min(fl.recast_ms, ms(t2, t4));
  }
  return fl;
}

struct MapError {
  long long compared = 0;        ///< pixels valid in both maps
  long long validity_diff = 0;   ///< pixels valid in exactly one of them
  long long reason_diff = 0;     ///< pixels invalid in both, for different reasons
  double median_um = 0, p99_um = 0, max_um = 0;
};

/// Per-pixel |skin_point - exact skin_point| (µm) over the pixels valid in
/// both maps; nearest-rank percentiles.
inline MapError compare_maps(const RefractionMap& map, const RefractionMap& exact) {
  if (map.width != exact.width || map.height != exact.height) throw std::invalid_argument("bench: map sizes differ");
  MapError e;
  std::vector<double> d;
  for (std::size_t p = 0; p < map.status.size(); ++p) {
    const bool a = map.status[p] == PixelStatus::valid, b = exact.status[p] == PixelStatus::valid;
    if (a && b) d.push_back((map.skin_point[p] - exact.skin_point[p]).norm() * 1e3);
    else if (a != b) ++e.validity_diff;
    else if (!a && map.status[p] != exact.status[p]) ++e.reason_diff;
  }
  e.compared = static_cast<long long>(d.size());
  if (d.empty()) return e;
  auto rank = [&](double q) {
    const std::size_t k = std::min(d.size() - 1, static_cast<std::size_t>(std::ceil(q * d.size())) - (q > 0 ? 1 : 0));
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
    return d[k];
  };
  e.median_um = rank(0.5);
  e.p99_um = rank(0.99);
  e.max_um = *std::max_element(d.begin(), d.end());
  return e;
}

}  // namespace clearfit::bench
