// The inverse map (chart texel → camera pixel) against independent references:
// the exact pinhole projection of the chart point (index-matched slab), an
// image of a known function resampled by cv::remap (refractive slab), a
// hand-built forward map with a seam, and the visible contact area (band).
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <clearfit/error.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <opencv2/imgproc.hpp>

#include "../support/outside_tools.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

using namespace clearfit;

namespace {

// A pinhole camera `height` mm above the part-frame origin looking down -z,
// tilted by `tilt_deg` about the part x axis.
struct Rig {
  CameraModel camera;
  Rigid3 cam_from_part;
  Rig(int w, int h, double f, double height, double tilt_deg = 0) {
    camera.lensmodel = "LENSMODEL_PINHOLE";
    camera.intrinsics = {f, f, (w - 1) / 2.0, (h - 1) / 2.0};
    camera.width = w;
    camera.height = h;
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(tilt_deg * M_PI / 180, Vec3::UnitX()).toRotationMatrix();
    cam_from_part.rotation = Eigen::Matrix3d(Eigen::Vector3d(1, -1, -1).asDiagonal()) * tilt.transpose();
    cam_from_part.translation = Vec3(0, 0, height);
  }
};

struct Part {
  Mesh mesh;
  ContactSurface contact;
  std::unique_ptr<RayIndex> index;
  Chart chart;
  Part(Mesh m, ChartMethod method) : mesh(std::move(m)) {
    ContactSelector s;
    s.group = "contact";
    contact = select_contact(mesh, s);
    index = make_ray_index(mesh);
    ChartOptions co;
    co.method = method;
    chart = compute_chart(mesh, contact, co);
  }
  TraceScene scene() const { return {&mesh, &contact, index.get(), &chart}; }
};

cv::Mat as_mat(const InverseMap& m, const std::vector<float>& v) {
  return cv::Mat(m.height, m.width, CV_32F, const_cast<float*>(v.data()));
}

// The largest chart step between neighbouring valid pixels (mm per pixel).
double max_step_mm(const RefractionMap& f) {
  double worst = 0;
  for (int y = 0; y + 1 < f.height; ++y)
    for (int x = 0; x + 1 < f.width; ++x) {
      const std::size_t p = f.index(x, y);
      if (!f.chart_uv[p].allFinite()) continue;
      for (std::size_t q : {p + 1, p + static_cast<std::size_t>(f.width)})
        if (f.chart_uv[q].allFinite())
          worst = std::max(worst, double((f.chart_uv[q] - f.chart_uv[p]).norm()));
    }
  return worst;
}

// A forward map built by hand: chart_uv = A (x, y) + b, plus `jump` (mm, in u)
// for x >= jump_x.
RefractionMap affine_map(int w, int h, const Eigen::Matrix2d& A, const Vec2& b, int jump_x, double jump) {
  RefractionMap f;
  f.width = w;
  f.height = h;
  f.status.assign(w * h, PixelStatus::valid);
  f.face.assign(w * h, 0);
  f.chart_uv.resize(w * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      f.chart_uv[f.index(x, y)] = (A * Vec2(x, y) + b + Vec2(x >= jump_x ? jump : 0, 0)).cast<float>();
  return f;
}

}  // namespace

TEST(InverseMap, IndexMatchedSlabInvertsToTheProjection) {
  // n_medium = n_part: straight rays, the forward map is a homography; the
  // inverse of a texel is the pinhole projection of its chart point.
  Part part(shapes::slab(400, 400, 3, 4), ChartMethod::planar);
  Rig rig(160, 120, 500, 50, 20);
  MapOptions mo;
  mo.indices.n_medium = mo.indices.n_part = 1.498;
  const RefractionMap fwd = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part, mo);
  ASSERT_EQ(fwd.stats.by_status[0], 160 * 120);
  const InverseMap inv = compute_inverse_map(fwd);
  double worst = 0;
  long long missing = 0, outside = 0;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const Vec2 uv = inv.uv(i, j);
      const Vec3 point = part.chart.origin + uv.x() * part.chart.axis_u + uv.y() * part.chart.axis_v;
      const Vec2 px = rig.camera.project(rig.cam_from_part.apply(point));
      const bool inside = px.x() > 1e-3 && px.y() > 1e-3 && px.x() < 159 - 1e-3 && px.y() < 119 - 1e-3;
      const std::size_t q = inv.index(i, j);
      if (!inv.valid[q]) {
        missing += inside;
        EXPECT_EQ(inv.map_x[q], kInvalidPixel);
        continue;
      }
      outside += !inside && (px.x() < -1e-3 || px.y() < -1e-3 || px.x() > 159 + 1e-3 || px.y() > 119 + 1e-3);
      worst = std::max(worst, (px - Vec2(inv.map_x[q], inv.map_y[q])).norm());
    }
  std::printf(
      "  %d x %d texels, %lld valid, max |pixel - projection| %.2e px, uv round trip %.2e um, %.1f ms\n",
      inv.width, inv.height, inv.error.texels_valid, worst, inv.error.max_uv_um, inv.raster_ms);
  EXPECT_GT(inv.error.texels_valid, 50000);
  EXPECT_EQ(missing, 0);  // every chart point seen inside the image has its pixel
  EXPECT_EQ(outside, 0);
  EXPECT_LT(worst, 1e-3);  // bilinear patches of a homography at 0.1 mm/px; float storage ~1e-5
  EXPECT_LT(inv.error.max_uv_um, 0.01);
  EXPECT_LT(inv.error.max_px, 1e-3);
  EXPECT_EQ(inv.cells_rejected_step + inv.cells_rejected_fold, 0);
}

TEST(InverseMap, RefractiveSlabResamplesAKnownImage) {
  // Camera image whose value at a pixel is f(chart uv of the pixel); cv::remap
  // through the inverse map must give f(texel uv) up to bilinear interpolation
  // error (plus cv::remap's 1/32 px quantisation).
  Part part(shapes::slab(400, 400, 3, 4), ChartMethod::planar);
  for (double tilt : {0.0, 25.0}) {
    Rig rig(160, 120, 500, 50, tilt);
    const RefractionMap fwd = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
    ASSERT_EQ(fwd.stats.by_status[0], 160 * 120);
    auto f = [](double u, double v) { return std::sin(u / 3) + std::cos(v / 5); };
    cv::Mat image(fwd.height, fwd.width, CV_32F);
    for (int y = 0; y < fwd.height; ++y)
      for (int x = 0; x < fwd.width; ++x) {
        const Eigen::Vector2f uv = fwd.chart_uv[fwd.index(x, y)];
        image.at<float>(y, x) = static_cast<float>(f(uv.x(), uv.y()));
      }
    InverseMapOptions opt;  // explicit bounds: the seen chart area plus a 1 mm margin of invalid texels
    opt.uv_min = Vec2::Constant(INFINITY);
    opt.uv_max = Vec2::Constant(-INFINITY);
    for (const Eigen::Vector2f& uv : fwd.chart_uv) {
      opt.uv_min = opt.uv_min->cwiseMin(uv.cast<double>() - Vec2(1, 1));
      opt.uv_max = opt.uv_max->cwiseMax(uv.cast<double>() + Vec2(1, 1));
    }
    const InverseMap inv = compute_inverse_map(fwd, opt);
    cv::Mat texels;
    cv::remap(image, texels, as_mat(inv, inv.map_x), as_mat(inv, inv.map_y), cv::INTER_LINEAR,
              cv::BORDER_CONSTANT, cv::Scalar(1e6));
    // Exact bilinear (no quantisation) as a second reading.
    auto bilinear = [&](double px, double py) {
      const int x0 = std::min(int(px), fwd.width - 2), y0 = std::min(int(py), fwd.height - 2);
      const double fx = px - x0, fy = py - y0;
      return (1 - fx) * (1 - fy) * image.at<float>(y0, x0) + fx * (1 - fy) * image.at<float>(y0, x0 + 1) +
             (1 - fx) * fy * image.at<float>(y0 + 1, x0) + fx * fy * image.at<float>(y0 + 1, x0 + 1);
    };
    double worst_cv = 0, worst_exact = 0;
    for (int j = 0; j < inv.height; ++j)
      for (int i = 0; i < inv.width; ++i) {
        if (!inv.valid[inv.index(i, j)]) continue;
        const double ref = f(inv.uv(i, j).x(), inv.uv(i, j).y());
        worst_cv = std::max(worst_cv, std::abs(texels.at<float>(j, i) - ref));
        worst_exact = std::max(
            worst_exact, std::abs(bilinear(inv.map_x[inv.index(i, j)], inv.map_y[inv.index(i, j)]) - ref));
      }
    // Bounds with h = the largest pixel footprint (mm): |grad f| <= 0.39 / mm,
    // |f''| <= 1/9 / mm²; bilinear error <= (h² / 8)(|g_xx| + |g_yy|) per cell;
    // quantisation <= |grad g| · √2 / 64 px. Factor 2 for the map's own curvature.
    const double h = max_step_mm(fwd);
    const double bound_exact = 2 * (h * h / 8) * (2.0 / 9) + 1e-6;
    const double bound_cv = bound_exact + 0.39 * h * std::sqrt(2.0) / 64;
    std::printf(
        "  tilt %4.1f: h %.4f mm/px, %lld texels, max error exact bilinear %.2e (bound %.2e), cv::remap %.2e "
        "(bound %.2e)\n",
        tilt, h, inv.error.texels_valid, worst_exact, bound_exact, worst_cv, bound_cv);
    EXPECT_GT(inv.error.texels_valid, 50000);
    EXPECT_LT(worst_exact, bound_exact) << tilt;
    EXPECT_LT(worst_cv, bound_cv) << tilt;
    EXPECT_LT(inv.error.max_uv_um, 0.01) << tilt;
    // The −1 sentinel of invalid texels reads the border value, also for bicubic.
    cv::Mat cubic;
    cv::remap(image, cubic, as_mat(inv, inv.map_x), as_mat(inv, inv.map_y), cv::INTER_CUBIC,
              cv::BORDER_CONSTANT, cv::Scalar(1e6));
    long long invalid = 0, border_linear = 0, border_cubic = 0;
    for (int j = 0; j < inv.height; ++j)
      for (int i = 0; i < inv.width; ++i) {
        const bool valid = inv.valid[inv.index(i, j)];
        invalid += !valid;
        border_linear += texels.at<float>(j, i) == 1e6f;
        border_cubic += !valid && cubic.at<float>(j, i) == 1e6f;
      }
    EXPECT_GT(invalid, 1000) << tilt;
    EXPECT_EQ(border_linear, invalid) << tilt;
    EXPECT_EQ(border_cubic, invalid) << tilt;
  }
}

TEST(InverseMap, BandWithLscmChartRoundTripsAndCoversTheVisibleArea) {
  const double r_in = 30, r_out = 32.5;
  Part part(shapes::cylindrical_shell(r_in, r_out, 100, 24, 128, 8), ChartMethod::lscm);
  Rig rig(320, 240, 800, 80 + r_out);
  const RefractionMap fwd = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
  InverseMapOptions opt;
  opt.texel_mm = 0.05;
  const InverseMap inv = compute_inverse_map(fwd, opt, &part.contact);
  // Visible contact area: 3D area of the skin points over pixel cells with
  // four valid corners (two triangles each).
  double area = 0;
  for (int y = 0; y + 1 < fwd.height; ++y)
    for (int x = 0; x + 1 < fwd.width; ++x) {
      const Vec3 &a = fwd.skin_point[fwd.index(x, y)], &b = fwd.skin_point[fwd.index(x + 1, y)],
                 &c = fwd.skin_point[fwd.index(x, y + 1)], &d = fwd.skin_point[fwd.index(x + 1, y + 1)];
      if (a.allFinite() && b.allFinite() && c.allFinite() && d.allFinite())
        area += 0.5 * ((b - a).cross(d - a).norm() + (d - a).cross(c - a).norm());
    }
  const double texel_area = inv.error.texels_valid * opt.texel_mm * opt.texel_mm;
  std::printf(
      "  %d x %d texels, %lld valid (%.1f mm2) vs visible area %.1f mm2; chart area ratio %.4f..%.4f\n",
      inv.width, inv.height, inv.error.texels_valid, texel_area, area, part.chart.area_ratio_min,
      part.chart.area_ratio_max);
  std::printf(
      "  round trip: uv max %.2e um; pixel max %.2e, p99 %.2e, median %.2e px over %lld pixels; cells %lld "
      "used, "
      "%lld step, %lld fold; %.1f + %.1f ms\n",
      inv.error.max_uv_um, inv.error.max_px, inv.error.p99_px, inv.error.median_px, inv.error.pixels_checked,
      inv.cells_used, inv.cells_rejected_step, inv.cells_rejected_fold, inv.raster_ms, inv.error_ms);
  EXPECT_GT(area, 300);
  EXPECT_NEAR(texel_area / area, 1.0, 0.02);
  EXPECT_LT(inv.error.max_px, 0.1);
  EXPECT_LT(inv.error.max_uv_um, 0.05);  // float storage of pixel coordinates (~1e-5 px) at 0.1 mm/px
  EXPECT_GT(inv.error.pixels_checked, fwd.stats.by_status[0] * 9 / 10);
  EXPECT_EQ(inv.texels_overlap, 0);
}

TEST(InverseMap, SeamIsNotBridgedAndTheInverseIsExactForAnAffineMap) {
  // Hand-built forward map: affine in the pixel, with a 10 mm jump in u
  // between pixel columns 19 and 20 (two chart pieces side by side).
  Eigen::Matrix2d A;
  A << 0.1103, 0.0217, -0.0311, 0.0893;  // mm per pixel; no texel centre falls on a cell edge
  const Vec2 b(1.2345678, 5.6789012);
  const RefractionMap fwd = affine_map(40, 30, A, b, 20, 10.0);
  InverseMapOptions opt;
  opt.texel_mm = 0.02;
  const InverseMap inv = compute_inverse_map(fwd, opt);
  EXPECT_EQ(inv.cells_rejected_step, 29);  // the column of cells across the seam
  EXPECT_EQ(inv.cells_used, 38 * 29);
  // Reference: a texel is valid iff its affine pre-image lies in one of the
  // two pieces' pixel rectangles ([0,19] or [20,39] x [0,29]).
  const Eigen::Matrix2d Ai = A.inverse();
  long long expected = 0, mismatched = 0, edge = 0;
  double worst = 0;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const Vec2 uv = inv.uv(i, j);
      const Vec2 left = Ai * (uv - b), right = Ai * (uv - b - Vec2(10, 0));
      const double e = 1e-7;
      const bool in_left = left.x() >= -e && left.x() <= 19 + e && left.y() >= -e && left.y() <= 29 + e;
      const bool in_right =
          right.x() >= 20 - e && right.x() <= 39 + e && right.y() >= -e && right.y() <= 29 + e;
      const bool on_edge = [&] {  // within rounding of a piece's boundary: either answer is right
        for (const Vec2& p : {left, right})
          for (double d : {p.x(), p.x() - 19, p.x() - 20, p.x() - 39, p.y(), p.y() - 29})
            if (std::abs(d) < 1e-6) return true;
        return false;
      }();
      const bool valid = inv.valid[inv.index(i, j)];
      expected += in_left || in_right;
      edge += on_edge;
      if (valid != (in_left || in_right) && !on_edge) ++mismatched;
      if (valid)
        worst = std::max(
            worst,
            ((in_left ? left : right) - Vec2(inv.map_x[inv.index(i, j)], inv.map_y[inv.index(i, j)])).norm());
    }
  std::printf("  %lld texels valid, %lld expected (%lld on an edge), max error %.2e px\n",
              inv.error.texels_valid, expected, edge, worst);
  EXPECT_EQ(mismatched, 0);
  EXPECT_LT(worst, 1e-5);
  EXPECT_LT(inv.error.max_px, 1e-4);

  // Without the jump every cell is used; with 1 thread the result is identical.
  RefractionMap whole = affine_map(40, 30, A, b, 40, 0);
  const InverseMap many = compute_inverse_map(whole, opt);
  EXPECT_EQ(many.cells_rejected_step, 0);
  EXPECT_EQ(many.cells_used, 39 * 29);
  // Two contact components meeting between columns 19 and 20 without a jump
  // in the chart: only the component check sees the seam.
  ContactSurface two;
  two.components = 2;
  two.component = {0, 1};
  for (int y = 0; y < 30; ++y)
    for (int x = 20; x < 40; ++x) whole.face[whole.index(x, y)] = 1;
  const InverseMap split = compute_inverse_map(whole, opt, &two);
  EXPECT_EQ(split.cells_rejected_step, 29);
  whole.face[0] = 2;  // not a face of the contact surface
  EXPECT_THROW(compute_inverse_map(whole, opt, &two), std::invalid_argument);
  whole.face[0] = 0;
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const InverseMap single = compute_inverse_map(whole, opt);
  EXPECT_EQ(single.valid, many.valid);
  EXPECT_EQ(single.map_x, many.map_x);
  EXPECT_EQ(single.map_y, many.map_y);
}

TEST(InverseMap, FoldedAndDegenerateCellsAreSkipped) {
  // Every pixel of the right half maps onto one chart point: degenerate cells.
  Eigen::Matrix2d A;
  A << 0.1, 0, 0, 0.1;
  RefractionMap fwd = affine_map(20, 10, A, Vec2::Zero(), 20, 0);
  for (int y = 0; y < 10; ++y)
    for (int x = 12; x < 20; ++x) fwd.chart_uv[fwd.index(x, y)] = Eigen::Vector2f(5, 5);
  const InverseMap inv = compute_inverse_map(fwd);
  EXPECT_EQ(inv.cells_used, 11 * 9);
  EXPECT_EQ(inv.cells_rejected_fold + inv.cells_rejected_step, 8 * 9);
  for (std::size_t q = 0; q < inv.valid.size(); ++q)
    if (inv.valid[q]) {
      EXPECT_LE(inv.map_x[q], 11.0f);
    }
}

TEST(InverseMap, BadOptionsAndEmptyMaps) {
  EXPECT_NO_THROW(InverseMapOptions{}.validate());
  auto message = [](const InverseMapOptions& o) {
    try {
      o.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  for (double bad : {0.0, -1.0, std::nan(""), double(INFINITY)}) {
    InverseMapOptions o;
    o.texel_mm = bad;
    EXPECT_NE(message(o).find("texel_mm"), std::string::npos) << message(o);
  }
  InverseMapOptions o;
  o.max_step_ratio = 1;
  EXPECT_NE(message(o).find("max_step_ratio"), std::string::npos);
  o = {};
  o.uv_min = Vec2(0, 0);
  EXPECT_NE(message(o).find("uv_min"), std::string::npos);
  o.uv_max = Vec2(-1, 5);
  EXPECT_NE(message(o).find("uv_max"), std::string::npos);

  Eigen::Matrix2d A = Eigen::Matrix2d::Identity() * 0.1;
  RefractionMap none = affine_map(8, 6, A, Vec2::Zero(), 8, 0);
  std::fill(none.status.begin(), none.status.end(), PixelStatus::miss);
  EXPECT_THROW(compute_inverse_map(none), InputError);  // nothing seen, no bounds: no grid to speak of
  InverseMapOptions bounded;
  bounded.uv_min = Vec2(0, 0);
  bounded.uv_max = Vec2(1, 0.5);
  bounded.texel_mm = 0.1;
  const InverseMap empty = compute_inverse_map(none, bounded);  // with bounds: an all-invalid grid
  EXPECT_EQ(empty.width, 10);
  EXPECT_EQ(empty.height, 5);
  EXPECT_EQ(empty.error.texels_valid, 0);
  EXPECT_EQ(std::count(empty.valid.begin(), empty.valid.end(), 0), 50);

  RefractionMap no_chart = affine_map(8, 6, A, Vec2::Zero(), 8, 0);
  std::fill(no_chart.chart_uv.begin(), no_chart.chart_uv.end(), Eigen::Vector2f::Constant(NAN));
  EXPECT_THROW(compute_inverse_map(no_chart), std::invalid_argument);

  InverseMapOptions tiny;
  tiny.texel_mm = 1e-6;
  EXPECT_THROW(compute_inverse_map(affine_map(8, 6, A, Vec2::Zero(), 8, 0), tiny), InputError);
}

TEST(InverseMap, NpyExportReadsBackWithNumPy) {
  Eigen::Matrix2d A = Eigen::Matrix2d::Identity() * 0.1;
  InverseMapOptions opt;
  opt.uv_min = Vec2(-0.2, 0);  // a margin of invalid texels on the left
  opt.uv_max = Vec2(0.7, 0.5);
  opt.texel_mm = 0.1;
  const InverseMap inv = compute_inverse_map(affine_map(8, 6, A, Vec2::Zero(), 8, 0), opt);
  const auto path = std::filesystem::temp_directory_path() / "clearfit_inverse_map_test.npy";
  write_inverse_map_npy(inv, path);
  ASSERT_EQ(inv.width, 9);
  ASSERT_FALSE(inv.valid[inv.index(0, 2)]);
  ASSERT_TRUE(inv.valid[inv.index(5, 3)]);
  CLEARFIT_REQUIRE_PYTHON("numpy", "python3-numpy");
  const std::string cmd = "/usr/bin/python3 -c \"import numpy as np; a = np.load('" + path.string() +
                          "'); print(a.shape, a.dtype, bool(np.isnan(a[2, 0]).all()), repr(float(a[3, 5, "
                          "0])), repr(float(a[3, 5, 1])))\"";
  FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  char buf[256] = {};
  ASSERT_NE(fgets(buf, sizeof buf, pipe), nullptr);
  pclose(pipe);
  EXPECT_NE(std::string(buf).find("(5, 9, 2) float32 True"), std::string::npos) << buf;
  double x = 0, y = 0;
  std::sscanf(std::strstr(buf, "True") + 5, "%lf %lf", &x, &y);
  EXPECT_EQ(static_cast<float>(x), inv.map_x[inv.index(5, 3)]) << buf;
  EXPECT_EQ(static_cast<float>(y), inv.map_y[inv.index(5, 3)]) << buf;
  EXPECT_NEAR(x, 3.5, 1e-5);  // texel (5, 3): centre uv (-0.15 + 0.5, 0.05 + 0.3) = pixel (3.5, 3.5)
  EXPECT_NEAR(y, 3.5, 1e-5);
  std::filesystem::remove(path);
}

// Timing at full HD; run with --gtest_also_run_disabled_tests.
TEST(InverseMap, DISABLED_Timing1080pBand) {
  const double r_in = 30, r_out = 32.5;
  Part part(shapes::cylindrical_shell(r_in, r_out, 100, 24, 256, 16), ChartMethod::lscm);
  Rig rig(1920, 1080, 3500, 80 + r_out);  // the band fills most of the frame, ~0.024 mm/px
  const auto t0 = std::chrono::steady_clock::now();
  const RefractionMap fwd = compute_refraction_map(part.scene(), rig.camera, rig.cam_from_part);
  const double fwd_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  for (bool errors : {false, false, true}) {
    InverseMapOptions opt;
    opt.compute_errors = errors;
    const InverseMap inv = compute_inverse_map(fwd, opt, &part.contact);
    std::printf(
        "  forward %.0f ms (%lld valid px, %.4f mm/px); inverse %d x %d, %lld texels valid: raster %.1f ms, "
        "errors %.1f ms\n",
        fwd_ms, fwd.stats.by_status[0], max_step_mm(fwd), inv.width, inv.height, inv.error.texels_valid,
        inv.raster_ms, inv.error_ms);
    if (errors)
      std::printf(
          "  round trip: uv max %.2e um; pixel max %.2e, p99 %.2e, median %.2e px; cells %lld used, %lld "
          "step, %lld fold\n",
          inv.error.max_uv_um, inv.error.max_px, inv.error.p99_px, inv.error.median_px, inv.cells_used,
          inv.cells_rejected_step, inv.cells_rejected_fold);
  }
}
