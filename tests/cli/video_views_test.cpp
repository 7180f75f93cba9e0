// detect, calibrate and pose from videos: a board rendered through a known lens
// moving in front of the camera, with frames blurred, smeared, repeated, without
// the board and with too little of it injected on purpose (lossless FFV1, so the
// intrinsics meet the image test's tolerances); a still fixture filmed as a
// video gives the pose its image gives, and one view to detect; bad videos exit 2.
#include "cli_support.hpp"

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/camera/render_board.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <random>

namespace clearfit::cli_test {
namespace {

const std::string kData = std::string(CLEARFIT_TEST_DATA_DIR) + "/boards/";

CameraModel true_lens() {  // as tests/cli/calibrate_test.cpp's, at 800 x 600
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  m.width = 800;
  m.height = 600;
  m.intrinsics = {625.0, 626.25, 401.3, 298.6, -0.30, 0.10, 0.0010, -0.0005, -0.02, 0.02, 0.01, 0.0};
  return m;
}

class VideoViewsCli : public CliTest {
 protected:
  /// Writes `frames` (8-bit grey, one size) as a video: raw frames through the ffmpeg program (scripts/bootstrap.sh installs it).
  void encode(const std::vector<cv::Mat>& frames, const std::string& video, const std::string& codec_args) {
    const fs::path raw = root() / (video + ".raw");
    {
      std::ofstream out(raw, std::ios::binary);
      for (const cv::Mat& f : frames) out.write(reinterpret_cast<const char*>(f.data), static_cast<std::streamsize>(f.total()));
      ASSERT_TRUE(out.good());
    }
    const std::string size = std::to_string(frames.at(0).cols) + "x" + std::to_string(frames.at(0).rows);
    const std::string cmd = "ffmpeg -nostdin -v error -y -f rawvideo -pix_fmt gray -s " + size + " -framerate 10 -i " + raw.string() + " " +
                            codec_args + " " + (work() / video).string() + " > " + (root() / "ffmpeg.log").string() + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << "ffmpeg failed (install the ffmpeg package): " << cmd;
    fs::remove(raw);
  }
};

struct Injected {
  int views = 0, repeats = 0, blurred = 0, no_board = 0, too_few = 0;
  int total() const { return views + repeats + blurred + no_board + too_few; }
};

/// A calibration video: the image test's 14 views, then repeats, blurred and smeared frames, frames without the
/// board and frames with two of its tags (board.yaml written in `dir`).
std::vector<cv::Mat> board_video(const fs::path& dir, Injected& n) {
  const Board board = make_board({"tag36h11", 5, 5, 24, 24, 0});  // 10 x 10 corners
  write_board(board, dir / "board.yaml");
  const CameraModel truth = true_lens();
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
  const RayGrid rays = unproject_image(truth, 1);
  std::uint64_t seed = 1;
  auto render = [&](const Rigid3& p, double blur = 0, int supersample = 3) {
    RenderOptions ro;
    ro.noise_sigma = 2;
    ro.seed = seed++;
    ro.supersample = supersample;
    ro.blur_sigma_px = blur;
    return render_board(board, truth, p, ro, &rays);
  };
  std::vector<cv::Mat> frames;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    frames.push_back(render(poses[k]));
    ++n.views;
    if (k < 5) frames.push_back(render(poses[k])), ++n.repeats;  // the camera paused: same view, new noise
  }
  for (int k : {3, 7, 11}) frames.push_back(render(poses[k], 2.5, 2)), ++n.blurred;  // out of focus
  for (int k : {5, 9}) {                                                             // moving: 11 px smears
    cv::Mat smeared;
    const cv::Mat line = k == 5 ? cv::Mat::ones(1, 11, CV_32F) / 11.0 : cv::Mat::eye(11, 11, CV_32F) / 11.0;
    cv::filter2D(render(poses[k], 0, 2), smeared, -1, line);
    frames.push_back(smeared), ++n.blurred;
  }
  Rigid3 away = poses[0];
  away.translation.x() += 5000;  // the board out of view
  for (int k = 0; k < 3; ++k) frames.push_back(render(away, 0, 1)), ++n.no_board;
  // A few tags in view: the board slid right until 8 to 16 of its corners (less than the quarter
  // min_corner_fraction asks for) remain inside.
  for (double y : {-150.0, -60.0}) {
    Rigid3 edge;  // facing the camera, 300 mm away
    int inside = 0;
    for (double x = -108; x < 1000 && !(inside >= 8 && inside <= 16); x += 2) {
      edge.translation = Eigen::Vector3d(x, y, 300);
      inside = 0;
      for (const auto& c : true_corners(board, truth, edge, 5)) inside += c.z() > 0;
    }
    EXPECT_TRUE(inside >= 8 && inside <= 16) << inside;
    frames.push_back(render(edge, 0, 2)), ++n.too_few;
  }
  return frames;
}

TEST_F(VideoViewsCli, CalibrateFromAVideoKeepsTheSharpDistinctFrames) {
  Injected n;
  const auto t0 = std::chrono::steady_clock::now();
  const auto frames = board_video(work(), n);
  const auto t1 = std::chrono::steady_clock::now();
  encode(frames, "board.mkv", "-c:v ffv1 -pix_fmt bgr0");
  std::printf("render %.1f s, encode %.1f s (machine load shows here)\n", std::chrono::duration<double>(t1 - t0).count(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
  const RunResult r = run_clearfit({"calibrate", "--board", "board.yaml", "board.mkv", "--out", "cam.cameramodel", "--report",
                                    "report.json", "--no-uncertainty"},
                                   work(), root() / "capture", 120);
  ASSERT_EQ(r.exit_code, 0) << r;
  std::printf("%s(calibrate: %.1f s)\n", r.out.c_str(), r.seconds);
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  const auto& video = report["inputs"]["videos"][0];
  EXPECT_EQ(video["frames_read"], n.total());
  EXPECT_EQ(video["used"], n.views);
  EXPECT_EQ(video["dropped"]["duplicate_view"], n.repeats);
  EXPECT_EQ(video["dropped"]["blurred"], n.blurred);
  EXPECT_EQ(video["dropped"]["no_board"], n.no_board);
  EXPECT_EQ(video["dropped"]["too_few_corners"], n.too_few);
  EXPECT_EQ(video["dropped"]["over_cap"], 0);
  EXPECT_NE(r.out.find(std::to_string(n.total()) + " frames read, " + std::to_string(n.views) + " used"), std::string::npos) << r;
  EXPECT_EQ(report["views"].size(), static_cast<std::size_t>(n.views));
  EXPECT_NE(report["views"][0]["image"].get<std::string>().find("board.mkv#"), std::string::npos);
  // The image test's tolerances against the truth.
  const CameraModel truth = true_lens();
  const CameraModel ours = read_cameramodel(work() / "cam.cameramodel");
  const auto coverage = report["coverage"]["corners"].get<std::vector<int>>();
  const auto d = projection_difference_grid(truth, ours, 8, 6, coverage);
  double worst = 0;
  for (std::size_t k = 0; k < d.size(); ++k)
    if (coverage[k] > 0) worst = std::max(worst, d[k]);
  std::printf("video: rms %.3f px, worst error vs truth over observed cells %.3f px\n", report["rms_px"].get<double>(), worst);
  EXPECT_LT(report["rms_px"].get<double>(), 0.2);
  EXPECT_LT(worst, 0.25);

}

TEST_F(VideoViewsCli, PoseAndDetectFromAStillVideo) {
  const cv::Mat still = cv::imread(kData + "pose_fixture.png", cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(still.empty());
  std::mt19937 rng(7);
  std::printf("noise seed 7\n");
  std::vector<cv::Mat> frames;
  auto noisy = [&](const cv::Mat& img) {
    cv::Mat noise(img.size(), CV_32F), out;
    cv::randn(noise, 0, 2);
    cv::Mat f;
    img.convertTo(f, CV_32F);
    cv::Mat(f + noise).convertTo(out, CV_8U);
    return out;
  };
  cv::theRNG().state = rng();
  for (int k = 0; k < 8; ++k) frames.push_back(noisy(still));
  for (int k = 0; k < 3; ++k) {
    cv::Mat b;
    cv::GaussianBlur(still, b, cv::Size(0, 0), 2.5);
    frames.push_back(noisy(b));  // the camera refocusing
  }
  for (int k = 0; k < 2; ++k) frames.push_back(noisy(cv::Mat(still.size(), CV_8U, cv::Scalar(120))));  // a hand over the lens
  encode(frames, "still.mkv", "-c:v ffv1 -pix_fmt bgr0");
  const std::vector<std::string> common{"--camera", kData + "opencv8_640x480.cameramodel", "--layout", kData + "pose_layout.yaml"};
  auto args = [&](const std::string& input, const std::string& out) {
    std::vector<std::string> a{"pose", input, "--out", out, "--report", out + ".report.json"};
    a.insert(a.end(), common.begin(), common.end());
    return a;
  };
  const RunResult image = run(args(kData + "pose_fixture.png", "image.json"));
  ASSERT_EQ(image.exit_code, 0) << image;
  const RunResult video = run(args("still.mkv", "video.json"));
  ASSERT_EQ(video.exit_code, 0) << video;
  EXPECT_NE(video.out.find("13 frames read, 8 used; dropped 3 blurred"), std::string::npos) << video;
  const auto report = nlohmann::json::parse(read_text(work() / "video.json.report.json"));
  EXPECT_EQ(report["videos"][0]["dropped"]["no_board"], 2);
  EXPECT_EQ(report["videos"][0]["dropped"]["blurred"], 3);
  const Rigid3 a = read_pose_json(work() / "image.json"), b = read_pose_json(work() / "video.json");
  const Rigid3 truth = Rigid3::from_rt({-0.49831823442222983, 0.1958103722485659, 0.049998596644955109, 5, -8, 230});
  auto dt = [](const Rigid3& x, const Rigid3& y) { return (x.translation - y.translation).norm(); };
  auto dr = [](const Rigid3& x, const Rigid3& y) { return rodrigues_from_rotation(x.rotation * y.rotation.transpose()).norm() * 180 / M_PI; };
  std::printf("video vs image: %.4f mm, %.5f deg; video vs truth: %.4f mm, %.5f deg\n", dt(a, b), dr(a, b), dt(b, truth), dr(b, truth));
  // The image's own tolerance against the truth (tests/cli/pose_test.cpp), for both and between them.
  EXPECT_LT(dt(b, truth), 0.1);
  EXPECT_LT(dr(b, truth), 0.05);
  EXPECT_LT(dt(a, b), 0.1);
  EXPECT_LT(dr(a, b), 0.05);
  // The same frames as a phone codes them (H.264 CRF 23, 4:2:0, limited range): the same verdicts and pose.
  encode(frames, "still.mp4", "-c:v libx264 -crf 23 -pix_fmt yuv420p");
  const RunResult phone = run(args("still.mp4", "phone.json"));
  ASSERT_EQ(phone.exit_code, 0) << phone;
  EXPECT_NE(phone.out.find("13 frames read, 8 used; dropped 3 blurred"), std::string::npos) << phone;
  const Rigid3 c = read_pose_json(work() / "phone.json");
  std::printf("H.264 CRF 23 vs truth: %.4f mm, %.5f deg\n", dt(c, truth), dr(c, truth));
  EXPECT_LT(dt(c, truth), 0.1);
  EXPECT_LT(dr(c, truth), 0.05);
  // The cap: the 5 sharpest frames.
  std::vector<std::string> capped = args("still.mkv", "capped.json");
  capped.insert(capped.end(), {"--max-views", "5"});
  const RunResult cap = run(capped);
  ASSERT_EQ(cap.exit_code, 0) << cap;
  EXPECT_NE(cap.out.find("13 frames read, 5 used"), std::string::npos) << cap;
  EXPECT_NE(cap.out.find("3 over the cap of 5"), std::string::npos) << cap;
  // detect on the same video (the fixture's tags as a board): a still camera gives one view, the rest repeat it.
  write_board(make_board({"tag36h11", 3, 4, 20, 20, 10}), work() / "fixture.yaml");
  const RunResult det = run({"detect", "--board", "fixture.yaml", "still.mkv", "--out", "corners.vnl"});
  ASSERT_EQ(det.exit_code, 0) << det;
  EXPECT_NE(det.out.find("13 frames read, 1 used; dropped 3 blurred"), std::string::npos) << det;
  EXPECT_NE(det.out.find("7 duplicate views"), std::string::npos) << det;
  EXPECT_NE(det.out.find("2 with no board or tags found"), std::string::npos) << det;
  EXPECT_NE(det.out.find("board found in 1 of 1 images"), std::string::npos) << det;
  EXPECT_NE(read_text(work() / "corners.vnl").find("still.mkv#"), std::string::npos);
}

TEST_F(VideoViewsCli, BadVideos) {
  encode(std::vector<cv::Mat>(5, cv::Mat(120, 160, CV_8U, cv::Scalar(100))), "grey.mkv", "-c:v ffv1 -pix_fmt bgr0");
  write_board(make_board({"tag36h11", 5, 5, 24, 24, 0}), work() / "board.yaml");
  expect_input_error({"calibrate", "--board", "board.yaml", "grey.mkv", "--out", "cam.cameramodel"},
                     {"grey.mkv", "no board found in any of its 5 frames"});
  expect_input_error({"detect", "--board", "board.yaml", "grey.mkv", "--out", "c.vnl"}, {"grey.mkv", "no board found"});
  write_text(work() / "text.mp4", "not a video\n");
  expect_input_error({"calibrate", "--board", "board.yaml", "text.mp4", "--out", "cam.cameramodel"}, {"text.mp4", "cannot be opened as a video"});
  expect_input_error({"pose", "text.mp4", "--camera", kData + "opencv8_640x480.cameramodel", "--layout", kData + "pose_layout.yaml", "--out", "p.json"},
                     {"text.mp4", "cannot be opened as a video"});
}

}  // namespace
}  // namespace clearfit::cli_test
