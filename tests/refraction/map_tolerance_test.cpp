// The adaptive map keeps its promised error on parts nobody tuned on: random
// smooth height fields and random doubly curved shells
// (shapes::random_freeform), each seed printed, at two resolutions, with and
// without a chart, against the exact trace of the same part and options.
// Promise: p99 <= tolerance and max <= 3 x tolerance over the pixels valid in
// both maps; validity as the exact trace's but for slivers narrower than the
// node spacing; fewer pixels traced. Four families: 30k-triangle parts seen
// from above (as `clearfit bench map` frames them), 6.7k-triangle parts (facets
// of 10-20 px, whose kinks a regular lattice of checks aliases with), flat
// normals (the map jumps at every facet edge) and oblique views (the part
// turned by 35 and 21 degrees).
//
// History, so that no seed below reads as untouched when it was not: the
// criterion was tuned on seeds 1-5. Seeds 23-96 were fixed before they were
// run; their first run showed a fold on shell 58 that the checks of a child
// cell missed (max 4.4 µm), which the parent-error rule (kTrustedParent)
// answers. Seeds 311-409 were run once, after it, and never tuned on. Then
// shell 58 at 6.7k triangles gave p99 1.46 µm with a chart (four checks on
// a lattice aliasing with the facets), answered by the drawn checks
// (quadtree.hpp kMaxChecks); flat normals gave 15 µm, answered by the
// entry-face rule; seeds 1-5 and 58 were rerun with both. Seeds 5101-5104,
// 6201-6202 and 7301-7304 were fixed after those fixes and before their first run.
// CLEARFIT_TOLERANCE_SEEDS=a,b,... runs other seeds in every family (kinds
// alternate: height field, shell, ...), CLEARFIT_TOLERANCE_N other meshes
// (quads per edge), CLEARFIT_TOLERANCE_UM another tolerance.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map.hpp>
#include <gtest/gtest.h>

#include "../../bench/map_scenes.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>

using namespace clearfit;

namespace {

struct Part {
  Mesh mesh;
  ContactSurface contact;
  std::unique_ptr<RayIndex> index;
  Chart chart;
  explicit Part(Mesh m) : mesh(std::move(m)) {
    ContactSelector s;
    s.group = "contact";
    contact = select_contact(mesh, s);
    index = make_ray_index(mesh);
    chart = compute_chart(mesh, contact);
  }
};

struct Errors {
  double p99_um = 0, max_um = 0;
  int max_x = -1, max_y = -1;
  long long compared = 0, validity_diff = 0;
};

Errors compare(const RefractionMap& approx, const RefractionMap& exact) {
  Errors e;
  std::vector<double> d;
  for (std::size_t i = 0; i < exact.status.size(); ++i) {
    const bool a = approx.status[i] == PixelStatus::valid, x = exact.status[i] == PixelStatus::valid;
    if (a != x) ++e.validity_diff;
    if (!a || !x) continue;
    const double um = (approx.skin_point[i] - exact.skin_point[i]).norm() * 1e3;
    d.push_back(um);
    if (um > e.max_um) {
      e.max_um = um;
      e.max_x = static_cast<int>(i % static_cast<std::size_t>(exact.width));
      e.max_y = static_cast<int>(i / static_cast<std::size_t>(exact.width));
    }
  }
  e.compared = static_cast<long long>(d.size());
  if (d.empty()) return e;
  std::sort(d.begin(), d.end());
  e.p99_um = d[static_cast<std::size_t>(0.99 * static_cast<double>(d.size() - 1))];
  return e;
}

std::vector<unsigned> seeds(std::vector<unsigned> fallback) {
  std::vector<unsigned> out;
  if (const char* s = std::getenv("CLEARFIT_TOLERANCE_SEEDS")) {
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) out.push_back(static_cast<unsigned>(std::stoul(item)));
    return out;
  }
  return fallback;
}

double env_or(const char* name, double fallback) {
  const char* s = std::getenv(name);
  return s ? std::strtod(s, nullptr) : fallback;
}

struct Family {
  std::vector<unsigned> seeds;
  int n = 86;  // quads per edge: 4n² + 8n triangles (86: 30.3k, 40: 6.7k)
  MapOptions::Normals normals = MapOptions::Normals::smooth;
  double tilt_deg = 0;  // the part turned about x by this, about y by 0.6 of it
};

// Runs every seed of `family` at 320x240 and 640x480, with and without a
// chart, and checks the promise against the exact map.
void check_family(const Family& family) {
  const int n = static_cast<int>(env_or("CLEARFIT_TOLERANCE_N", family.n));
  const double tol_um = env_or("CLEARFIT_TOLERANCE_UM", 1.0);
  const bool flat = family.normals == MapOptions::Normals::flat;
  std::printf("  %d quads per edge, %s normals, tilt %.0f deg\n", n, flat ? "flat" : "smooth", family.tilt_deg);
  std::printf("  %-12s %6s %9s %5s %7s %8s %8s %11s %7s %6s\n", "part", "seed", "size", "chart", "tol_um", "p99_um",
              "max_um", "at", "traced", "vdiff");
  const std::vector<unsigned> list = seeds(family.seeds);
  for (std::size_t k = 0; k < list.size(); ++k) {
    const auto kind = k % 2 ? shapes::Freeform::shell : shapes::Freeform::height_field;
    const unsigned seed = list[k];
    Mesh mesh = shapes::random_freeform(kind, seed, n);
    const double t = family.tilt_deg * M_PI / 180;
    const Eigen::Matrix3d turn =
        (Eigen::AngleAxisd(t, Vec3::UnitX()) * Eigen::AngleAxisd(0.6 * t, Vec3::UnitY())).toRotationMatrix();
    for (Vec3& v : mesh.vertices) v = turn * v;
    const Part part(std::move(mesh));
    for (const auto& [w, h] : {std::pair{320, 240}, std::pair{640, 480}}) {
      const CameraModel camera = bench::make_camera(w, h);  // the framing of `clearfit bench map`
      const Rigid3 pose = bench::frame_part(part.mesh, camera);
      for (const bool use_chart : {true, false}) {
        const TraceScene scene{&part.mesh, &part.contact, part.index.get(), use_chart ? &part.chart : nullptr};
        MapOptions opt;
        opt.normals = family.normals;
        const RefractionMap exact = compute_refraction_map(scene, camera, pose, opt);
        opt.mode = MapOptions::Mode::adaptive;
        opt.tolerance_um = tol_um;
        const RefractionMap approx = compute_refraction_map(scene, camera, pose, opt);
        const Errors e = compare(approx, exact);
        const std::string at = "(" + std::to_string(e.max_x) + "," + std::to_string(e.max_y) + ")";
        std::printf("  %-12s %6u %4dx%-4d %5s %7.2f %8.3f %8.3f %11s %6.1f%% %6lld\n", shapes::to_string(kind), seed, w, h,
                    use_chart ? "yes" : "no", tol_um, e.p99_um, e.max_um, at.c_str(),
                    100.0 * static_cast<double>(approx.stats.traced) / static_cast<double>(approx.stats.pixels),
                    e.validity_diff);
        const std::string what = std::string(shapes::to_string(kind)) + " seed " + std::to_string(seed) + " " +
                                 std::to_string(w) + "x" + std::to_string(h) + (use_chart ? " chart" : " 3D");
        ASSERT_GT(e.compared, w * h / 10) << what;  // the part fills the view
        EXPECT_LE(e.p99_um, tol_um) << what;
        EXPECT_LE(e.max_um, 3 * tol_um) << what;
        // A valid sliver narrower than the node spacing (4 px at the finest
        // level) inside an invalid region can be missed whatever the
        // criterion: a few pixels at most.
        EXPECT_LE(e.validity_diff, w * h / 2000) << what;
        EXPECT_LT(approx.stats.traced, exact.stats.traced) << what;
      }
    }
  }
}

}  // namespace

TEST(MapTolerance, AdaptiveKeepsItsToleranceOnRandomFreeformParts) {
  check_family({.seeds = {23, 58, 71, 96, 311, 342, 377, 409}});
}

TEST(MapTolerance, AdaptiveKeepsItsToleranceOnCoarselyFacetedParts) {
  check_family({.seeds = {5101, 5102, 5103, 5104}, .n = 40});
}

TEST(MapTolerance, AdaptiveKeepsItsToleranceWithFlatNormals) {
  check_family({.seeds = {6201, 6202}, .n = 24, .normals = MapOptions::Normals::flat});
}

TEST(MapTolerance, AdaptiveKeepsItsToleranceOnObliqueViews) {
  check_family({.seeds = {7301, 7302, 7303, 7304}, .tilt_deg = 35});
}
