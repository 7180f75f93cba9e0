// Board detection on rendered images through a known OPENCV8 lens: corners
// against the true projected grid points, plain and after lens-aware refinement;
// bad images (no tags, wrong family, blur, overexposure, partial, duplicate).
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/render_board.hpp>
#include <clearfit/error.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

namespace clearfit {
namespace {

const std::filesystem::path kData = CLEARFIT_TEST_DATA_DIR "/boards";

CameraModel lens() { return read_cameramodel(kData / "opencv8_640x480.cameramodel"); }

/// Renders through lens() with its rays unprojected once for the whole program.
cv::Mat render(const Board& board, const Rigid3& cam_from_board, const RenderOptions& ro = {}) {
  static const CameraModel cam = lens();
  static const RayGrid rays = unproject_image(cam, 1);
  return render_board(board, cam, cam_from_board, ro, &rays);
}

Board test_board(const std::string& family = "tag36h11") { return make_board({family, 4, 5, 20.0, 20.0, 0}); }

/// cam_from_board with the board's centre at `centre_in_cam` (mm), rotated by
/// (yaw about y, pitch about x, roll about z) in degrees.
Rigid3 pose(const Board& b, Eigen::Vector3d centre_in_cam, double yaw_deg, double pitch_deg,
            double roll_deg) {
  const double d = M_PI / 180;
  Rigid3 p;
  p.rotation = (Eigen::AngleAxisd(yaw_deg * d, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(pitch_deg * d, Eigen::Vector3d::UnitX()) *
                Eigen::AngleAxisd(roll_deg * d, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
  p.translation = centre_in_cam - p.rotation * Eigen::Vector3d(b.width_mm() / 2, b.height_mm() / 2, 0);
  return p;
}

struct ErrorStats {
  int n = 0;
  double sum2 = 0, max = 0, er_r = 0, r2 = 0;
  double rms() const { return n ? std::sqrt(sum2 / n) : 0; }
  /// Least-squares slope of the radial (outward) error against the radius: px per px.
  double radial_slope() const { return r2 > 0 ? er_r / r2 : 0; }
  void add(double e) { ++n, sum2 += e * e, max = std::max(max, e); }
};

/// Errors of the observed corners against the truth, split by the distance
/// from the image centre (inner: r < inner_px).
void compare(const BoardObservation& obs, const std::vector<Eigen::Vector3d>& truth, const CameraModel& cam,
             double inner_px, ErrorStats& inner, ErrorStats& outer, int* missing = nullptr) {
  const Eigen::Vector2d centre(cam.intrinsics[2], cam.intrinsics[3]);
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (truth[i].z() < 0) continue;
    if (obs.corners[i].z() < 0) {
      if (missing) ++*missing;
      continue;
    }
    const Eigen::Vector2d d = obs.corners[i].head<2>() - truth[i].head<2>(),
                          radial = truth[i].head<2>() - centre;
    ErrorStats& s = radial.norm() < inner_px ? inner : outer;
    s.add(d.norm());
    s.er_r += d.dot(radial.normalized()) * radial.norm();
    s.r2 += radial.squaredNorm();
  }
}

TEST(BoardDetect, RenderedBoardsThroughOpencv8LensPlainAndLensAware) {
  const CameraModel cam = lens();
  const Board board = test_board();

  const std::uint64_t seed = 20261122;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  ErrorStats raw_in, raw_out, sub_in, sub_out, lens_in, lens_out;
  int missing = 0, views = 0;
  const double inner = 200;  // px from the image centre
  const struct {
    double x, y, z, yaw, pitch, roll;
  } views_list[] = {
      {0, 0, 260, 0, 0, 0},        {30, 10, 240, 25, 0, 5},     {-30, -10, 250, -20, 15, -8},
      {20, -20, 230, 10, -25, 12}, {-10, 25, 280, -30, -10, 3}, {0, 0, 200, 15, 20, 30},
  };
  for (const auto& v : views_list) {
    const Rigid3 cam_from_board = pose(board, {v.x, v.y, v.z}, v.yaw, v.pitch, v.roll);
    RenderOptions ro;
    ro.blur_sigma_px = 0.5;
    ro.noise_sigma = 1.5;
    ro.seed = seed + views;
    const cv::Mat img = render(board, cam_from_board, ro);
    const auto truth = true_corners(board, cam, cam_from_board, 4);
    const auto inside = true_corners(board, cam, cam_from_board, 12);  // surely detected
    DetectOptions raw_opt;
    raw_opt.subpixel = false;
    const BoardObservation raw = detect_board(img, board, raw_opt, "raw");
    const BoardObservation sub = detect_board(img, board, {}, "sub");
    const BoardObservation refined = refine_corners(img, sub, board, &cam);
    compare(raw, truth, cam, inner, raw_in, raw_out);
    compare(sub, truth, cam, inner, sub_in, sub_out);
    for (int id = 0; id < board.num_tags(); ++id) {  // tags whose four corners are well inside
      bool all_inside = true, any_missing = false;
      for (int k = 0; k < 4; ++k) {
        const int i = board.point_index(*board.corner_grid_index(id, k));
        all_inside &= inside[i].z() >= 0;
        any_missing |= sub.corners[i].z() < 0;
      }
      if (all_inside && any_missing) ++missing, std::printf("  view %d: tag %d missing\n", views, id);
    }
    compare(refined, truth, cam, inner, lens_in, lens_out);
    ++views;
  }
  std::printf("corner error vs truth (px), inner r<%g px | outer:\n", inner);
  std::printf("  AprilTag corners        rms %.4f max %.4f (n %d) | rms %.4f max %.4f (n %d)\n", raw_in.rms(),
              raw_in.max, raw_in.n, raw_out.rms(), raw_out.max, raw_out.n);
  std::printf("  straight edges, pixels  rms %.4f max %.4f (n %d) | rms %.4f max %.4f (n %d)\n", sub_in.rms(),
              sub_in.max, sub_in.n, sub_out.rms(), sub_out.max, sub_out.n);
  std::printf("  lens-aware refinement   rms %.4f max %.4f (n %d) | rms %.4f max %.4f (n %d)\n",
              lens_in.rms(), lens_in.max, lens_in.n, lens_out.rms(), lens_out.max, lens_out.n);
  auto slope = [](const ErrorStats& a, const ErrorStats& b) { return (a.er_r + b.er_r) / (a.r2 + b.r2); };
  std::printf(
      "outward radial error / radius: AprilTag %.2e, straight edges in pixels %.2e, lens-aware %.2e\n",
      slope(raw_in, raw_out), slope(sub_in, sub_out), slope(lens_in, lens_out));
  EXPECT_GT(slope(sub_in, sub_out), 5e-5);              // the bias distortion gives straight-line fits
  EXPECT_LT(std::abs(slope(lens_in, lens_out)), 2e-5);  // removed by fitting in undistorted coordinates
  EXPECT_EQ(missing, 0);
  EXPECT_GT(lens_in.n, 100);
  EXPECT_LE(lens_in.rms(), 0.05);
  EXPECT_LT(lens_out.rms(), sub_out.rms());
}

BoardObservation detect_rendered(const Board& printed, const Board& expected, const RenderOptions& ro,
                                 const Rigid3& cam_from_board) {
  const CameraModel cam = lens();
  return detect_board(render(printed, cam_from_board, ro), expected, {}, "img");
}

std::string all_notes(const BoardObservation& o) {
  std::string s;
  for (const auto& n : o.notes) s += n + "\n";
  return s;
}

TEST(BoardDetect, NoTagsGivesNoCornersAndANote) {
  const Board board = test_board();
  const cv::Mat blank(480, 640, CV_8UC1, cv::Scalar(128));
  const BoardObservation o = detect_board(blank, board, {}, "blank.png");
  EXPECT_FALSE(o.detected());
  EXPECT_EQ(o.tags_used, 0);
  ASSERT_EQ(o.corners.size(), static_cast<std::size_t>(board.num_points()));
  EXPECT_NE(all_notes(o).find("no tag36h11 board tag found"), std::string::npos) << all_notes(o);
  // corners.vnl: one "filename - - -" row for the image.
  EXPECT_EQ(corners_vnl({o}, board), "# filename x y weight\nblank.png - - -\n");
}

TEST(BoardDetect, WrongFamilyIsNamed) {
  const Board printed = test_board("tag25h9"), expected = test_board("tag36h11");
  const Rigid3 p = pose(printed, {0, 0, 260}, 0, 0, 0);
  const BoardObservation o = detect_rendered(printed, expected, {}, p);
  EXPECT_FALSE(o.detected());
  EXPECT_NE(all_notes(o).find("family tag25h9"), std::string::npos) << all_notes(o);
  // The same image with the right board file is detected.
  const BoardObservation right = detect_rendered(printed, printed, {}, p);
  EXPECT_EQ(right.tags_used, printed.num_tags()) << all_notes(right);
}

TEST(BoardDetect, OtherIdsAreIgnoredWithANote) {
  const Board printed = make_board({"tag36h11", 4, 5, 20.0, 20.0, 100}), expected = test_board();
  const BoardObservation o = detect_rendered(printed, expected, {}, pose(printed, {0, 0, 260}, 0, 0, 0));
  EXPECT_FALSE(o.detected());
  EXPECT_NE(all_notes(o).find("not on this board"), std::string::npos) << all_notes(o);
}

TEST(BoardDetect, BlurredAndOverexposedBoards) {
  const Board board = test_board();
  const CameraModel cam = lens();
  const Rigid3 p = pose(board, {0, 0, 260}, 10, 10, 0);
  const auto truth = true_corners(board, cam, p, 4);
  // Both bias the corners (a one-cell dark strip under blur; clipping moves
  // the half-level point): detected, bounded, and flagged with a note.
  const struct {
    const char* what;
    double blur, exposure;
    double max_error_px;
    const char* note;
  } cases[] = {
      {"blur 1.5 px", 1.5, 1.0, 0.6, "blurred"},
      {"overexposed x1.6 (paper clipped at 255)", 0.7, 1.6, 0.8, "overexposed"},
  };
  for (const auto& c : cases) {
    RenderOptions ro;
    ro.blur_sigma_px = c.blur;
    ro.exposure = c.exposure;
    ro.noise_sigma = 1.0;
    const cv::Mat img = render(board, p, ro);
    const BoardObservation o = detect_board(img, board);
    DetectOptions raw_opt;
    raw_opt.subpixel = false;
    ErrorStats in, out, raw_in, raw_out;
    compare(o, truth, cam, 1e9, in, out);
    compare(detect_board(img, board, raw_opt), truth, cam, 1e9, raw_in, raw_out);
    std::printf("%s: %d tags, %d corners, rms %.4f max %.4f px (AprilTag corners: rms %.4f max %.4f)\n",
                c.what, o.tags_used, o.num_valid(), in.rms(), in.max, raw_in.rms(), raw_in.max);
    EXPECT_EQ(o.tags_used, board.num_tags()) << c.what << "\n" << all_notes(o);
    EXPECT_LT(in.max, c.max_error_px) << c.what;
    EXPECT_NE(all_notes(o).find(c.note), std::string::npos) << all_notes(o);
    for (const auto& corner : o.corners) EXPECT_LE(corner.z(), 0.8);  // down-weighted
  }
  // So blurred that the tags cannot be decoded: no corners, never wrong ones.
  RenderOptions ro;
  ro.blur_sigma_px = 6;
  const BoardObservation o = detect_board(render(board, p, ro), board);
  ErrorStats in, out;
  compare(o, truth, cam, 1e9, in, out);
  std::printf("blur 6 px: %d tags, %d corners, max error %.3f px\n", o.tags_used, o.num_valid(), in.max);
  EXPECT_LT(in.max, 1.0);
}

TEST(BoardDetect, PartialTagAtTheBorderIsRejected) {
  const Board board = test_board();
  const CameraModel cam = lens();
  // Shift the board left until its first column of tags is cut by the image border.
  const Rigid3 p = pose(board, {-90, 0, 230}, 0, 0, 0);
  const auto truth = true_corners(board, cam, p, -1000);  // every corner in front of the camera
  const BoardObservation o = detect_board(render(board, p, {}), board);
  int cut = 0;
  for (int id = 0; id < board.num_tags(); ++id) {
    int outside = 0, present = 0;
    for (int k = 0; k < 4; ++k) {
      const int i = board.point_index(*board.corner_grid_index(id, k));
      outside += truth[i].x() < 3;
      present += o.corners[i].z() >= 0;
    }
    if (outside > 0 && outside < 4) {
      ++cut;
      EXPECT_EQ(present, 0) << "tag " << id << " is cut by the border but was used";
    }
  }
  EXPECT_GT(cut, 0) << "the test pose cuts no tag";
  EXPECT_GT(o.tags_used, 8);
  ErrorStats in, out;
  compare(o, true_corners(board, cam, p, 0), cam, 1e9, in, out);
  EXPECT_LT(in.max, 0.5);
}

TEST(BoardDetect, DuplicateIdsAreRejected) {
  const Board board = make_board({"tag36h11", 2, 2, 20.0, 20.0, 0});
  const CameraModel cam = lens();
  cv::Mat img = render(board, pose(board, {-60, 0, 220}, 0, 0, 0), {});
  // Paste a copy of the right column (tags 1 and 3 with their white surround) further right.
  img(cv::Rect(190, 100, 120, 280)).copyTo(img(cv::Rect(460, 100, 120, 280)));
  const BoardObservation o = detect_board(img, board);
  EXPECT_NE(all_notes(o).find("tag 1 seen 2 times"), std::string::npos) << all_notes(o);
  for (int k = 0; k < 4; ++k) EXPECT_LT(o.corners[board.point_index(*board.corner_grid_index(1, k))].z(), 0);
  for (int k = 0; k < 4; ++k) EXPECT_GT(o.corners[board.point_index(*board.corner_grid_index(0, k))].z(), 0);
}

TEST(BoardDetect, CornersVnlHasOneRowPerGridPoint) {
  const Board board = test_board();
  const CameraModel cam = lens();
  const BoardObservation o =
      detect_board(render(board, pose(board, {0, 0, 260}, 0, 0, 0), {}), board, {}, "a.png");
  BoardObservation none = o;
  none.image = "b.png";
  for (auto& c : none.corners) c = Eigen::Vector3d(-1, -1, -1);
  std::istringstream in(corners_vnl({o, none}, board));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "# filename x y weight");
  int rows_a = 0, rows_b = 0, dashes = 0;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string name, x, y, w;
    f >> name >> x >> y >> w;
    ASSERT_FALSE(w.empty()) << line;
    (name == "a.png" ? rows_a : rows_b)++;
    if (x == "-")
      ++dashes;
    else
      EXPECT_GT(std::stod(w), 0);
  }
  EXPECT_EQ(rows_a, board.num_points());
  EXPECT_EQ(rows_b, 1);
  EXPECT_EQ(dashes, board.num_points() - o.num_valid() + 1);
  none.image = "with space.png";
  EXPECT_THROW(corners_vnl({none}, board), std::invalid_argument);
}

TEST(BoardDetect, FolderWithProgress) {
  const Board board = test_board();
  const CameraModel cam = lens();
  const auto dir = std::filesystem::temp_directory_path() / ("clearfit_detect_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cv::imwrite((dir / "v1.png").string(), render(board, pose(board, {0, 0, 260}, 0, 0, 0), {}));
  cv::imwrite((dir / "v0.png").string(), cv::Mat(480, 640, CV_8UC1, cv::Scalar(200)));
  std::filesystem::create_directories(dir / "sub");  // not recursed into
  const auto files = list_images({dir});
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0].filename(), "v0.png");
  int calls = 0, last = 0;
  const auto obs = detect_boards(files, board, {}, [&](int done, int total) {
    ++calls, last = done;
    EXPECT_EQ(total, 2);
  });
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(last, 2);
  EXPECT_FALSE(obs[0].detected());
  EXPECT_EQ(obs[1].tags_used, board.num_tags());
  std::filesystem::remove_all(dir / "sub");
  std::filesystem::create_directories(dir / "empty");
  EXPECT_THROW(list_images({dir / "empty"}), InputError);
  EXPECT_THROW(list_images({dir / "nope.png"}), InputError);
  std::ofstream(dir / "bad.png") << "not a png";
  try {  // the image named once, then what is wrong with it
    detect_boards({dir / "v1.png", dir / "bad.png"}, board);
    ADD_FAILURE() << "bad.png was read";
  } catch (const InputError& e) {
    const std::string file = (dir / "bad.png").string();
    EXPECT_EQ(e.file(), file);
    EXPECT_FALSE(e.problem().empty());
    EXPECT_EQ(std::string(e.what()).rfind(file + ": ", 0), 0u) << e.what();
    EXPECT_EQ(std::string(e.what()).find(file, 1), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(e.problem()), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace clearfit
