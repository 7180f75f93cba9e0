// Numerical limits of the trace and the map (issue 16, section 5): indices of
// refraction from 1.0001 to 3, grazing rays, slivers and zero-area triangles,
// parts from micrometres to metres, random poses of cameras down to one pixel.
// Every result is either a finite skin point that matches an independent
// answer (the closed-form slab, the same part at another scale) or an invalid
// pixel with its reason and NaN; nothing throws but a PoseError for a part
// wholly behind the camera.
// Ray counts scale with CLEARFIT_RAY_TEST_SCALE (default 1: some 1.5e5 rays;
// scripts/numerical-sweep.sh runs it at 10 and more).
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/analytic.hpp>
#include <clearfit/refraction/map.hpp>
#include <gtest/gtest.h>

#include "../support/trace_part.hpp"

#include <cmath>
#include <cstdio>
#include <random>

using namespace clearfit;

namespace {

using Part = test::TracePart;

constexpr double kDeg = M_PI / 180;

// The invariants every traced sample keeps, whatever the input.
void expect_sane(const SkinSample& s, const char* what) {
  if (s.status == PixelStatus::valid) {
    ASSERT_TRUE(s.skin_point.allFinite()) << what;
    ASSERT_TRUE(std::isfinite(s.transmittance) && s.transmittance > 0 && s.transmittance <= 1)
        << what << ": T = " << s.transmittance;
    ASSERT_TRUE(std::isfinite(s.incidence_deg) && std::isfinite(s.contact_deg)) << what;
    ASSERT_GE(s.face, 0) << what;
    for (double b : s.bary) ASSERT_TRUE(std::isfinite(b)) << what;
  } else {
    ASSERT_FALSE(s.skin_point.allFinite()) << what << ": " << to_string(s.status);
    ASSERT_LT(static_cast<int>(s.status), kPixelStatusCount) << what;
  }
}

// The map's counterpart of expect_sane, pixel by pixel.
void expect_sane(const RefractionMap& map, const std::string& what) {
  ASSERT_EQ(map.status.size(), static_cast<std::size_t>(map.width) * map.height) << what;
  for (std::size_t i = 0; i < map.status.size(); ++i) {
    if (map.status[i] == PixelStatus::valid) {
      ASSERT_TRUE(map.skin_point[i].allFinite()) << what << " pixel " << i;
      ASSERT_TRUE(std::isfinite(map.transmittance[i]) && map.transmittance[i] > 0 && map.transmittance[i] <= 1)
          << what << " pixel " << i << ": T = " << map.transmittance[i];
      ASSERT_TRUE(std::isfinite(map.incidence_deg[i]) && std::isfinite(map.contact_deg[i])) << what << " pixel " << i;
      ASSERT_TRUE(map.bary[i].allFinite()) << what << " pixel " << i;
      ASSERT_GE(map.face[i], 0) << what << " pixel " << i;
    } else {
      ASSERT_FALSE(map.skin_point[i].allFinite()) << what << " pixel " << i;
      ASSERT_LT(static_cast<int>(map.status[i]), kPixelStatusCount) << what << " pixel " << i;
    }
  }
  ASSERT_TRUE(std::isfinite(map.stats.coverage) && std::isfinite(map.stats.max_error_um)) << what;
}

PixelStatus expected_status(analytic::Reason r) {
  switch (r) {
    case analytic::Reason::ok: return PixelStatus::valid;
    case analytic::Reason::tir: return PixelStatus::entry_tir;
    case analytic::Reason::contact_tir: return PixelStatus::contact_tir;
    case analytic::Reason::exit_elsewhere: return PixelStatus::exits_elsewhere;
    case analytic::Reason::miss: return PixelStatus::miss;
  }
  return PixelStatus::miss;
}

CameraModel pinhole(int w, int h, double f) {
  CameraModel c;
  c.lensmodel = "LENSMODEL_PINHOLE";
  c.intrinsics = {f, f, (w - 1) / 2.0, (h - 1) / 2.0};
  c.width = w;
  c.height = h;
  return c;
}

// A camera on the part's +z axis at `distance`, looking down at the part (the
// shapes' convention): camera z is the part's −z.
Rigid3 looking_down(double distance) {
  Rigid3 cam_from_part;
  cam_from_part.rotation = Eigen::AngleAxisd(M_PI, Vec3::UnitX()).toRotationMatrix();
  cam_from_part.translation = Vec3(0, 0, distance);
  return cam_from_part;
}

// Splits every triangle of `m` at a point `near` an edge: two slivers and a
// fat triangle. weight 0 puts the point exactly on the edge (a zero-area
// triangle); 1e-9 and 1e-13 give slivers of relative height 1e-9 and 1e-13.
Mesh with_slivers(const Mesh& m, double weight) {
  Mesh out = m;
  out.faces.clear();
  out.file_face.clear();
  out.face_group.clear();
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto [a, b, c] = m.faces[f];
    const double w = f % 3 == 0 ? 0.0 : weight;  // every third face gets a zero-area triangle
    out.vertices.push_back((0.5 - w / 2) * m.vertices[a] + (0.5 - w / 2) * m.vertices[b] + w * m.vertices[c]);
    const int p = out.num_vertices() - 1;
    for (const std::array<int, 3>& t : {std::array<int, 3>{a, p, c}, {p, b, c}, {a, b, p}}) {
      out.faces.push_back(t);
      out.file_face.push_back(static_cast<int>(out.faces.size()) - 1);
      if (!m.face_group.empty()) out.face_group.push_back(m.face_group[f]);
    }
  }
  out.check_consistent();
  return out;
}

}  // namespace

TEST(NumericalLimits, SlabAtEveryIndexAndGrazingAngleMatchesTheClosedForm) {
  // Indices from 1.0001 to 3 on each side, incidence from 0 to 89.999°, with
  // and without the slab's closed-form fast path: the mesh trace gives the
  // closed form's outcome and skin point (where the skin point lies on the
  // 400 mm plate; beyond it the ray leaves through the side).
  const double thickness = 3, half = 200;
  const Part slab(shapes::slab(2 * half, 2 * half, thickness, 2));
  const double angles_deg[] = {0, 1e-7, 1, 30, 60, 80, 85, 89, 89.9, 89.99, 89.999};
  const double parts[] = {1.0001, 1.001, 1.01, 1.2, 1.49, 2, 3};
  int compared = 0, outcomes[kPixelStatusCount] = {};
  double worst = 0, worst_t = 0;
  for (double n_part : parts)
    for (double n_medium : {1.0, 1.333, 1.0001})
      for (double n_skin : {1.0, 1.4, 3.0})
        for (bool fast : {true, false})
          for (double a_deg : angles_deg) {
            MapOptions opt;
            opt.indices = {n_medium, n_part, n_skin};
            opt.fast_paths = fast;
            const double a = a_deg * kDeg, phi = 0.3;
            const Vec3 dir(std::sin(a) * std::cos(phi), std::sin(a) * std::sin(phi), -std::cos(a));
            const Vec3 origin = Vec3(0.37, -0.61, thickness) - 20 * dir;
            const SkinSample s = trace_skin_ray(slab.scene(), origin, dir, opt);
            char what[160];
            std::snprintf(what, sizeof what, "n %g/%g/%g, %g deg, fast path %d", n_medium, n_part, n_skin, a_deg, fast);
            expect_sane(s, what);
            ++outcomes[static_cast<int>(s.status)];
            const analytic::SkinHit ref = analytic::trace_slab(origin, dir, thickness, opt.indices);
            if (ref.reason == analytic::Reason::ok || ref.reason == analytic::Reason::contact_tir) {
              const double r = ref.skin_point.head<2>().cwiseAbs().maxCoeff();
              if (r > half - 1 && r < half + 1) continue;  // at the plate's edge
              if (r >= half + 1) {
                EXPECT_EQ(s.status, PixelStatus::exits_elsewhere) << what;
                continue;
              }
            }
            ASSERT_EQ(s.status, expected_status(ref.reason)) << what;
            if (s.status != PixelStatus::valid) continue;
            // Rounding grows with the path in the part (up to 1/cos θ_t thicknesses).
            const double path = (ref.skin_point - ref.entry_point).norm();
            const double err = (s.skin_point - ref.skin_point).norm() / (1 + path);
            worst = std::max(worst, err);
            EXPECT_LT(err, 1e-12) << what;
            worst_t = std::max(worst_t, std::abs(s.transmittance - ref.transmittance));
            EXPECT_NEAR(s.transmittance, ref.transmittance, 1e-12) << what;
            EXPECT_NEAR(s.incidence_deg, ref.incidence_rad / kDeg, 1e-9) << what;
            ++compared;
          }
  std::printf("  %d rays compared with the closed form; worst skin point %.2g mm per mm of path, T %.2g\n", compared,
              worst, worst_t);
  for (int k = 0; k < kPixelStatusCount; ++k)
    if (outcomes[k]) std::printf("  %-16s %d\n", to_string(static_cast<PixelStatus>(k)), outcomes[k]);
  EXPECT_GT(compared, 800);
  EXPECT_GT(outcomes[static_cast<int>(PixelStatus::entry_tir)], 0);
  EXPECT_GT(outcomes[static_cast<int>(PixelStatus::contact_tir)], 0);
  EXPECT_GT(outcomes[static_cast<int>(PixelStatus::exits_elsewhere)], 0);
}

TEST(NumericalLimits, RaysInThePlaneOfAFaceAndDegenerateDirections) {
  // Exactly grazing rays (in the outer plane, along an edge, through a
  // vertex), rays from the surface itself, and directions that are zero, NaN,
  // denormal or huge: an outcome with its reason, never a NaN skin point.
  const Part slab(shapes::slab(40, 40, 3, 4));
  const double tiny = std::numeric_limits<double>::denorm_min(), nan = std::nan("");
  const std::pair<Vec3, Vec3> rays[] = {
      {{-30, 0.3, 3}, {1, 0, 0}},           // in the outer plane
      {{-30, 0, 3}, {1, 0, 0}},             // along the outer plane's edge row
      {{-30, -20, 3}, {1, 0, 0}},           // along the part's rim
      {{-30, -30, 3}, {1, 1, 0}},           // through a corner vertex along a diagonal
      {{0.3, 0.2, 3}, {0, 0, -1}},          // starting on the outer face
      {{0.3, 0.2, 0}, {0, 0, -1}},          // starting on the contact face, leaving
      {{0.3, 0.2, 1.5}, {0, 0, 1}},         // inside the part
      {{0.3, 0.2, 10}, {0, 0, 0}},          // no direction
      {{0.3, 0.2, 10}, {tiny, 0, -tiny}},   // denormal direction
      {{0.3, 0.2, 10}, {1e-300, 0, -1e-300}},
      {{0.3, 0.2, 10}, {0, 0, -1e300}},     // huge direction
      {{0.3, 0.2, 10}, {nan, 0, -1}},
      {{nan, 0.2, 10}, {0, 0, -1}},
      {{0.3, 0.2, 1e300}, {0, 0, -1}},      // from very far
      {{0.3, 0.2, 10}, {1, 0, -1e-17}},     // grazing from above, never reaching the plate's plane in range
      {{-19.999999, 0.2, 3.0000001}, {1, 0, -1e-7}},  // enters at 89.99999 deg
  };
  for (bool fast : {true, false})
    for (const auto& [o, d] : rays) {
      MapOptions opt;
      opt.fast_paths = fast;
      char what[160];
      std::snprintf(what, sizeof what, "origin (%g %g %g) dir (%g %g %g) fast %d", o.x(), o.y(), o.z(), d.x(), d.y(),
                    d.z(), fast);
      SkinSample s;
      ASSERT_NO_THROW(s = trace_skin_ray(slab.scene(), o, d, opt)) << what;
      expect_sane(s, what);
      std::vector<SkinSample> batch(1);
      const Ray ray{o, d};
      ASSERT_NO_THROW(trace_skin_rays(slab.scene(), std::span<const Ray>(&ray, 1), batch, opt)) << what;
      EXPECT_EQ(batch[0].status, s.status) << what;
    }
}

TEST(NumericalLimits, SliverAndZeroAreaTrianglesGiveTheFlatAnswer) {
  // A slab whose every triangle is split at a point on or within 1e-9 or
  // 1e-13 of an edge: zero-area triangles and slivers on both the entry and
  // the contact face. Smooth and flat normals must still be the plate's, so
  // every ray gives the closed form's skin point.
  const double thickness = 3;
  const optics::Indices n{1.0, 1.49, 1.4};
  std::mt19937_64 rng(160501);
  std::printf("  seed 160501\n");
  std::uniform_real_distribution<double> u(-1, 1);
  for (double weight : {1e-9, 1e-13}) {
    const Part part(with_slivers(shapes::slab(40, 40, thickness, 3), weight));
    for (auto normals : {MapOptions::Normals::smooth, MapOptions::Normals::flat})
      for (bool fast : {true, false}) {
        MapOptions opt;
        opt.indices = n;
        opt.normals = normals;
        opt.fast_paths = fast;
        int valid = 0;
        double worst = 0;
        const int count = static_cast<int>(4000 * test::ray_test_scale());
        std::vector<Ray> rays(count);
        for (std::size_t i = 0; i < rays.size(); ++i) {
          // Aim at the outer face's grid vertices, its grid lines and anywhere, alike.
          const double step = 40.0 / 3, gx = -20 + step * std::round((u(rng) + 1) * 1.5);
          const double gy = -20 + step * std::round((u(rng) + 1) * 1.5);
          const Vec3 target = i % 3 == 0 ? Vec3(gx, gy, thickness)
                              : i % 3 == 1 ? Vec3(gx, 15 * u(rng), thickness)
                                           : Vec3(15 * u(rng), 15 * u(rng), thickness);
          rays[i].origin = target + Vec3(8 * u(rng), 8 * u(rng), 10);
          rays[i].direction = target - rays[i].origin;
        }
        std::vector<SkinSample> out(rays.size());
        trace_skin_rays(part.scene(), rays, out, opt);
        for (std::size_t i = 0; i < rays.size(); ++i) {
          char what[120];
          std::snprintf(what, sizeof what, "weight %g, ray %zu, %s normals, fast %d", weight, i,
                        normals == MapOptions::Normals::smooth ? "smooth" : "flat", fast);
          expect_sane(out[i], what);
          const analytic::SkinHit ref = analytic::trace_slab(rays[i].origin, rays[i].direction, thickness, n);
          const double rim = std::max(ref.skin_point.head<2>().cwiseAbs().maxCoeff(),
                                      ref.entry_point.head<2>().cwiseAbs().maxCoeff());
          if (!ref.valid || rim > 19.5) continue;  // enters or leaves through a side wall
          ASSERT_EQ(out[i].status, PixelStatus::valid) << what << ": " << to_string(out[i].status);
          ++valid;
          worst = std::max(worst, (out[i].skin_point - ref.skin_point).norm());
          ASSERT_LT((out[i].skin_point - ref.skin_point).norm(), 1e-9)
              << what << ": entry face " << out[i].entry_face << " (area " << part.mesh.face_area(out[i].entry_face)
              << "), normal " << out[i].entry_normal.transpose() << ", skin face " << out[i].face << " (area "
              << part.mesh.face_area(out[i].face) << ")";
          ASSERT_NEAR(out[i].transmittance, ref.transmittance, 1e-9) << what;
        }
        EXPECT_GT(valid, count / 2);
        std::printf("  slivers %g, %s normals, fast path %d: %d valid, worst %.2g mm\n", weight,
                    normals == MapOptions::Normals::smooth ? "smooth" : "flat", fast, valid, worst);
      }
  }
}

TEST(NumericalLimits, PartsFromMicrometresToMetresGiveTheScaledMap) {
  // The same dome and camera, every length scaled by s from 1e-4 (a 25 nm
  // dome) to 1e4 (a 250 m one): the exact map is the scaled map pixel for
  // pixel; the adaptive map (its tolerance absolute, in µm) stays finite.
  const Mesh base = shapes::spherical_shell(25, 27.5, 40, 16, 64);
  const CameraModel cam = pinhole(96, 72, 120);
  MapOptions exact;
  RefractionMap ref;
  {
    const Part part(base);
    ref = compute_refraction_map(part.scene(), cam, looking_down(80), exact);
  }
  expect_sane(ref, "scale 1");
  ASSERT_GT(ref.stats.coverage, 0.2);
  for (double s : {1e-4, 1e-3, 1e-2, 1e2, 1e3, 1e4}) {
    Mesh scaled = base;
    for (Vec3& v : scaled.vertices) v *= s;
    const Part part(std::move(scaled));
    const RefractionMap map = compute_refraction_map(part.scene(), cam, looking_down(80 * s), exact);
    const std::string what = "scale " + std::to_string(s);
    expect_sane(map, what);
    int differ = 0;
    double worst = 0;
    for (std::size_t i = 0; i < map.status.size(); ++i) {
      if (map.status[i] != ref.status[i]) {
        ++differ;
        continue;
      }
      if (map.status[i] != PixelStatus::valid) continue;
      worst = std::max(worst, (map.skin_point[i] / s - ref.skin_point[i]).norm());
    }
    EXPECT_LE(differ, 2) << what;  // pixels whose ray passes within rounding of an edge
    EXPECT_LT(worst, 1e-9) << what;
    MapOptions adaptive;
    adaptive.mode = MapOptions::Mode::adaptive;
    const RefractionMap fast = compute_refraction_map(part.scene(), cam, looking_down(80 * s), adaptive);
    expect_sane(fast, what + ", adaptive");
    EXPECT_NEAR(fast.stats.coverage, map.stats.coverage, 0.02) << what;
    std::printf("  scale %g: %d pixels differ, worst %.2g mm (at scale 1); adaptive coverage %.3f vs %.3f\n", s,
                differ, worst, fast.stats.coverage, map.stats.coverage);
  }
}

TEST(NumericalLimits, RandomPosesOfTinyToSmallCamerasGiveFiniteMapsOrAPoseError) {
  // Random cameras (1×1 to 48×36 px, focal lengths 0.5 to 1e5 px, pinhole or
  // OPENCV8) at random poses: looking at the part from 1 µm to 1 km, from
  // inside it, from beside it, away from it; exact, grid and adaptive modes.
  const int poses = static_cast<int>(600 * test::ray_test_scale());
  std::mt19937_64 rng(16051);
  std::printf("  seed 16051, %d poses\n", poses);
  std::uniform_real_distribution<double> u(0, 1);
  const Part dome(shapes::spherical_shell(25, 27.5, 40, 12, 48));
  const Part band(shapes::cylindrical_shell(30, 32.5, 200, 20, 48, 4));
  const int sizes[][2] = {{1, 1}, {2, 1}, {1, 3}, {7, 5}, {16, 12}, {48, 36}};
  long long rays = 0, pose_errors = 0, by_status[kPixelStatusCount] = {};
  for (int k = 0; k < poses; ++k) {
    const auto& size = sizes[k % 6];
    CameraModel cam = pinhole(size[0], size[1], std::pow(10.0, -0.3 + 5.3 * u(rng)));
    if (k % 3 == 0) {
      cam.lensmodel = "LENSMODEL_OPENCV8";
      for (int i = 0; i < 8; ++i) cam.intrinsics.push_back(0.4 * (u(rng) - 0.5) / (1 + i));
    }
    // Aim at a random point near the part from a random direction and distance.
    const Vec3 target(40 * (u(rng) - 0.5), 40 * (u(rng) - 0.5), 40 * (u(rng) - 0.2));
    const Vec3 from = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
    const double distance = std::pow(10.0, -3 + 9 * u(rng));
    Vec3 eye = target + distance * from;
    if (k % 7 == 0) eye = Vec3(0, 0, 26.2);  // inside the dome's wall
    Vec3 z = (target - eye).normalized();
    if (k % 11 == 0) z = -z;  // looking away
    const Vec3 x = z.unitOrthogonal();
    Eigen::Matrix3d part_from_cam_rotation;
    part_from_cam_rotation << x, z.cross(x), z;
    Rigid3 part_from_cam;
    part_from_cam.rotation = part_from_cam_rotation;
    part_from_cam.translation = eye;
    const Rigid3 cam_from_part = part_from_cam.inverse();
    MapOptions opt;
    opt.mode = static_cast<MapOptions::Mode>(k % 3);
    opt.grid_step = 4;
    opt.normals = k % 2 ? MapOptions::Normals::smooth : MapOptions::Normals::flat;
    opt.indices.n_part = 1.0001 + 1.9999 * u(rng);
    const Part& part = k % 2 ? dome : band;
    const std::string what = "pose " + std::to_string(k);
    try {
      const RefractionMap map = compute_refraction_map(part.scene(), cam, cam_from_part, opt);
      expect_sane(map, what);
      for (PixelStatus s : map.status) ++by_status[static_cast<int>(s)];
      rays += map.stats.traced;
    } catch (const PoseError&) {
      ++pose_errors;
    }
    if (HasFatalFailure()) return;
  }
  std::printf("  %lld rays traced, %lld poses refused (the part behind the camera)\n", rays, pose_errors);
  for (int k = 0; k < kPixelStatusCount; ++k)
    if (by_status[k]) std::printf("  %-16s %lld\n", to_string(static_cast<PixelStatus>(k)), by_status[k]);
  EXPECT_GT(by_status[0], 0);
  EXPECT_LT(pose_errors, poses / 2);
}
