// Numerical limits of the camera (issue 16, section 5): projection and
// unprojection of points and pixels at the extremes of double, imagers of one
// pixel, and near-singular calibrations (noise-free corners, one pose seen
// over and over, boards all facing the camera at one distance, a board of a
// few pixels). Each gives a finite answer (checked against the truth it was
// made from) or NaN where the contract says so, or an InputError; never NaN
// in a calibration's figures.
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/error.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

using namespace clearfit;

namespace {

CameraModel lens(const std::string& lensmodel, int w, int h) {
  CameraModel m;
  m.lensmodel = lensmodel;
  m.width = w;
  m.height = h;
  const double f = 0.8 * std::max(w, h);
  m.intrinsics = {f, 1.002 * f, (w - 1) / 2.0 + 0.3, (h - 1) / 2.0 - 0.2};
  if (lensmodel == "LENSMODEL_OPENCV8")
    m.intrinsics.insert(m.intrinsics.end(), {-0.30, 0.10, 0.0010, -0.0005, -0.02, 0.02, 0.01, 0.0});
  return m;
}

const CalibrationGrid kGrid{10, 10, 30.0};

// Every figure of a calibration is finite (uncertainty included when asked).
void expect_finite(const CalibrationResult& r, const std::string& what) {
  for (double v : r.model.intrinsics) EXPECT_TRUE(std::isfinite(v)) << what;
  for (double v : {r.rms_px, r.mrcal_rms_px, r.seed_rms_px, r.focal_seed_px, r.calobject_warp_x_mm,
                   r.calobject_warp_y_mm, r.uncertainty_center_px, r.observed_pixel_sigma_px})
    EXPECT_TRUE(std::isfinite(v)) << what << ": " << v;
  for (double v : r.uncertainty_px) EXPECT_TRUE(std::isfinite(v) && v >= 0) << what << ": uncertainty " << v;
  for (const auto& v : r.views)
    if (v.used) {
      EXPECT_TRUE(std::isfinite(v.rms_px) && std::isfinite(v.distance_mm) && std::isfinite(v.tilt_deg)) << what;
    }
}

}  // namespace

TEST(NumericalLimits, ProjectAndUnprojectKeepTheirContractAtTheExtremes) {
  const double big = std::numeric_limits<double>::max(), tiny = std::numeric_limits<double>::denorm_min();
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  for (const char* lm : {"LENSMODEL_PINHOLE", "LENSMODEL_OPENCV8", "LENSMODEL_STEREOGRAPHIC"}) {
    for (const auto& [w, h] : {std::pair{1, 1}, std::pair{2, 1}, std::pair{640, 480}}) {
      const CameraModel cam = lens(lm, w, h);
      const std::string what = std::string(lm) + " " + std::to_string(w) + "x" + std::to_string(h);
      // Points: either a finite pixel or NaN in both coordinates.
      for (const Vec3& p : {Vec3(0, 0, 1), Vec3(0, 0, tiny), Vec3(tiny, tiny, tiny), Vec3(1e-300, 0, 1e-300),
                            Vec3(1, 1, 1e-300), Vec3(0, 0, big), Vec3(big, big, big), Vec3(1e300, 0, 1),
                            Vec3(0, 0, -1), Vec3(0, 0, 0), Vec3(nan, 0, 1), Vec3(0, 0, inf), Vec3(1, 0, 0)}) {
        const Vec2 q = cam.project(p);
        EXPECT_TRUE(q.allFinite() || (std::isnan(q.x()) && std::isnan(q.y())))
            << what << ": (" << p.transpose() << ") -> " << q.transpose();
      }
      // Pixels: a unit ray or NaN in every coordinate; inside the imager a ray
      // that projects back to the pixel.
      for (const Vec2& q : {Vec2(0, 0), Vec2(-0.5, -0.5), Vec2(w - 0.5, h - 0.5), Vec2(1e6, -1e6), Vec2(1e300, 0),
                            Vec2(big, big), Vec2(nan, 0), Vec2(inf, 0), Vec2(tiny, -tiny)}) {
        const Vec3 v = cam.unproject(q);
        const bool ok = v.allFinite() && std::abs(v.norm() - 1) < 1e-9;
        EXPECT_TRUE(ok || (std::isnan(v.x()) && std::isnan(v.y()) && std::isnan(v.z())))
            << what << ": (" << q.transpose() << ") -> " << v.transpose();
        if (ok && q.cwiseAbs().maxCoeff() < 1e3) {
          EXPECT_LT((cam.project(v) - q).norm(), 1e-6) << what << ": " << q.transpose();
        }
      }
      // The whole imager at once, as the map asks for it.
      const RayGrid g = unproject_image(cam);
      ASSERT_EQ(g.rays.size(), static_cast<std::size_t>(w) * h) << what;
      for (const Vec3& v : g.rays) EXPECT_TRUE(v.allFinite() && std::abs(v.norm() - 1) < 1e-9) << what;
    }
  }
}

TEST(NumericalLimits, NearSingularCalibrationsGiveFiniteFiguresOrARefusal) {
  const CameraModel truth = lens("LENSMODEL_OPENCV8", 1280, 960);
  struct Case {
    std::string name;
    SyntheticViewsOptions views;
    int repeat_first = 0;  ///< the first view, given this many times instead of the others
    std::string refusal;   ///< what the refusal names; empty: a finite calibration
  };
  std::vector<Case> cases;
  SyntheticViewsOptions base;
  base.views = 12;
  base.seed = 1605;
  cases.push_back({"noise-free corners", base, 0, ""});
  cases.back().views.noise_px = 0;
  cases.push_back({"one pose seen 12 times", base, 12, "in only 1 distinct pose(s)"});
  cases.push_back({"every board facing the camera at one distance", base, 0, "do not determine the focal length"});
  cases.back().views.min_tilt_deg = cases.back().views.max_tilt_deg = 0;
  cases.back().views.min_distance_mm = cases.back().views.max_distance_mm = 900;
  cases.push_back({"boards 60 m away (a few pixels)", base, 0, "px apart"});
  cases.back().views.min_distance_mm = cases.back().views.max_distance_mm = 60000;
  cases.back().views.min_inside_fraction = 1;
  for (const Case& c : cases) {
    auto views = synthesize_views(truth, kGrid, c.views);
    if (c.repeat_first) views.assign(c.repeat_first, views.front());
    for (std::size_t i = 0; i < views.size(); ++i) views[i].image = "view" + std::to_string(i) + ".png";
    for (const char* lm : {"LENSMODEL_PINHOLE", "LENSMODEL_OPENCV8"}) {
      CalibrationOptions opt;
      opt.lensmodel = lm;
      const std::string what = c.name + ", " + lm;
      try {
        const CalibrationResult r = calibrate_camera(views, kGrid, opt);
        expect_finite(r, what);
        std::printf("  %s: rms %.3g px, focal %.6g px (truth 1024), uncertainty at the centre %.3g px, %zu warnings\n",
                    what.c_str(), r.rms_px, r.model.intrinsics[0], r.uncertainty_center_px, r.warnings.size());
        EXPECT_EQ(c.refusal, "") << what << ": accepted";
        if (std::string(lm) == "LENSMODEL_OPENCV8") {  // the truth's model; regularisation biases it slightly
          EXPECT_NEAR(r.model.intrinsics[0], truth.intrinsics[0], 0.02) << what;
        }
      } catch (const InputError& e) {
        std::printf("  %s: refused: %s\n", what.c_str(), e.what());
        EXPECT_NE(c.refusal, "") << what << ": refused: " << e.what();
        EXPECT_NE(std::string(e.what()).find(c.refusal), std::string::npos) << e.what();
      }
    }
  }
}
