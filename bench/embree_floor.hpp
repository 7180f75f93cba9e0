#pragma once
// A plain Embree floor for the exact refraction map, independent of
// clearfit's ray index: build a BVH of the part (float vertices, default
// quality), then per 4x4 pixel tile one rtcIntersect16 of the camera rays
// and one of the rays refracted at their hits (Snell at the geometric normal,
// no double-precision refinement, no guards, no statuses), in parallel over
// all cores (TBB). What an exact map cannot do with less: its BVH and its two
// casts. The outline pixels' seen fraction (kSeenSub x kSeenSub rays per
// pixel, compute_refraction_map) is cast the same way, a pixel's rays to a
// packet. Used by `clearfit-bench map` (column `xemb`).
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pixel_unprojector.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/refraction/map.hpp>
#include <clearfit/refraction/optics.hpp>

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <stdexcept>
#include <vector>

namespace clearfit::bench {

struct EmbreeFloor {
  double build_ms = 1e300, cast_ms = 1e300;  ///< best of the repeats (each its own best)
  double ms = 1e300;                         ///< best BVH build + both casts in one repeat
  double cpu_ms = 1e300;                     ///< both casts in process CPU time (all threads), best of the repeats
  long long rays1 = 0, rays2 = 0;            ///< camera rays cast, refracted rays cast (outline rays included)
  long long outline_rays = 0;                ///< of rays1: the seen fraction's rays of the outline pixels
};

/// One packet of up to 16 camera rays (unit directions in the part frame;
/// inactive lanes have `valid` 0) cast from `origin`, then the rays refracted
/// at their hits (Snell at the geometric normal, indices ratio `eta`) cast
/// again. Returns the refracted rays cast; the camera rays are the caller's.
inline int cast_floor_packet(RTCScene scene, RTCIntersectContext& ctx, RTCRayHit16& p, int (&valid)[16],
                             const Eigen::Vector3f& origin, float eta) {
  for (int k = 0; k < 16; ++k) {
    p.ray.org_x[k] = origin.x(), p.ray.org_y[k] = origin.y(), p.ray.org_z[k] = origin.z();
    p.ray.tnear[k] = 0, p.ray.tfar[k] = std::numeric_limits<float>::infinity();
    p.ray.mask[k] = 0xffffffffu, p.ray.time[k] = 0, p.ray.flags[k] = 0;
    p.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid, scene, &ctx, &p);
  // The refracted rays from the hits, in the same packet.
  int second = 0;
  for (int k = 0; k < 16; ++k) {
    if (!valid[k]) continue;
    if (p.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID) {
      valid[k] = 0;
      continue;
    }
    const Eigen::Vector3f d(p.ray.dir_x[k], p.ray.dir_y[k], p.ray.dir_z[k]);
    Eigen::Vector3f nrm(p.hit.Ng_x[k], p.hit.Ng_y[k], p.hit.Ng_z[k]);
    nrm.normalize();
    if (nrm.dot(d) > 0) nrm = -nrm;
    const float cos_i = -nrm.dot(d), k2 = 1 - eta * eta * (1 - cos_i * cos_i);
    if (k2 < 0) {
      valid[k] = 0;
      continue;
    }
    const Eigen::Vector3f t_dir = eta * d + (eta * cos_i - std::sqrt(k2)) * nrm;
    const float tf = p.ray.tfar[k];
    p.ray.org_x[k] += tf * d.x(), p.ray.org_y[k] += tf * d.y(), p.ray.org_z[k] += tf * d.z();
    p.ray.dir_x[k] = t_dir.x(), p.ray.dir_y[k] = t_dir.y(), p.ray.dir_z[k] = t_dir.z();
    p.ray.tnear[k] = 1e-4f * std::max(1.0f, tf), p.ray.tfar[k] = std::numeric_limits<float>::infinity();
    p.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    ++second;
  }
  if (second > 0) rtcIntersect16(valid, scene, &ctx, &p);
  return second;
}

/// The floor for the pixels the exact map `exact` traced (status other than
/// `outside`) of camera rays `rays` (unproject_image, not timed), and for the
/// rays of its seen outline (unprojected through `camera`, not timed), the
/// part placed by cam_from_part, refracting from n.n_medium into n.n_part.
inline EmbreeFloor measure_embree_floor(const Mesh& mesh, const CameraModel& camera, const RayGrid& rays,
                                        const Rigid3& cam_from_part, const RefractionMap& exact,
                                        const optics::Indices& n, int repeat) {
  RTCDevice device = rtcNewDevice(nullptr);
  if (!device) throw std::runtime_error("bench: rtcNewDevice failed");
  const Rigid3 part_from_cam = cam_from_part.inverse();
  const Eigen::Vector3f origin = part_from_cam.translation.cast<float>();
  const int W = exact.width, H = exact.height, tiles_x = (W + 3) / 4, tiles_y = (H + 3) / 4;
  const float eta = static_cast<float>(n.n_medium / n.n_part);
  const std::vector<std::uint32_t> outline = seen_outline(exact);
  constexpr int kPer = kSeenSub * kSeenSub;
  static_assert(kPer == 16, "one packet per outline pixel");
  std::vector<Vec2> points;
  for (std::uint32_t px : outline) {
    const auto square = seen_sample_points(static_cast<int>(px % W), static_cast<int>(px / W));
    points.insert(points.end(), square.begin(), square.end());
  }
  std::vector<Vec3> sub_rays(points.size());
  PixelUnprojector(camera).unproject(points, sub_rays);
  EmbreeFloor fl;
  using Clock = std::chrono::steady_clock;
  auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  for (int r = 0; r < std::max(1, repeat); ++r) {
    const auto t0 = Clock::now();
    RTCScene scene = rtcNewScene(device);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertices.size()));
    auto* ix = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), mesh.faces.size()));
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
      for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
    for (std::size_t f = 0; f < mesh.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) ix[3 * f + k] = static_cast<unsigned>(mesh.faces[f][k]);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    const auto t1 = Clock::now();
    const double c1 = 1e3 * static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
    std::atomic<long long> cast1{0}, cast2{0};
    tbb::parallel_for(tbb::blocked_range<int>(0, tiles_x * tiles_y, 16), [&](const tbb::blocked_range<int>& range) {
      long long c1 = 0, c2 = 0;
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      for (int t = range.begin(); t < range.end(); ++t) {
        alignas(64) RTCRayHit16 p;
        alignas(64) int valid[16];
        const int x0 = t % tiles_x * 4, y0 = t / tiles_x * 4;
        int active = 0;
        for (int k = 0; k < 16; ++k) {
          const int x = x0 + k % 4, y = y0 + k / 4;
          valid[k] = 0;
          if (x >= W || y >= H) continue;
          const std::size_t px = static_cast<std::size_t>(y) * W + x;
          const Vec3& d_cam = rays.rays[px];
          if (exact.status[px] == PixelStatus::outside || !d_cam.allFinite()) continue;
          const Eigen::Vector3f d = (part_from_cam.rotation * d_cam).cast<float>();
          valid[k] = -1, ++active;
          p.ray.dir_x[k] = d.x(), p.ray.dir_y[k] = d.y(), p.ray.dir_z[k] = d.z();
        }
        if (active == 0) continue;
        c1 += active;
        c2 += cast_floor_packet(scene, ctx, p, valid, origin, eta);
      }
      cast1 += c1, cast2 += c2;
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, outline.size(), 64), [&](const auto& range) {
      long long c1 = 0, c2 = 0;
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      for (std::size_t i = range.begin(); i < range.end(); ++i) {
        alignas(64) RTCRayHit16 p;
        alignas(64) int valid[16];
        int active = 0;
        for (int k = 0; k < kPer; ++k) {
          const Vec3& d_cam = sub_rays[i * kPer + k];
          valid[k] = d_cam.allFinite() ? -1 : 0;
          if (!valid[k]) continue;
          const Eigen::Vector3f d = (part_from_cam.rotation * d_cam).cast<float>();
          ++active;
          p.ray.dir_x[k] = d.x(), p.ray.dir_y[k] = d.y(), p.ray.dir_z[k] = d.z();
        }
        if (active == 0) continue;
        c1 += active;
        c2 += cast_floor_packet(scene, ctx, p, valid, origin, eta);
      }
      cast1 += c1, cast2 += c2;
    });
    const auto t2 = Clock::now();
    fl.cpu_ms = std::min(fl.cpu_ms, 1e3 * static_cast<double>(std::clock()) / CLOCKS_PER_SEC - c1);
    rtcReleaseScene(scene);
    fl.build_ms = std::min(fl.build_ms, ms(t0, t1));
    fl.cast_ms = std::min(fl.cast_ms, ms(t1, t2));
    fl.ms = std::min(fl.ms, ms(t0, t2));
    fl.rays1 = cast1, fl.rays2 = cast2;
    fl.outline_rays = static_cast<long long>(points.size());
  }
  rtcReleaseDevice(device);
  return fl;
}

}  // namespace clearfit::bench
