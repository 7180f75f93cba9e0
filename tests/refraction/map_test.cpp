// The mesh-based refraction map against the exact closed forms of
// refraction/analytic.hpp (independent of any mesh) on the analytic parts.
#include <clearfit/error.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/analytic.hpp>
#include <clearfit/refraction/map.hpp>
#include <gtest/gtest.h>

#include "../support/outside_tools.hpp"
#include "../support/trace_part.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

using namespace clearfit;

namespace {

// A pinhole camera `height` mm above the part-frame origin, looking down -z:
// camera x = part x, camera y = -part y, camera z = -part z.
struct Rig {
  CameraModel camera;
  Rigid3 cam_from_part;
  Rig(int w, int h, double f, double height) {
    camera.lensmodel = "LENSMODEL_PINHOLE";
    camera.intrinsics = {f, f, (w - 1) / 2.0, (h - 1) / 2.0};
    camera.width = w;
    camera.height = h;
    cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    cam_from_part.translation = Vec3(0, 0, height);
  }
  Vec3 eye() const { return cam_from_part.inverse().translation; }
  Vec3 direction(int x, int y) const {
    return cam_from_part.rotation.transpose() * camera.unproject(Vec2(x, y)).normalized();
  }
};

using Part = test::TracePart;

struct Errors {
  std::vector<double> e;
  int both = 0, only_mesh = 0, only_exact = 0;
  double median() { std::sort(e.begin(), e.end()); return e.empty() ? NAN : e[e.size() / 2]; }
  double max() const { return e.empty() ? NAN : *std::max_element(e.begin(), e.end()); }
};

template <class Exact>
Errors compare(const RefractionMap& map, const Rig& rig, Exact exact) {
  Errors out;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const analytic::SkinHit ref = exact(rig.eye(), rig.direction(x, y));
      const bool mesh_ok = map.status[map.index(x, y)] == PixelStatus::valid;
      if (mesh_ok && ref.valid) {
        ++out.both;
        out.e.push_back((map.skin_point[map.index(x, y)] - ref.skin_point).norm());
      } else if (mesh_ok) {
        ++out.only_mesh;
      } else if (ref.valid) {
        ++out.only_exact;
      }
    }
  return out;
}

}  // namespace

TEST(RefractionMap, FlatSlabMatchesClosedFormTo1e9mm) {
  // A 400 x 400 x 3 mm plate seen from 60 mm; the camera's view stays inside
  // it, so the unbounded closed form applies to every pixel.
  Part part(shapes::slab(400, 400, 3, 4));
  for (double tilt_deg : {0.0, 10.0, 25.0}) {
    Rig rig(64, 48, 60, 60);
    const double a = tilt_deg * M_PI / 180;
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix();
    rig.cam_from_part.rotation = rig.cam_from_part.rotation * tilt.transpose();  // camera orbits about x
    rig.cam_from_part.translation = Vec3(0, 0, 60);
    MapOptions opt;
    RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, opt);
    Errors err = compare(map, rig, [&](const Vec3& o, const Vec3& d) { return analytic::trace_slab(o, d, 3.0, opt.indices); });
    EXPECT_EQ(err.both, 64 * 48) << tilt_deg;
    EXPECT_EQ(err.only_exact, 0) << tilt_deg;
    EXPECT_EQ(err.only_mesh, 0) << tilt_deg;
    EXPECT_LT(err.max(), 1e-9) << tilt_deg;
  }
}

TEST(RefractionMap, FlatSlabFastPathIsDetectedAndAgreesWithTheIndex) {
  Part part(shapes::slab(60, 40, 3, 8));
  // Seen from an angle so part of the view falls beside the plate: those rays
  // leave the closed form for the ray index.
  Rig rig(96, 64, 60, 70);
  rig.cam_from_part.translation = Vec3(10, 0, 70);
  MapOptions fast, slow;
  slow.fast_paths = false;
  const RefractionMap a = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, fast);
  const RefractionMap b = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, slow);
  EXPECT_EQ(a.stats.fast_path, "flat-slab");
  EXPECT_EQ(b.stats.fast_path, "none");
  EXPECT_GT(a.stats.by_status[int(PixelStatus::valid)], 1000);
  EXPECT_GT(a.stats.by_status[int(PixelStatus::miss)] + a.stats.by_status[int(PixelStatus::exits_elsewhere)], 0);
  for (std::size_t i = 0; i < a.status.size(); ++i) {
    ASSERT_EQ(a.status[i], b.status[i]) << "pixel " << i % 96 << "," << i / 96 << ": " << to_string(a.status[i]) << " vs " << to_string(b.status[i]);
    if (a.status[i] == PixelStatus::valid) {
      EXPECT_LT((a.skin_point[i] - b.skin_point[i]).norm(), 1e-12);
      EXPECT_EQ(a.face[i], b.face[i]);
    }
  }
  // Not a slab: one outer vertex lifted by a micrometre, or a curved band.
  Mesh bent = shapes::slab(60, 40, 3, 8);
  for (Vec3& v : bent.vertices)
    if (v.z() == 3 && v.x() == 0 && v.y() == 0) v.z() += 1e-3;
  Part other(std::move(bent));
  EXPECT_EQ(compute_refraction_map(other.scene(), rig.camera, rig.cam_from_part).stats.fast_path, "none");
}

TEST(RefractionMap, BandConvergesToTheExactCylinderWithSmoothNormals) {
  // Wristband segment, r_in 30, r_out 32.5, seen from 80 mm above its middle.
  const double r_in = 30, r_out = 32.5, span = 100, width = 24;
  Rig rig(160, 60, 150, 80 + r_out);
  double previous = 0;
  std::printf("  n_around  median_um  max_um  order\n");
  for (int n : {32, 64, 128, 256}) {
    Part part(shapes::cylindrical_shell(r_in, r_out, span, width, n, 4));
    RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
    Errors err = compare(map, rig, [&](const Vec3& o, const Vec3& d) {
      return analytic::trace_cylindrical_shell(o, d, r_in, r_out, span, width);
    });
    const double med = err.median();
    const double order = previous > 0 ? std::log2(previous / med) : NAN;
    std::printf("  %8d  %9.4f  %6.3f  %5.2f\n", n, med * 1e3, err.max() * 1e3, order);
    EXPECT_GT(err.both, 3000);
    EXPECT_EQ(err.only_exact, 0) << n;
    if (previous > 0) EXPECT_GT(order, 1.5) << n;  // about second order in the facet size
    previous = med;
  }
  EXPECT_LT(previous, 5e-4);  // < 0.5 µm median at 256 segments
}

TEST(RefractionMap, DomeConvergesToTheExactSphericalShell) {
  const double r_in = 25, r_out = 27, cap = 35;
  Rig rig(60, 60, 60, 70 + r_out);
  double previous = 0;
  for (int n : {16, 32, 64}) {
    Part part(shapes::spherical_shell(r_in, r_out, cap, n, 4 * n));
    RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
    Errors err = compare(map, rig, [&](const Vec3& o, const Vec3& d) {
      return analytic::trace_spherical_shell(o, d, r_in, r_out, cap);
    });
    const double med = err.median();
    if (previous > 0) EXPECT_GT(std::log2(previous / med), 1.5) << n;
    previous = med;
  }
}

TEST(RefractionMap, IndexMatchedRaysGoStraight) {
  Part part(shapes::slab(400, 400, 3, 2));
  Rig rig(32, 24, 30, 50);
  MapOptions opt;
  opt.indices.n_medium = opt.indices.n_part = 1.498;  // the study's oil and acrylic, matched
  RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, opt);
  EXPECT_EQ(map.stats.fast_path, "index-matched+flat-slab");
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      const Vec3 d = rig.direction(x, y), o = rig.eye();
      const Vec3 straight = o + (-o.z() / d.z()) * d;  // the z = 0 plane, no bending
      ASSERT_EQ(map.status[map.index(x, y)], PixelStatus::valid);
      EXPECT_LT((map.skin_point[map.index(x, y)] - straight).norm(), 1e-9);
    }
}

TEST(RefractionMap, EveryInvalidPixelHasAReason) {
  // The band seen from far enough that the view passes beside it: misses,
  // side-wall exits and valid pixels in one image.
  Part part(shapes::cylindrical_shell(30, 32.5, 100, 10, 64, 2));
  Rig rig(64, 48, 30, 120);
  RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
  long long total = 0;
  for (int s = 0; s < kPixelStatusCount; ++s) total += map.stats.by_status[s];
  EXPECT_EQ(total, 64 * 48);
  EXPECT_GT(map.stats.by_status[int(PixelStatus::valid)], 0);
  EXPECT_GT(map.stats.by_status[int(PixelStatus::miss)] + map.stats.by_status[int(PixelStatus::outside)], 0);
  for (std::size_t i = 0; i < map.status.size(); ++i) {
    const bool valid = map.status[i] == PixelStatus::valid;
    EXPECT_EQ(valid, map.skin_point[i].allFinite());
    if (valid) EXPECT_TRUE(std::isfinite(map.transmittance[i]) && map.transmittance[i] > 0 && map.transmittance[i] <= 1);
  }
}

TEST(RefractionMap, ContactSeenFirstAndBadPoses) {
  Part part(shapes::slab(40, 40, 3, 2));
  Rig below(16, 12, 20, 50);
  below.cam_from_part.rotation = Eigen::Vector3d(1, 1, 1).asDiagonal();  // camera under the part looking up
  below.cam_from_part.translation = Vec3(0, 0, 50);
  RefractionMap map = compute_refraction_map(part.scene(), below.camera, below.cam_from_part);
  EXPECT_EQ(map.stats.by_status[int(PixelStatus::contact_first)], 16 * 12);

  Rig behind(16, 12, 20, 50);
  behind.cam_from_part.translation = Vec3(0, 0, -50);  // part behind the camera
  EXPECT_THROW(compute_refraction_map(part.scene(), behind.camera, behind.cam_from_part), InputError);

  MapOptions bad;
  bad.indices.n_part = std::nan("");
  Rig rig(16, 12, 20, 50);
  EXPECT_THROW(compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, bad), std::invalid_argument);
  ContactSurface none = make_contact_surface(part.mesh, std::vector<char>(part.mesh.num_faces(), 0), "nothing");
  TraceScene s = part.scene();
  s.contact = &none;
  EXPECT_THROW(compute_refraction_map(s, rig.camera, rig.cam_from_part), InputError);
}

TEST(RefractionMap, NpyExportReadsBackWithNumPy) {
  Part part(shapes::slab(40, 40, 3, 2));
  Rig rig(8, 6, 10, 50);
  RefractionMap map = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
  const auto path = std::filesystem::temp_directory_path() / "clearfit_map_test.npy";
  write_skin_points_npy(map, path);
  CLEARFIT_REQUIRE_PYTHON("numpy", "python3-numpy");
  const std::string cmd = "/usr/bin/python3 -c \"import numpy as np; a = np.load('" + path.string() +
                          "'); print(a.shape, a.dtype, repr(float(a[5, 7, 0])), repr(float(a[5, 7, 2])))\"";
  FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  char buf[256] = {};
  ASSERT_NE(fgets(buf, sizeof buf, pipe), nullptr);
  pclose(pipe);
  const Vec3 p = map.skin_point[map.index(7, 5)];
  EXPECT_NE(std::string(buf).find("(6, 8, 3) float32"), std::string::npos) << buf;
  const float x = static_cast<float>(p.x());
  double parsed_x = 0, parsed_z = 1;
  std::sscanf(std::strstr(buf, "float32") + 8, "%lf %lf", &parsed_x, &parsed_z);
  EXPECT_EQ(static_cast<float>(parsed_x), x) << buf;
  EXPECT_EQ(parsed_z, 0.0) << buf;
}
