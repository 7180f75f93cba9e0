// The grid and adaptive approximations against the exact trace.
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/map.hpp>
#include <gtest/gtest.h>

#include <algorithm>

using namespace clearfit;

namespace {
struct Scene {
  Mesh mesh;
  ContactSurface contact;
  std::unique_ptr<RayIndex> index;
  Chart chart;
  bool use_chart = true;
  CameraModel camera;
  Rigid3 cam_from_part;
  Scene(Mesh m, int w, int h, double f, double height) : mesh(std::move(m)) {
    ContactSelector s;
    s.group = "contact";
    contact = select_contact(mesh, s);
    index = make_ray_index(mesh);
    chart = compute_chart(mesh, contact);
    camera.lensmodel = "LENSMODEL_OPENCV8";
    camera.intrinsics = {f, f, (w - 1) / 2.0, (h - 1) / 2.0, -0.05, 0.01, 0.001, -0.0005, 0, 0, 0, 0};
    camera.width = w;
    camera.height = h;
    cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    cam_from_part.translation = Vec3(0, 0, height);
  }
  RefractionMap run(MapOptions opt) const {
    return compute_refraction_map({&mesh, &contact, index.get(), use_chart ? &chart : nullptr}, camera, cam_from_part, opt);
  }
};

struct Compared {
  std::vector<double> err_um;
  long long mismatched = 0;
  double p(double q) {
    if (err_um.empty()) return 0;
    std::sort(err_um.begin(), err_um.end());
    return err_um[static_cast<std::size_t>(q * (err_um.size() - 1))];
  }
};

MapOptions adaptive_at(double tolerance_um) {
  MapOptions opt;
  opt.mode = MapOptions::Mode::adaptive;
  opt.tolerance_um = tolerance_um;
  return opt;
}

Compared compare(const RefractionMap& approx, const RefractionMap& exact) {
  Compared c;
  for (std::size_t i = 0; i < exact.status.size(); ++i) {
    const bool a = approx.status[i] == PixelStatus::valid, e = exact.status[i] == PixelStatus::valid;
    if (a != e) ++c.mismatched;
    if (a && e) c.err_um.push_back((approx.skin_point[i] - exact.skin_point[i]).norm() * 1e3);
  }
  return c;
}
}  // namespace

TEST(MapModes, AdaptiveMeetsItsToleranceOnTheBand) {
  Scene band(shapes::cylindrical_shell(32, 34.5, 100, 40, 192, 16), 320, 240, 290, 80 + 34.5);
  MapOptions exact_opt;
  const RefractionMap exact = band.run(exact_opt);
  ASSERT_GT(exact.stats.by_status[0], 320 * 240 / 4);
  // At this coarse framing a pixel covers 0.3 mm of skin and the map's second
  // derivative is several µm per pixel², so 1 µm needs ~2-pixel cells; the
  // speed-up grows with resolution (see `clearfit-bench map`). Here: the
  // tolerance is honoured and a looser tolerance traces fewer pixels.
  std::printf("  tolerance_um  traced  interpolated  p50_um  p99_um  max_um  est_max_um  mismatched\n");
  long long previous_traced = exact.stats.traced + 1;
  for (double tol : {0.1, 1.0, 10.0, 30.0}) {
    MapOptions opt;
    opt.mode = MapOptions::Mode::adaptive;
    opt.tolerance_um = tol;
    const RefractionMap approx = band.run(opt);
    Compared c = compare(approx, exact);
    const double p50 = c.p(0.5), p99 = c.p(0.99), mx = c.p(1.0);
    std::printf("  %12.1f  %6lld  %12lld  %6.3f  %6.3f  %6.3f  %10.3f  %10lld\n", tol, approx.stats.traced,
                approx.stats.interpolated, p50, p99, mx, approx.stats.max_error_um, c.mismatched);
    EXPECT_LE(p99, 2 * tol) << tol;
    EXPECT_LE(approx.stats.max_error_um, tol) << tol;
    EXPECT_LT(c.mismatched, 320 * 240 / 200) << tol;   // < 0.5 % of pixels, at validity edges only
    EXPECT_LT(approx.stats.traced, previous_traced) << tol;
    previous_traced = approx.stats.traced;
    // 30 µm: about a quarter of the exact trace (nodes and eight checks per cell).
    if (tol >= 30.0) EXPECT_LT(approx.stats.traced, exact.stats.traced / 4) << tol;
  }
}

TEST(MapModes, GridErrorShrinksWithTheStep) {
  Scene dome(shapes::spherical_shell(25, 27.5, 40, 48, 192), 240, 240, 220, 70 + 27.5);
  const RefractionMap exact = dome.run({});
  // Bilinear interpolation errs as the cell size squared: 4x smaller cells,
  // ~16x smaller error (at least 6x asked).
  double previous = 1e9;
  for (int step : {32, 8, 2}) {
    MapOptions opt;
    opt.mode = MapOptions::Mode::grid;
    opt.grid_step = step;
    const RefractionMap approx = dome.run(opt);
    Compared c = compare(approx, exact);
    const double p99 = c.p(0.99);
    EXPECT_LT(p99 * 6, previous) << step;
    std::printf("  grid step %2d: p99 %.3f um\n", step, p99);
    previous = p99;
    EXPECT_EQ(approx.stats.by_status[0] + approx.stats.by_status[1] + approx.stats.by_status[2] +
                  approx.stats.by_status[7] + approx.stats.by_status[8],
              240 * 240 - approx.stats.by_status[4] - approx.stats.by_status[5] - approx.stats.by_status[3] -
                  approx.stats.by_status[6]);
  }
  EXPECT_LT(previous, 10.0);
}

TEST(MapModes, WithoutAChartInterpolationIsLimitedBySurfaceSag) {
  // Interpolating skin points in 3D cuts the chord of a curved surface: for a
  // cell L wide on a radius-r surface the error is about L²/(8r). The adaptive
  // mode must still honour its tolerance (by tracing more).
  Scene band(shapes::cylindrical_shell(32, 34.5, 100, 40, 192, 16), 320, 240, 290, 80 + 34.5);
  band.use_chart = false;
  const RefractionMap exact = band.run({});
  const RefractionMap approx = band.run(adaptive_at(1.0));
  Compared c = compare(approx, exact);
  EXPECT_LE(c.p(0.99), 2.0);
  EXPECT_LE(approx.stats.max_error_um, 1.0);
  EXPECT_TRUE(std::isnan(approx.chart_uv[approx.width * approx.height / 2].x()));
}

TEST(MapModes, FlatSlabIsInterpolatedAlmostEverywhere) {
  // A plane seen through a pinhole is a projective map: bilinear interpolation
  // errs only slightly, so adaptive accepts the largest cells.
  Scene slab(shapes::slab(400, 400, 3, 4), 256, 192, 240, 60);
  slab.camera.lensmodel = "LENSMODEL_PINHOLE";
  slab.camera.intrinsics.resize(4);
  const RefractionMap approx = slab.run(adaptive_at(1.0));
  const RefractionMap exact = slab.run({});
  Compared c = compare(approx, exact);
  EXPECT_EQ(c.mismatched, 0);
  EXPECT_LE(c.p(1.0), 2.0);
  EXPECT_LT(approx.stats.traced, exact.stats.traced / 20);
}

TEST(MapModes, BadOptionsNameTheField) {
  Scene slab(shapes::slab(40, 40, 3, 1), 16, 12, 15, 60);
  MapOptions opt;
  opt.mode = MapOptions::Mode::adaptive;
  opt.grid_step = 12;
  EXPECT_THROW(slab.run(opt), std::invalid_argument);
  opt.grid_step = 16;
  opt.tolerance_um = 0;
  try {
    slab.run(opt);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tolerance_um"), std::string::npos);
  }
}

// Cells that a validity boundary crosses go to the boundary resolver: it
// traces both sides of every such boundary and fits the valid pixels behind
// them. Validity must be the exact trace's at every pixel; an invalid reason
// may differ only where two reasons meet (the nearest node's, within 2 px),
// and not at all with exact_reasons. The pixels near a boundary must honour
// the tolerance like the rest.
void expect_pixel_exact_boundaries(Scene& scene, const char* name) {
  SCOPED_TRACE(name);
  for (int run = 0; run < 3; ++run) {
    const bool use_chart = run != 1, exact_reasons = run == 2;
    scene.use_chart = use_chart;
    const RefractionMap exact = scene.run({});
    MapOptions opt = adaptive_at(1.0);
    opt.exact_reasons = exact_reasons;
    const RefractionMap approx = scene.run(opt);
    long long validity_diff = 0, reason_diff = 0, reason_far = 0, reason_edges = 0, boundaries = 0;
    std::vector<double> near_um;
    const int W = exact.width, H = exact.height;
    // Valid pixels with an invalid one within 6 px (a square window): a
    // separable dilation of the invalid mask.
    std::vector<char> invalid(exact.status.size()), rows(exact.status.size()), near(exact.status.size());
    for (std::size_t p = 0; p < invalid.size(); ++p) invalid[p] = exact.status[p] != PixelStatus::valid;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (int d = -6; d <= 6 && !rows[exact.index(x, y)]; ++d)
          rows[exact.index(x, y)] = x + d >= 0 && x + d < W && invalid[exact.index(x + d, y)];
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (int d = -6; d <= 6 && !near[exact.index(x, y)]; ++d)
          near[exact.index(x, y)] = y + d >= 0 && y + d < H && rows[exact.index(x, y + d)];
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const std::size_t p = exact.index(x, y);
        validity_diff += (approx.status[p] == PixelStatus::valid) != !invalid[p];
        for (const std::size_t q : {p + 1, p + W})  // pairs of pixels invalid for different reasons
          if ((q == p + 1 ? x + 1 < W : y + 1 < H) && invalid[p] && invalid[q] && exact.status[p] != exact.status[q])
            ++reason_edges;
        if (invalid[p] && approx.status[p] != PixelStatus::valid && approx.status[p] != exact.status[p]) {
          ++reason_diff;
          bool seen = false;  // the exact trace gives that reason within 2 px
          for (int dy = -2; dy <= 2 && !seen; ++dy)
            for (int dx = -2; dx <= 2 && !seen; ++dx)
              seen = x + dx >= 0 && x + dx < W && y + dy >= 0 && y + dy < H &&
                     exact.status[exact.index(x + dx, y + dy)] == approx.status[p];
          reason_far += !seen;
        }
        if (x + 1 < W && exact.status[p] != exact.status[p + 1]) ++boundaries;
        if (near[p] && !invalid[p] && approx.status[p] == PixelStatus::valid)
          near_um.push_back((approx.skin_point[p] - exact.skin_point[p]).norm() * 1e3);
      }
    std::sort(near_um.begin(), near_um.end());
    ASSERT_GT(boundaries, 500);  // the rim of the dome and the edge of the contact cap cross many rows
    ASSERT_GT(near_um.size(), 2000u);
    const double p99 = near_um[near_um.size() * 99 / 100], mx = near_um.back();
    std::printf("  %s, chart %d, exact reasons %d: traced %lld of %lld, validity differs %lld, reason differs %lld "
                "(%lld more than 2 px from it), near-boundary p99 %.3f um, max %.3f um\n",
                name, use_chart, exact_reasons, approx.stats.traced, exact.stats.traced, validity_diff, reason_diff,
                reason_far, p99, mx);
    EXPECT_EQ(validity_diff, 0) << run;
    EXPECT_EQ(reason_far, 0) << run;
    EXPECT_LE(reason_diff, reason_edges) << run;  // about one pixel along each such boundary
    if (exact_reasons) EXPECT_EQ(reason_diff, 0);
    // The tolerance is checked at samples (four per cell, every known pixel of
    // a fit), so single pixels may exceed it a little; without a chart the
    // interpolation is in 3D and sags off the surface between samples (see
    // WithoutAChartInterpolationIsLimitedBySurfaceSag).
    EXPECT_LE(p99, use_chart ? 1.25 : 2.0) << run;
    EXPECT_LE(mx, 3.0) << run;
    EXPECT_LT(approx.stats.traced, exact.stats.traced / 2) << run;  // 4 checks at half the tolerance: 36 % on the bump plate at 640x480
  }
}

TEST(MapModes, AdaptiveBoundariesArePixelExact) {
  // The rim of a dome and the edge of its contact cap; a plate whose bumps
  // bend the edge of the contact region (where a fit from too few rows of
  // traced pixels once went 30 µm astray).
  Scene dome(shapes::spherical_shell(25, 27.5, 40, 64, 256), 640, 480, 560, 70 + 27.5);
  expect_pixel_exact_boundaries(dome, "dome");
  Scene bumps(shapes::bump_plate(60, 40, 3, 70, 12, 2.0, 7), 640, 480, 576, 64);
  expect_pixel_exact_boundaries(bumps, "bumps");
}
