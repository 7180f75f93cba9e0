// clearfit calibrate end to end: a corners file and rendered board images
// through a known lens, the report, mrcal's own tools reading the output,
// OpenCV conversion, and bad input.
#include "cli_support.hpp"

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/camera/render_board.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>

namespace clearfit::cli_test {
namespace {

CameraModel true_lens(int w = 1280, int h = 960) {
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  m.width = w;
  m.height = h;
  m.intrinsics = {1000.0 * w / 1280,
                  1002.0 * w / 1280,
                  0.5 * w + 1.3,
                  0.5 * h - 1.4,
                  -0.30,
                  0.10,
                  0.0010,
                  -0.0005,
                  -0.02,
                  0.02,
                  0.01,
                  0.0};
  return m;
}

std::string run_text(const std::string& command) {
  std::string out;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  EXPECT_EQ(pclose(p), 0) << command << "\n" << out;
  return out;
}

class Calibrate : public CliTest {};

const CalibrationGrid kGrid{10, 10, 30};

/// `views` boards seen by true_lens() with corner noise `noise_px`, seed printed.
std::vector<BoardObservation> synthetic_views(int views, double noise_px, unsigned seed) {
  SyntheticViewsOptions o;
  o.views = views, o.noise_px = noise_px, o.seed = seed;
  std::printf("synthetic views: seed %u\n", o.seed);
  return synthesize_views(true_lens(), kGrid, o);
}

TEST_F(Calibrate, CornersFileToModelAndReport) {
  const CameraModel truth = true_lens();
  write_corners_levels_vnl(synthetic_views(20, 0.25, 41), work() / "corners.vnl");
  const RunResult r =
      run({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "corners.vnl",
           "--imagersize", "1280", "960", "--out", "cam.cameramodel", "--report", "report.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("calibrated LENSMODEL_OPENCV8"), std::string::npos) << r;
  EXPECT_NE(r.err.find("solving: board poses"), std::string::npos) << r;  // progress on stderr
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  EXPECT_EQ(report["schema"], "clearfit.calibration/1");
  EXPECT_NEAR(report["rms_px"].get<double>(), 0.25, 0.02);
  EXPECT_EQ(report["views"].size(), 20u);
  EXPECT_EQ(report["uncertainty"]["nodes_px"].size(), 17u * 13u);
  const auto u = read_projection_uncertainty(work() / "cam.cameramodel");
  ASSERT_TRUE(u);
  EXPECT_EQ(u->layout, ProjectionUncertainty::Layout::nodes);
  EXPECT_EQ(u->px, report["uncertainty"]["nodes_px"].get<std::vector<double>>());
  EXPECT_GT(report["uncertainty"]["centre_px"].get<double>(), 0.0);
  EXPECT_EQ(report["coverage"]["corners"].size(), 48u);
  const CameraModel ours = read_cameramodel(work() / "cam.cameramodel");
  EXPECT_EQ(ours.intrinsics, report["intrinsics"].get<std::vector<double>>());
  // mrcal's own command-line tool reads the file: reproject the image centre
  // from our model to the true one, compare with our own arithmetic.
  write_cameramodel(truth, work() / "truth.cameramodel");
  const std::string out =
      run_text("cd " + work().string() +
               " && echo '639.5 479.5' | /usr/bin/python3 /usr/bin/mrcal-reproject-points "
               "cam.cameramodel truth.cameramodel");
  double x = 0, y = 0;
  ASSERT_EQ(std::sscanf(out.substr(out.rfind("\n", out.size() - 2) + 1).c_str(), "%lf %lf", &x, &y), 2)
      << out;
  const Vec2 expected = truth.project(ours.unproject(Vec2(639.5, 479.5)));
  EXPECT_NEAR(x, expected.x(), 2e-6);
  EXPECT_NEAR(y, expected.y(), 2e-6);
}

// Corners knocked 12 px off their place are thrown out by mrcal's outlier rejection, which libmrcal announces
// on stderr at each pass ("mrcal.c(N): Threw out some outliers (have a total of K now); going again"). The
// user sees clearfit's own words instead: a progress line, and the count in the summary and the report.
TEST_F(Calibrate, MrcalsOutlierChatterIsClearfitsOwnMessage) {
  std::vector<BoardObservation> views = synthetic_views(12, 0.2, 43);
  int moved = 0;
  for (std::size_t v = 0; v < views.size(); v += 3)  // the first corner present in every third view
    for (auto& c : views[v].corners)
      if (c.z() > 0) {
        c.x() += 12, c.y() -= 9;
        ++moved;
        break;
      }
  write_corners_levels_vnl(views, work() / "corners.vnl");
  const RunResult r = run({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "corners.vnl", "--imagersize", "1280",
                           "960", "--out", "cam.cameramodel", "--report", "report.json", "--no-uncertainty"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  EXPECT_GE(report["outliers"]["count"].get<int>(), moved) << r;
  // Each moved corner is reported with its distance from the solution (15 px moved, 0.2 px noise), not 0.
  int found = 0;
  for (const auto& o : report["outliers"]["corners"])
    if (std::abs(o["error_px"].get<double>() - 15.0) < 1.5) ++found;
  EXPECT_EQ(found, moved) << report["outliers"].dump();
  EXPECT_EQ(r.err.find("Threw out"), std::string::npos) << "libmrcal's own words on stderr\n" << r;
  EXPECT_EQ(r.err.find("mrcal.c("), std::string::npos) << r;
  EXPECT_NE(r.err.find("outliers thrown out and solved again ("), std::string::npos) << r;
  EXPECT_NE(r.out.find(std::to_string(report["outliers"]["count"].get<int>()) + " outliers"), std::string::npos) << r;
}

TEST_F(Calibrate, RenderedBoardImages) {
  // A board rendered through a known lens, detected, refined with the lens
  // model and calibrated; error against the truth over the observed region.
  const Board board = make_board({"tag36h11", 5, 5, 24, 24, 0});  // 10 x 10 corners, 24 mm
  write_board(board, work() / "board.yaml");
  const CameraModel truth = true_lens(800, 600);
  SyntheticViewsOptions o;
  o.views = 14;
  o.noise_px = 0;
  o.seed = 42;
  o.min_distance_mm = 250;
  o.max_distance_mm = 600;
  o.max_tilt_deg = 40;
  std::printf("rendered views: seed %u\n", o.seed);
  std::vector<Rigid3> poses;
  synthesize_views(truth, CalibrationGrid::of(board), o, &poses);
  fs::create_directories(work() / "images");
  const RayGrid rays = unproject_image(truth, 1);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    RenderOptions ro;
    ro.noise_sigma = 2;
    ro.seed = k + 1;
    ro.supersample = 3;
    cv::imwrite((work() / "images" / ("view" + std::to_string(100 + k) + ".png")).string(),
                render_board(board, truth, poses[k], ro, &rays));
  }
  const RunResult r = run_clearfit({"calibrate", "--board", "board.yaml", "images", "--out",
                                    "cam.cameramodel", "--report", "report.json", "--no-uncertainty"},
                                   work(), root() / "capture", 120);
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.err.find("detecting the board in 14 images"), std::string::npos) << r;
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  const CameraModel ours = read_cameramodel(work() / "cam.cameramodel");
  const auto coverage = report["coverage"]["corners"].get<std::vector<int>>();
  const auto d = projection_difference_grid(truth, ours, 8, 6, coverage);
  double worst = 0;
  for (std::size_t k = 0; k < d.size(); ++k)
    if (coverage[k] > 0) worst = std::max(worst, d[k]);
  std::printf(
      "rendered: rms %.3f px (before refinement %.3f), worst error vs truth over observed cells %.3f px\n",
      report["rms_px"].get<double>(), report["refinement"]["first_rms_px"].get<double>(), worst);
  EXPECT_LT(report["rms_px"].get<double>(), 0.2);
  EXPECT_LT(worst, 0.25);
}

TEST_F(Calibrate, FromOpencvYaml) {
  const cv::Mat K = (cv::Mat_<double>(3, 3) << 900.5, 0, 640.25, 0, 901.0, 360.75, 0, 0, 1);
  const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.2, 0.04, 0.001, -0.002, 0.01);
  {
    cv::FileStorage fs((work() / "calib.yaml").string(), cv::FileStorage::WRITE);
    fs << "image_width" << 1280 << "image_height" << 720 << "camera_matrix" << K << "distortion_coefficients"
       << D;
  }
  const RunResult r = run({"calibrate", "--from-opencv", "calib.yaml", "--out", "cam.cameramodel"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const CameraModel m = read_cameramodel(work() / "cam.cameramodel");
  EXPECT_EQ(m.lensmodel, "LENSMODEL_OPENCV5");
  std::vector<cv::Point3d> p{{0.3, -0.2, 1.0}, {-0.5, 0.3, 2.0}};
  std::vector<cv::Point2d> q;
  cv::projectPoints(p, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D, q);
  for (std::size_t k = 0; k < p.size(); ++k)
    EXPECT_LT((m.project(Vec3(p[k].x, p[k].y, p[k].z)) - Vec2(q[k].x, q[k].y)).norm(), 1e-6);
  // An existing .cameramodel is checked and rewritten unchanged.
  const RunResult again =
      run({"calibrate", "--from-cameramodel", "cam.cameramodel", "--out", "copy.cameramodel"});
  ASSERT_EQ(again.exit_code, 0) << again;
  EXPECT_EQ(read_cameramodel(work() / "copy.cameramodel").intrinsics, m.intrinsics);
}

TEST_F(Calibrate, BadInput) {
  expect_input_error({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "c.vnl"},
                     {"--out"});
  write_text(work() / "c.vnl", "# filename x y level\na.png 1 2 0\n");
  expect_input_error({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "c.vnl", "--out",
                      "x.cameramodel"},
                     {"--imagersize"});
  expect_input_error({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "c.vnl",
                      "--imagersize", "640", "480", "--out", "x.cameramodel"},
                     {"c.vnl", "line 2", "needs 100"});
  expect_input_error(
      {"calibrate", "--corners", "c.vnl", "--imagersize", "640", "480", "--out", "x.cameramodel"},
      {"--board"});
  expect_input_error(
      {"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "c.vnl", "--imagersize", "640",
       "480", "--lensmodel", "LENSMODEL_NOPE", "--out", "x.cameramodel"},
      {"unknown lens model"});
  // The printed board is 12 x 8, the description says 8 x 12.
  SyntheticViewsOptions o;
  o.views = 8;
  o.seed = 43;
  write_corners_levels_vnl(synthesize_views(true_lens(), {12, 8, 25}, o), work() / "swapped.vnl");
  expect_input_error({"calibrate", "--grid", "8", "12", "--spacing-mm", "25", "--corners", "swapped.vnl",
                      "--imagersize", "1280", "960", "--out", "x.cameramodel"},
                     {"frame000.png", "inconsistent with a 8 x 12 grid"});
  write_text(work() / "bad.yaml", "%YAML:1.0\n---\nimage_width: 640\n");
  expect_input_error({"calibrate", "--from-opencv", "bad.yaml", "--out", "x.cameramodel"},
                     {"bad.yaml", "camera_matrix"});
}

}  // namespace
}  // namespace clearfit::cli_test
