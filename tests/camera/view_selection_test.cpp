// Edge widths against the closed form of a Gaussian-blurred step edge (blur adds
// in quadrature), motion blur found along its direction, and the choice of views
// counted by reason on candidates built to known verdicts.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/render_board.hpp>
#include <clearfit/camera/view_selection.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

namespace clearfit {
namespace {

const std::filesystem::path kData = CLEARFIT_TEST_DATA_DIR "/boards";

const CameraModel& lens() {
  static const CameraModel cam = read_cameramodel(kData / "opencv8_640x480.cameramodel");
  return cam;
}

/// The board with its centre `distance_mm` in front of the camera, turned by yaw (deg) about y and roll about z.
Rigid3 pose(const Board& b, double distance_mm, double yaw_deg, double roll_deg = 0) {
  Rigid3 p;
  p.rotation = (Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_deg * M_PI / 180, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
  p.translation = Eigen::Vector3d(0, 0, distance_mm) - p.rotation * Eigen::Vector3d(b.width_mm() / 2, b.height_mm() / 2, 0);
  return p;
}

struct Rendered {
  cv::Mat image;
  std::vector<std::vector<Eigen::Vector2d>> region;
};

Rendered render(const Board& board, const Rigid3& cam_from_board, double blur_sigma_px) {
  static const RayGrid rays = unproject_image(lens(), 1);
  RenderOptions ro;
  ro.blur_sigma_px = blur_sigma_px;
  ro.noise_sigma = 1;
  Rendered r{render_board(board, lens(), cam_from_board, ro, &rays), {{}}};
  for (const auto& c : true_corners(board, lens(), cam_from_board))
    if (c.z() > 0) r.region[0].push_back(c.head<2>());
  return r;
}

TEST(EdgeBlur, GaussianBlurAddsInQuadrature) {
  // width^2(s) - width^2(0) = s^2: the closed form of a step edge blurred by a Gaussian of s px.
  const Board board = make_board({"tag36h11", 4, 3, 24, 24, 0});
  for (double distance : {250.0, 450.0}) {
    const Rigid3 p = pose(board, distance, 25, 10);
    const Rendered sharp = render(board, p, 0);
    const EdgeBlur w0 = measure_edge_blur(sharp.image, sharp.region);
    ASSERT_TRUE(w0.measured());
    std::printf("distance %.0f mm: sharp width %.3f px (best orientation %.3f)\n", distance, w0.width_px, w0.best_width_px);
    EXPECT_GT(w0.width_px, 0.8);
    EXPECT_LT(w0.width_px, 1.8);
    for (double s : {1.5, 2.5, 3.5}) {
      const Rendered blurred = render(board, p, s);
      const EdgeBlur w = measure_edge_blur(blurred.image, blurred.region);
      const double added = std::sqrt(w.width_px * w.width_px - w0.width_px * w0.width_px);
      std::printf("  blur %.1f px: width %.3f px, added %.3f px\n", s, w.width_px, added);
      EXPECT_NEAR(added, s, 0.15 * s);
    }
  }
}

TEST(EdgeBlur, MotionBlurWidensTheEdgesAlongTheMotion) {
  const Board board = make_board({"tag36h11", 4, 3, 24, 24, 0});
  const Rendered r = render(board, pose(board, 300, 0), 0);
  const EdgeBlur sharp = measure_edge_blur(r.image, r.region);
  // A horizontal smear of 9 px (a box: the board moved 9 px during the exposure).
  cv::Mat smeared;
  cv::blur(r.image, smeared, cv::Size(9, 1));
  const EdgeBlur moved = measure_edge_blur(smeared, r.region);
  std::printf("sharp %.3f / %.3f px, smeared %.3f / %.3f px, worst normal %.1f deg\n", sharp.width_px, sharp.best_width_px,
              moved.width_px, moved.best_width_px, moved.worst_normal_deg);
  EXPECT_GT(moved.width_px, 1.8 * sharp.width_px);
  // The worst edges' normals lie along the motion (x); the edges along x are as sharp as before.
  EXPECT_TRUE(moved.worst_normal_deg < 25 || moved.worst_normal_deg > 155) << moved.worst_normal_deg;
  EXPECT_NEAR(moved.best_width_px, sharp.best_width_px, 0.15 * sharp.best_width_px);
}

TEST(EdgeBlur, NothingToMeasure) {
  const cv::Mat flat(100, 100, CV_8U, cv::Scalar(128));
  EXPECT_FALSE(measure_edge_blur(flat, {{{10, 10}, {90, 10}, {90, 90}}}).measured());
  EXPECT_FALSE(measure_edge_blur(flat, {}).measured());
  EXPECT_THROW(measure_edge_blur(cv::Mat(10, 10, CV_16U), {}), std::invalid_argument);
}

/// A 10 x 10 grid of corners 20 px apart, shifted by (dx, dy); the first `missing` corners absent.
ViewCandidate grid(double dx, double dy, double width_px, int missing = 0) {
  ViewCandidate c;
  for (int k = 0; k < 100; ++k)
    c.corners.emplace_back(k < missing ? Eigen::Vector3d(-1, -1, -1) : Eigen::Vector3d(100 + dx + 20 * (k % 10), 60 + dy + 20 * (k / 10), 1));
  c.blur.width_px = c.blur.best_width_px = width_px;
  c.blur.edge_pixels = missing == 100 ? 0 : 1000;
  return c;
}

TEST(SelectViews, CountsEachReason) {
  // 640 x 480: the diagonal is 800 px, min_corner_shift 0.03 -> 24 px.
  std::vector<ViewCandidate> c;
  for (int k = 0; k < 6; ++k) c.push_back(grid(40.0 * k, 10.0 * k, 1.2 + 0.01 * k));  // 6 distinct views
  for (int k = 0; k < 4; ++k) c.push_back(grid(40.0 * k + 3, 10.0 * k - 2, 1.25));    // 4 repeats, 3.6 px away
  c.push_back(grid(0, 100, 2.5));                                                      // 2 blurred (> 1.5 x 1.2)
  c.push_back(grid(100, 100, 1.9));
  c.push_back(grid(0, 0, 0, 100));  // no board
  c.push_back(grid(0, 0, 1.2, 80));  // 20 corners of 100: too few
  ViewSelectionOptions o;
  ViewSelection s = select_views(c, 640, 480, o);
  EXPECT_DOUBLE_EQ(s.sharpest_width_px, 1.2);
  EXPECT_DOUBLE_EQ(s.blur_limit_px, 1.8);
  EXPECT_NEAR(s.min_shift_px, 24, 1e-9);
  EXPECT_EQ(s.count(ViewVerdict::used), 6);
  EXPECT_EQ(s.count(ViewVerdict::duplicate_view), 4);
  EXPECT_EQ(s.count(ViewVerdict::blurred), 2);
  EXPECT_EQ(s.count(ViewVerdict::no_board), 1);
  EXPECT_EQ(s.count(ViewVerdict::too_few_corners), 1);
  EXPECT_EQ(s.count(ViewVerdict::over_cap), 0);
  EXPECT_EQ(s.used(), (std::vector<int>{0, 1, 2, 3, 4, 5}));
  // The cap: 3 of the 6 distinct views; the sharpest first, then the farthest from it (5), then another.
  o.max_views = 3;
  s = select_views(c, 640, 480, o);
  EXPECT_EQ(s.count(ViewVerdict::used), 3);
  // Repeats of a view not kept are over the cap too (they are distinct from every kept view).
  EXPECT_EQ(s.count(ViewVerdict::over_cap) + s.count(ViewVerdict::duplicate_view), 7);
  EXPECT_GE(s.count(ViewVerdict::duplicate_view), 1);
  EXPECT_EQ(s.verdicts[0], ViewVerdict::used);
  EXPECT_EQ(s.verdicts[5], ViewVerdict::used);
  // A still camera: the sharpest, not necessarily distinct.
  s = select_views(c, 640, 480, o, false);
  EXPECT_EQ(s.used(), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(s.count(ViewVerdict::over_cap), 7);
}

TEST(SelectViews, DefaultsAreValidAndBadOnesAreNamed) {
  EXPECT_NO_THROW(ViewSelectionOptions{}.validate());
  ViewSelectionOptions o;
  o.max_blur_ratio = 0.5;
  try {
    o.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_blur_ratio"), std::string::npos);
  }
}

}  // namespace
}  // namespace clearfit
