// The adaptive map keeps its promised error on parts nobody tuned on: random
// smooth height fields and random doubly curved shells
// (shapes::random_freeform, 30k triangles), each seed printed, at two
// resolutions, with and without a chart, against the exact trace of the same
// part. Promise checked with a chart (what clearfit map uses by default):
// p99 <= tolerance and max <= 3 x tolerance over the pixels valid in both
// maps. Without a chart (3D interpolation) max <= 3 x tolerance only: the
// interpolated points lie off the flat facets by up to their sag, which the
// checks cannot see (p99 up to 1.23 µm at 1 µm, on shell 58). Both: validity as the
// exact trace's but for slivers narrower than the node spacing, and fewer
// pixels traced.
//
// The criterion was tuned on seeds 1-5. Seeds 23-96 were fixed before they
// were run; their first run showed a fold on shell 58 that the checks of a
// child cell missed (max 4.4 µm), which the parent-error rule
// (kTrustedParent) answers. Seeds 311-409 were run once, after it, and never
// tuned on. CLEARFIT_TOLERANCE_SEEDS=a,b,... runs other seeds (kinds
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

std::vector<unsigned> seeds() {
  std::vector<unsigned> out;
  if (const char* s = std::getenv("CLEARFIT_TOLERANCE_SEEDS")) {
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) out.push_back(static_cast<unsigned>(std::stoul(item)));
    return out;
  }
  return {23, 58, 71, 96, 311, 342, 377, 409};  // not tuned on (tuning: 1-5; see the top)
}

double env_or(const char* name, double fallback) {
  const char* s = std::getenv(name);
  return s ? std::strtod(s, nullptr) : fallback;
}

}  // namespace

TEST(MapTolerance, AdaptiveKeepsItsToleranceOnRandomFreeformParts) {
  const int n = static_cast<int>(env_or("CLEARFIT_TOLERANCE_N", 86));  // 4n² + 8n triangles: 30.3k
  const double tol_um = env_or("CLEARFIT_TOLERANCE_UM", 1.0);
  std::printf("  %-12s %6s %9s %5s %7s %8s %8s %11s %7s %6s\n", "part", "seed", "size", "chart", "tol_um", "p99_um",
              "max_um", "at", "traced", "vdiff");
  const std::vector<unsigned> list = seeds();
  for (std::size_t k = 0; k < list.size(); ++k) {
    const auto kind = k % 2 ? shapes::Freeform::shell : shapes::Freeform::height_field;
    const unsigned seed = list[k];
    const Part part(shapes::random_freeform(kind, seed, n));
    for (const auto& [w, h] : {std::pair{320, 240}, std::pair{640, 480}}) {
      const CameraModel camera = bench::make_camera(w, h);  // the framing of `clearfit bench map`
      const Rigid3 pose = bench::frame_part(part.mesh, camera);
      for (const bool use_chart : {true, false}) {
        const TraceScene scene{&part.mesh, &part.contact, part.index.get(), use_chart ? &part.chart : nullptr};
        const RefractionMap exact = compute_refraction_map(scene, camera, pose);
        MapOptions opt;
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
        if (use_chart) {
          EXPECT_LE(e.p99_um, tol_um) << what;
        }
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
