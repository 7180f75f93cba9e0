// Ray index: every backend against closed forms (sphere, box planes), against
// each other (brute force is the reference), watertightness on closed meshes
// with rays aimed exactly at vertices and edges, t ranges, degenerate faces.
// Ray counts scale with CLEARFIT_RAY_TEST_SCALE (default 1, 0.1 under ASan).
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>
#include <set>

namespace clearfit {
namespace {

constexpr std::uint64_t kSeed = 20261122;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kUnitRoundoff = 0x1p-53;

double test_scale() {
  double s = 1;
#if defined(__SANITIZE_ADDRESS__)
  s = 0.1;
#endif
  if (const char* e = std::getenv("CLEARFIT_RAY_TEST_SCALE")) s = std::atof(e);
  return s;
}
int scaled(int n) { return std::max(16, static_cast<int>(n * test_scale())); }

std::mt19937_64 seeded(const char* what, std::uint64_t salt = 0) {
  std::cout << "[ seed ] " << what << ": " << kSeed + salt << "\n";
  return std::mt19937_64(kSeed + salt);
}
double uniform(std::mt19937_64& rng, double lo = 0, double hi = 1) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}
Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  for (;;) {
    Vec3 v(n(rng), n(rng), n(rng));
    if (v.norm() > 1e-3) return v.normalized();
  }
}
Mesh transformed(Mesh m, double scale, const Eigen::Matrix3d& rotation, const Vec3& offset) {
  for (Vec3& v : m.vertices) v = rotation * (scale * v) + offset;
  return m;
}
Eigen::Matrix3d some_rotation() {
  return Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
}
std::vector<RayHit> cast(const RayIndex& index, const std::vector<Ray>& rays) {
  std::vector<RayHit> hits(rays.size());
  index.intersect(rays, hits);
  return hits;
}
int group_of(const Mesh& m, const std::string& name) {
  return static_cast<int>(std::find(m.groups.begin(), m.groups.end(), name) - m.groups.begin());
}

class Backends : public ::testing::TestWithParam<RayBackend> {};
INSTANTIATE_TEST_SUITE_P(All, Backends,
                         ::testing::Values(RayBackend::embree, RayBackend::cgal_aabb, RayBackend::brute_force),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(RayIndex, BackendNames) {
  EXPECT_EQ(to_string(RayBackend::embree), "embree");
  EXPECT_EQ(to_string(RayBackend::cgal_aabb), "cgal_aabb");
  EXPECT_EQ(to_string(RayBackend::brute_force), "brute_force");
  const Mesh m = shapes::box(Vec3(1, 1, 1));
  for (RayBackend b : {RayBackend::embree, RayBackend::cgal_aabb, RayBackend::brute_force})
    EXPECT_EQ(make_ray_index(m, b)->backend(), b);
  EXPECT_EQ(make_ray_index(m)->backend(), RayBackend::embree);  // the default
}

// Icosphere of radius R: each hit is checked against the exact plane of its
// face (a formula independent of the index's), and against the analytic
// sphere, whose gap must shrink ~4x per subdivision (sagitta ~ h²).
TEST_P(Backends, IcosphereMatchesPlaneAndSphere) {
  const double R = 10;
  auto rng = seeded("IcosphereMatchesPlaneAndSphere");
  const int n = scaled(GetParam() == RayBackend::brute_force ? 500 : 2000);
  double previous_gap = 0, previous_normal_error = 0;
  for (int s = 1; s <= 5; ++s) {
    const Mesh m = shapes::icosphere(R, s);
    const auto index = make_ray_index(m, GetParam());
    double inradius = R;
    for (int f = 0; f < m.num_faces(); ++f) inradius = std::min(inradius, m.face_normal(f).dot(m.corner(f, 0)));
    std::vector<Ray> rays(n);
    for (Ray& r : rays) {
      r.origin = 3 * R * random_unit(rng);
      const Vec3 target = 0.7 * R * std::cbrt(uniform(rng)) * random_unit(rng);
      r.direction = (target - r.origin) * uniform(rng, 0.1, 10);
    }
    const auto hits = cast(*index, rays);
    double gap = 0, normal_error = 0;
    for (int i = 0; i < n; ++i) {
      const Ray& r = rays[i];
      const RayHit& h = hits[i];
      ASSERT_TRUE(h) << "ray " << i << " at subdivision " << s;
      const Vec3 a = m.corner(h.face, 0), b = m.corner(h.face, 1), c = m.corner(h.face, 2);
      const Vec3 n_face = (b - a).cross(c - a);
      const double t_plane = n_face.dot(a - r.origin) / n_face.dot(r.direction);
      EXPECT_NEAR(h.t, t_plane, 1e-13 * t_plane);
      EXPECT_LT((h.point - (h.bary[0] * a + h.bary[1] * b + h.bary[2] * c)).norm(), 1e-12 * R);
      EXPECT_NEAR(h.bary[0] + h.bary[1] + h.bary[2], 1.0, 1e-14);
      EXPECT_GE(std::min({h.bary[0], h.bary[1], h.bary[2]}), 0.0);
      EXPECT_LT((h.geometric_normal - n_face.normalized()).norm(), 1e-14);
      EXPECT_GT(h.geometric_normal.dot(h.point), 0);  // outward
      EXPECT_TRUE(h.front_facing);
      EXPECT_NEAR(h.shading_normal.norm(), 1.0, 1e-12);
      // Analytic sphere: nearer root of |o + t d|² = R²; the polyhedron lies inside.
      const double A = r.direction.squaredNorm(), B = r.origin.dot(r.direction), C = r.origin.squaredNorm() - R * R;
      const double t_sphere = (-B - std::sqrt(B * B - A * C)) / A;
      EXPECT_GE(h.t, t_sphere * (1 - 1e-14));
      EXPECT_GE(h.point.norm(), inradius * (1 - 1e-14));
      EXPECT_LE(h.point.norm(), R * (1 + 1e-14));
      gap += (h.t - t_sphere) * std::sqrt(A) / n;
      normal_error += std::acos(std::min(1.0, h.shading_normal.dot(h.point.normalized()))) / n;
    }
    std::cout << "subdivision " << s << ": mean gap to sphere " << gap << " mm, mean shading-normal error "
              << normal_error << " rad\n";
    if (s > 1) {
      EXPECT_GT(previous_gap / gap, 3.0) << "subdivision " << s;
      EXPECT_LT(previous_gap / gap, 5.5) << "subdivision " << s;
    }
    // Subdivision 1 is symmetric enough for exactly radial vertex normals
    // (interpolated: exactly radial); from 2 on they converge.
    if (s > 2) {
      EXPECT_GT(previous_normal_error / normal_error, 1.5) << "subdivision " << s;
    }
    previous_gap = gap, previous_normal_error = normal_error;
  }
}

// Box: the entry face, t and normal against the slab method.
TEST_P(Backends, BoxMatchesSlabMethod) {
  const Vec3 size(4, 6, 10);
  const Mesh m = shapes::box(size, 3);
  const auto index = make_ray_index(m, GetParam());
  auto rng = seeded("BoxMatchesSlabMethod");
  const int n = scaled(2000);
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    r.origin = 20 * random_unit(rng);
    const Vec3 target(uniform(rng, -1.9, 1.9), uniform(rng, -2.9, 2.9), uniform(rng, -4.9, 4.9));
    r.direction = target - r.origin;
  }
  const auto hits = cast(*index, rays);
  const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"bottom", "top"}};
  for (int i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    double t_entry = -kInf;
    int axis = -1;
    for (int k = 0; k < 3; ++k) {
      const double t0 = (-size[k] / 2 - r.origin[k]) / r.direction[k], t1 = (size[k] / 2 - r.origin[k]) / r.direction[k];
      if (std::min(t0, t1) > t_entry) t_entry = std::min(t0, t1), axis = k;
    }
    const int side = r.direction[axis] < 0;
    ASSERT_TRUE(hits[i]) << "ray " << i;
    EXPECT_NEAR(hits[i].t, t_entry, 1e-14 * t_entry) << "ray " << i;
    EXPECT_EQ(m.face_group[hits[i].face], group_of(m, names[axis][side])) << "ray " << i;
    Vec3 normal = Vec3::Zero();
    normal[axis] = side ? 1 : -1;
    EXPECT_LT((hits[i].geometric_normal - normal).norm(), 1e-15);
    EXPECT_LT((hits[i].shading_normal - normal).norm(), 1e-12);  // box sides are creased
  }
}

// A non-convex bumpy sphere far from the origin; random rays from inside and
// outside with random t ranges. Brute force is the reference.
TEST(RayIndex, BackendsAgree) {
  Mesh m = shapes::icosphere(20, 4);
  for (Vec3& v : m.vertices) v *= 1 + 0.15 * std::sin(3 * v.x() / 20) * std::sin(2 * v.y() / 20 + 1) * std::cos(v.z() / 20);
  const Vec3 offset(1000, -500, 200);
  m = transformed(std::move(m), 1.0, some_rotation(), offset);
  auto rng = seeded("BackendsAgree");
  const int n = scaled(5000);
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    r.origin = offset + 40 * uniform(rng) * random_unit(rng);
    r.direction = random_unit(rng) * uniform(rng, 0.01, 100);
    const double scale = 40 / r.direction.norm();
    if (uniform(rng) < 0.3) r.t_min = uniform(rng, -1, 1) * scale;
    if (uniform(rng) < 0.3) r.t_max = r.t_min + uniform(rng, 0, 2) * scale;
  }
  const auto ref = cast(*make_ray_index(m, RayBackend::brute_force), rays);
  int hits = 0;
  for (RayBackend b : {RayBackend::embree, RayBackend::cgal_aabb}) {
    const auto got = cast(*make_ray_index(m, b), rays);
    hits = 0;
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(bool(got[i]), bool(ref[i])) << to_string(b) << " ray " << i;
      if (!ref[i]) continue;
      ++hits;
      EXPECT_EQ(got[i].face, ref[i].face) << to_string(b) << " ray " << i;
      EXPECT_NEAR(got[i].t, ref[i].t, 1e-9 * std::abs(ref[i].t)) << to_string(b) << " ray " << i;
      EXPECT_GE(got[i].t, rays[i].t_min);
      EXPECT_LE(got[i].t, rays[i].t_max);
      EXPECT_LT((got[i].point - ref[i].point).norm(), 1e-9);
    }
  }
  std::cout << n << " rays, " << hits << " hits\n";
  EXPECT_GT(hits, n / 3);
  EXPECT_LT(hits, n);
}

// Watertightness. Rays come from outside a closed convex mesh and aim exactly
// (to double rounding) at a vertex, an edge midpoint, a random point of an
// edge or a point inside a face, from a side that enters the solid. Each must
// hit at the target (no leak), front-facing; re-cast past that hit it must
// leave once, back-facing (no double hit at the entry); re-cast past the exit
// it must miss.
//
// Offset rule (an error bound, not a tuned epsilon): the watertight test on
// face g evaluates about 16 rounded operations on numbers no larger than
// M_g = max_i |v_i - origin|, so its intersection point lies within
// 16·u·M_g of g's plane (u = 2^-53), i.e. within 16·u·M_g / |n̂_g·d| of the
// exact t. Every face through the hit point (those around the target vertex
// or edge) meets the ray at the same exact t, so re-casting with
// t_min = t + 2·max_g 16·u·M_g / |n̂_g·d| clears all of them (the 2: the hit's
// own t carries the same error).
double offset_bound(const Mesh& m, const Ray& r, const std::vector<int>& faces) {
  double bound = 0;
  for (int g : faces) {
    double M = 0;
    for (int k = 0; k < 3; ++k) M = std::max(M, (m.corner(g, k) - r.origin).norm());
    bound = std::max(bound, 2 * 16 * kUnitRoundoff * M / std::abs(m.face_normal(g).dot(r.direction)));
  }
  return bound;
}

// The entry t is checked against 1/k (d = (target - origin)·k) with the
// offset bound plus the rounding of the target itself (a vertex, or a point
// interpolated on an edge or face: a few roundings of coordinates as large as
// |target|) and of the origin/direction: 4u·(|target| + |origin|) along the normal.
double entry_tolerance(const Mesh& m, const Ray& r, const std::vector<int>& faces, double target_norm) {
  double tol = 0;
  for (int g : faces)
    tol = std::max(tol, offset_bound(m, r, {g}) + 4 * kUnitRoundoff * (target_norm + r.origin.norm()) /
                                                      std::abs(m.face_normal(g).dot(r.direction)));
  return tol;
}

struct WatertightCase {
  std::string name;
  Mesh mesh;
};

std::vector<WatertightCase> watertight_meshes() {
  std::vector<WatertightCase> cases;
  cases.push_back({"box exact coordinates", shapes::box(Vec3(2, 3, 5), 4)});
  cases.push_back({"icosphere r=25mm rotated, offset", transformed(shapes::icosphere(1, 3), 25, some_rotation(), Vec3(3.7, -12.1, 0.4))});
  cases.push_back({"icosphere r=1um at 1 mm", transformed(shapes::icosphere(1, 3), 1e-3, some_rotation(), Vec3(1, 0.5, 0))});
  cases.push_back({"icosphere r=1m at 2 m", transformed(shapes::icosphere(1, 3), 1e3, some_rotation(), Vec3(-2e3, 1e3, 0))});
  return cases;
}

TEST_P(Backends, WatertightAtVerticesAndEdges) {
  // Embree: 200k rays (3 casts each; ~1 s on the shared 2-core machine), to
  // keep the suite within seconds. CLEARFIT_RAY_TEST_SCALE=5 runs the 1M the
  // issue asks for (passed: 0 leaks, 0 double hits; 5-6 s). CGAL and brute force fewer.
  const int total = scaled(GetParam() == RayBackend::embree ? 200'000 : GetParam() == RayBackend::cgal_aabb ? 50'000 : 20'000);
  const auto cases = watertight_meshes();
  const char* kinds[4] = {"vertex", "edge midpoint", "point on edge", "point in face"};
  double cast_seconds = 0;
  for (size_t c = 0; c < cases.size(); ++c) {
    const Mesh& m = cases[c].mesh;
    const auto [lo, hi] = bounding_box(m);
    const double size = (hi - lo).norm();
    std::vector<std::vector<int>> around(m.vertices.size());
    for (int f = 0; f < m.num_faces(); ++f)
      for (int v : m.faces[f]) around[v].push_back(f);
    auto rng = seeded(cases[c].name.c_str(), c);
    const int n = total / static_cast<int>(cases.size());
    std::vector<Ray> rays;
    std::vector<std::vector<int>> through;  // faces through each ray's target
    std::vector<int> kind;
    std::vector<double> t_target;  // the ray passes its target at t = 1/k
    rays.reserve(n), through.reserve(n), kind.reserve(n), t_target.reserve(n);
    std::uniform_int_distribution<int> pick_face(0, m.num_faces() - 1), pick_corner(0, 2);
    while (static_cast<int>(rays.size()) < n) {
      const int f = pick_face(rng), k = pick_corner(rng), kd = static_cast<int>(rays.size() % 4);
      const int a = m.faces[f][k], b = m.faces[f][(k + 1) % 3];
      Vec3 target;
      std::vector<int> faces;
      if (kd == 0) {
        target = m.vertices[a], faces = around[a];
      } else if (kd == 3) {
        double w1 = uniform(rng), w2 = uniform(rng);
        if (w1 + w2 > 1) w1 = 1 - w1, w2 = 1 - w2;
        target = m.corner(f, 0) + w1 * (m.corner(f, 1) - m.corner(f, 0)) + w2 * (m.corner(f, 2) - m.corner(f, 0));
        faces = {f};
      } else {
        target = kd == 1 ? Vec3(0.5 * (m.vertices[a] + m.vertices[b]))
                         : Vec3(m.vertices[a] + uniform(rng) * (m.vertices[b] - m.vertices[a]));
        for (int g : around[a])
          if (std::count(m.faces[g].begin(), m.faces[g].end(), b)) faces.push_back(g);
      }
      Vec3 u;  // a direction from which the ray enters through every face at the target
      int tries = 0;
      do u = random_unit(rng);
      while (++tries < 200 && std::any_of(faces.begin(), faces.end(), [&](int g) { return m.face_normal(g).dot(u) < 0.2; }));
      if (tries == 200) continue;
      Ray r;
      r.origin = target + uniform(rng, 1, 3) * size * u;
      const double k_scale = uniform(rng, 0.25, 4);
      r.direction = (target - r.origin) * k_scale;
      rays.push_back(r), through.push_back(std::move(faces)), kind.push_back(kd), t_target.push_back(1 / k_scale);
    }
    const auto index = make_ray_index(m, GetParam());
    const auto start = std::chrono::steady_clock::now();
    const auto entry = cast(*index, rays);
    std::vector<Ray> again = rays;
    for (int i = 0; i < n; ++i) {
      std::vector<int> faces = through[i];
      if (entry[i]) faces.push_back(entry[i].face);
      again[i].t_min = entry[i] ? entry[i].t + offset_bound(m, rays[i], faces) : kInf;
    }
    const auto exit = cast(*index, again);
    for (int i = 0; i < n; ++i) {
      std::vector<int> faces;
      if (exit[i])
        for (int v : m.faces[exit[i].face]) faces.insert(faces.end(), around[v].begin(), around[v].end());
      again[i].t_min = exit[i] ? exit[i].t + offset_bound(m, rays[i], faces) : kInf;
    }
    const auto beyond = cast(*index, again);
    cast_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    int leaks[4] = {}, wrong_entry[4] = {}, doubles[4] = {}, no_exit[4] = {}, extra[4] = {};
    for (int i = 0; i < n; ++i) {
      if (!entry[i]) { ++leaks[kind[i]]; continue; }
      std::vector<int> faces = through[i];
      faces.push_back(entry[i].face);
      if (!entry[i].front_facing || std::abs(entry[i].t - t_target[i]) > entry_tolerance(m, rays[i], faces, entry[i].point.norm()))
        ++wrong_entry[kind[i]];
      if (!exit[i]) ++no_exit[kind[i]];
      else if (exit[i].front_facing) ++doubles[kind[i]];
      if (beyond[i]) ++extra[kind[i]];
    }
    for (int k = 0; k < 4; ++k) {
      std::cout << cases[c].name << ", " << kinds[k] << ": leaks " << leaks[k] << ", wrong entry " << wrong_entry[k]
                << ", double hits " << doubles[k] << ", no exit " << no_exit[k] << ", extra hits " << extra[k] << "\n";
      EXPECT_EQ(leaks[k] + wrong_entry[k] + doubles[k] + no_exit[k] + extra[k], 0) << cases[c].name << ", " << kinds[k];
    }
  }
  std::cout << total << " rays x 3 casts (+ offset bounds) in " << cast_seconds << " s\n";
}

// Exact box coordinates: entry at t = 7.5 (top, z = 2.5), exit at t = 12.5.
TEST_P(Backends, TRangeIsRespected) {
  const Mesh m = shapes::box(Vec3(4, 4, 5), 1);
  const auto index = make_ray_index(m, GetParam());
  const Vec3 o(0.3, -0.7, 10), down(0, 0, -1);
  auto hit = [&](Vec3 origin, Vec3 d, double t_min, double t_max) { return index->intersect(Ray{origin, d, t_min, t_max}); };
  const int top = group_of(m, "top"), bottom = group_of(m, "bottom");
  RayHit h = hit(o, down, 0, kInf);
  ASSERT_TRUE(h);
  EXPECT_EQ(h.t, 7.5);
  EXPECT_EQ(m.face_group[h.face], top);
  EXPECT_TRUE(h.front_facing);
  EXPECT_EQ(hit(o, down, 0, 7.5).t, 7.5);
  EXPECT_FALSE(hit(o, down, 0, std::nextafter(7.5, 0.0)));
  EXPECT_EQ(hit(o, down, 7.5, kInf).t, 7.5);
  h = hit(o, down, std::nextafter(7.5, kInf), kInf);
  ASSERT_TRUE(h);
  EXPECT_EQ(h.t, 12.5);
  EXPECT_EQ(m.face_group[h.face], bottom);
  EXPECT_FALSE(h.front_facing);
  EXPECT_FALSE(hit(o, down, 12.5 + 1e-9, kInf));
  EXPECT_FALSE(hit(o, down, 9, 8));   // empty range
  EXPECT_FALSE(hit(o, down, kInf, kInf));
  EXPECT_EQ(hit(o, 4 * down, 0, kInf).t, 7.5 / 4);  // t in units of |direction|
  // From inside: forward to the top; with t_min < 0 the bottom behind the origin.
  const Vec3 inside(0.3, -0.7, 0), up(0, 0, 1);
  h = hit(inside, up, 0, kInf);
  EXPECT_EQ(h.t, 2.5);
  EXPECT_FALSE(h.front_facing);
  h = hit(inside, up, -10, kInf);
  EXPECT_EQ(h.t, -2.5);
  EXPECT_EQ(m.face_group[h.face], bottom);
  EXPECT_TRUE(h.front_facing);
  EXPECT_FALSE(hit(inside, up, -10, -3));
}

// Zero-area faces (a repeated vertex, three collinear vertices), a sliver of
// height 1e-12 between two proper faces, and a needle, hit by rays from all
// sides and by rays lying in their plane: no NaN anywhere, zero-area faces
// never reported, the sliver found as often as the brute-force loop finds it.
TEST_P(Backends, DegenerateAndSliverFacesGiveNoNaN) {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1e-12, 0}, {4, 0, 0}, {4, 1e-6, 0},
                {0, 3, 0}, {1, 3, 0}, {2, 3, 0}, {2.5, 1, 0}, {2.5, -1, 0}};
  // The sliver (3,4,5) is thinner than float resolution; faces 6 and 7 border it.
  m.faces = {{0, 1, 2}, {1, 1, 2}, {8, 9, 10}, {3, 4, 5}, {6, 4, 7}, {0, 2, 2}, {5, 4, 11}, {4, 3, 12}};
  m.file_face = {0, 1, 2, 3, 4, 5, 6, 7};
  const std::set<int> zero_area = {1, 2, 5};
  const auto index = make_ray_index(m, GetParam());
  auto rng = seeded("DegenerateAndSliverFacesGiveNoNaN");
  std::vector<Ray> rays(scaled(4000));
  for (size_t i = 0; i < rays.size(); ++i) {
    // Aim at the proper face, into the sliver, into the needle, or anywhere.
    const double x = uniform(rng), y = uniform(rng);
    const Vec3 target = i % 8 < 2   ? Vec3(x, y * (1 - x), 0)
                        : i % 8 < 4 ? Vec3(2 + x, 1e-12 * y * (1 - x), 0)
                        : i % 8 < 6 ? Vec3(3 + x, 1e-6 * y * x, 0)
                                    : Vec3(uniform(rng, -0.5, 4.5), uniform(rng, -0.5, 3.5), 0);
    Vec3 d = random_unit(rng);
    if (i % 2) d.z() = 0, d.normalize();  // in the plane of every face
    if (i % 7 == 0) d = Vec3(1, 0, 0), rays[i].origin = Vec3(-1, 0, 0);  // along the x axis edges
    else rays[i].origin = target - 2 * d;
    rays[i].direction = d;
  }
  const auto hits = cast(*index, rays);
  int n_hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const RayHit& h = hits[i];
    if (!h) continue;
    ++n_hits;
    EXPECT_FALSE(zero_area.count(h.face)) << "ray " << i;
    EXPECT_TRUE(std::isfinite(h.t) && h.point.allFinite() && h.geometric_normal.allFinite() &&
                h.shading_normal.allFinite()) << "ray " << i;
    for (double b : h.bary) EXPECT_TRUE(b >= 0 && b <= 1) << "ray " << i;
    EXPECT_NEAR(h.geometric_normal.norm(), 1.0, 1e-12);
  }
  EXPECT_GT(n_hits, static_cast<int>(rays.size()) / 5);
  // Ray by ray against brute force (double precision on every face). Where both hit, the same t and point; a
  // different face only on an edge both faces share, with the point on it (a tie: at scale 10 Embree gave face 7
  // where brute force gave the sliver 3 on their edge y = 0 for 2 of 40000 rays, the same point to 2e-16).
  // Embree alone may miss the needle (face 4, 1e-6 mm across at 1 to 4 mm: 3.5e-7 of the bounding radius R):
  // its float ray lies off the double one by a few 2^-24·R, so a face thinner than that can slip past the
  // float BVH (ray_index_embree.cpp, "Precision"); brute force and CGAL hit it. Measured: 84 of the 500 rays
  // aimed at the needle missed at scale 1, 766 of 5000 at scale 10; nothing else is missed or added.
  const auto ref = cast(*make_ray_index(m, RayBackend::brute_force), rays);
  int needle_missed = 0, sliver = 0, ties = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const RayHit &h = hits[i], &r = ref[i];
    sliver += r.face == 3;
    if (!h && r && r.face == 4 && GetParam() == RayBackend::embree) {
      ++needle_missed;
      continue;
    }
    ASSERT_EQ(bool(h), bool(r)) << "ray " << i << ": face " << h.face << ", brute force " << r.face;
    if (!r) continue;
    EXPECT_NEAR(h.t, r.t, 1e-12 * r.t) << "ray " << i;
    EXPECT_LT((h.point - r.point).norm(), 1e-12) << "ray " << i;
    if (h.face == r.face) continue;
    ++ties;
    std::vector<int> shared;
    for (int a : m.faces[h.face])
      if (std::count(m.faces[r.face].begin(), m.faces[r.face].end(), a)) shared.push_back(a);
    ASSERT_EQ(shared.size(), 2u) << "ray " << i << ": faces " << h.face << " and " << r.face << " share no edge";
    const Vec3 a = m.vertices[shared[0]], e = m.vertices[shared[1]] - a;
    EXPECT_LT((r.point - a).cross(e).norm() / e.norm(), 1e-12) << "ray " << i << ": off the shared edge";
  }
  std::cout << to_string(GetParam()) << ": " << rays.size() << " rays, " << sliver << " on the sliver (brute force), " << ties
            << " ties on a shared edge, " << needle_missed << " missed on the needle\n";
  EXPECT_GT(sliver, 0);
  EXPECT_LT(needle_missed, static_cast<int>(rays.size()) / 8 / 4);  // under a quarter of the 1 in 8 aimed at it off its plane
}

// A square split along its diagonal at a point computed on it (p = (a + b) / 2, on the line to rounding) leaves
// face 0 = (a, b, p) of zero area. A ray aimed exactly at the corner b (the sweep's ray 20871, coordinates as it
// had them) hits every face around b at t = 1 and, ties going to the lowest index, face 0, whose right-hand normal
// is zero: it must still be front-facing, with its corner normals (the neighbours' +z) as its geometric normal.
TEST_P(Backends, ZeroAreaFaceHitAtItsCornerTakesItsNeighboursNormal) {
  Mesh m;
  const Vec3 a(-6.6666666666666661, -6.6666666666666661, 3), b(6.6666666666666679, 6.6666666666666679, 3);
  m.vertices = {a, b, 0.5 * a + 0.5 * b, {6.6666666666666679, -6.6666666666666661, 3}, {-6.6666666666666661, 6.6666666666666679, 3}};
  m.faces = {{0, 1, 2}, {0, 3, 2}, {2, 3, 1}, {0, 1, 4}};
  m.file_face = {0, 1, 2, 3};
  ASSERT_LT(m.face_area(0), 1e-14);
  const auto index = make_ray_index(m, GetParam());
  const Ray r{{-0.52978105690134303, 1.5486800987381875, 13}, {7.1964477235680109, 5.1179865679284804, -10}};
  const RayHit h = index->intersect(r);
  ASSERT_TRUE(h);
  std::cout << to_string(GetParam()) << ": face " << h.face << " at t = " << h.t << "\n";
  EXPECT_NEAR(h.t, 1.0, 1e-14);
  EXPECT_LT((h.point - b).norm(), 1e-13);
  EXPECT_TRUE(h.front_facing) << "face " << h.face;
  EXPECT_LT((h.geometric_normal - Vec3(0, 0, 1)).norm(), 1e-12) << "face " << h.face << ": " << h.geometric_normal.transpose();
}

TEST_P(Backends, MissesReturnFaceMinusOne) {
  const Mesh m = shapes::icosphere(1, 2);
  const auto index = make_ray_index(m, GetParam());
  for (const Ray& r : {Ray{{0, 0, 5}, {0, 0, 1}}, Ray{{0, 0, 5}, {1, 0, 0}}, Ray{{2, 2, 2}, {1, -1, 0}}}) {
    const RayHit h = index->intersect(r);
    EXPECT_EQ(h.face, -1);
    EXPECT_FALSE(h);
    EXPECT_EQ(h.t, 0);
  }
  Mesh empty;
  const auto none = make_ray_index(empty, GetParam());
  EXPECT_FALSE(none->intersect(Ray{{0, 0, 5}, {0, 0, -1}}));
}

TEST_P(Backends, RejectsBadRaysAndNormals) {
  const Mesh m = shapes::icosphere(1, 1);
  const auto index = make_ray_index(m, GetParam());
  EXPECT_THROW(index->intersect(Ray{{0, 0, 5}, {0, 0, 0}}), std::invalid_argument);
  EXPECT_THROW(index->intersect(Ray{{NAN, 0, 5}, {0, 0, 1}}), std::invalid_argument);
  EXPECT_THROW(index->intersect(Ray{{0, 0, 5}, {0, 0, -1}, NAN}), std::invalid_argument);
  std::vector<Ray> rays(2);
  std::vector<RayHit> hits(1);
  EXPECT_THROW(index->intersect(rays, hits), std::invalid_argument);
  CornerNormals wrong;
  EXPECT_THROW(make_ray_index(m, GetParam(), &wrong), std::invalid_argument);
  // Caller-supplied normals are used as given.
  CornerNormals up;
  up.corner.assign(m.faces.size(), {Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(0, 0, 1)});
  EXPECT_EQ(make_ray_index(m, GetParam(), &up)->intersect(Ray{{0.1, 0.2, 5}, {0, 0, -1}}).shading_normal,
            Vec3(0, 0, 1));
}

}  // namespace
}  // namespace clearfit
