// Captures: reading, motion measurement and compensation, windows, the phase
// split and the blanching signal, on synthetic frames whose content, motion
// and press are known exactly.
#include <clearfit/error.hpp>
#include <clearfit/fit/blanching.hpp>
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/photometric.hpp>
#include <clearfit/fit/srgb.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <random>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

/// Smooth skin-like texture: sum of sinusoids, evaluated at any (x, y).
double texture(double x, double y) {
  return 0.35 + 0.06 * std::sin(0.31 * x + 0.2 * y) + 0.05 * std::sin(0.17 * y - 0.05 * x + 1.0) +
         0.04 * std::sin(0.11 * (x + y) + 2.0) + 0.03 * std::cos(0.23 * x - 0.29 * y);
}

struct Scene {
  int width = 160, height = 120;
  double press_gain = 1.05;          ///< linear green gain inside the pressed disk
  Vec2 press_centre{80, 60};
  double press_radius = 20;
};

/// A frame whose content is displaced by `shift` (content at x came from x − shift).
cv::Mat render(const Scene& s, const Vec2& shift, bool pressed, std::mt19937& rng, double noise_codes) {
  std::normal_distribution<double> noise(0.0, noise_codes);
  cv::Mat img(s.height, s.width, CV_8UC3);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      const double sx = x - shift.x(), sy = y - shift.y();
      double g = texture(sx, sy);
      if (pressed && Vec2(sx, sy).operator-(s.press_centre).norm() < s.press_radius) g *= s.press_gain;
      // Skin-coloured (linear R = 1.3 G, B = 0.8 G): grey frames would read as glare to the registration.
      const double n = noise(rng);
      auto code = [&](double lin) { return static_cast<std::uint8_t>(std::lround(std::clamp(255.0 * srgb::from_linear(lin) + n, 0.0, 255.0))); };
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(code(0.8 * g), code(g), code(1.3 * g));
    }
  return img;
}

class CaptureTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("clearfit_capture_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path write_frames(const std::string& name, const std::vector<cv::Mat>& frames) {
    const fs::path folder = dir_ / name;
    fs::create_directories(folder);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      char file[32];
      std::snprintf(file, sizeof file, "f%04zu.png", i);
      cv::imwrite((folder / file).string(), frames[i]);
    }
    return folder;
  }
  fs::path dir_;
};

TEST_F(CaptureTest, MeasuresSubpixelMotionAndUndoesItInTheAverage) {
  const Scene s;
  std::mt19937 rng(7);
  std::vector<cv::Mat> frames;
  std::vector<Vec2> truth;
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  for (int i = 0; i < 20; ++i) {
    const Vec2 d = i == 0 ? Vec2::Zero() : Vec2(2.4 + jitter(rng), -1.3 + jitter(rng));  // drift plus jitter
    truth.push_back(d);
    frames.push_back(render(s, d, false, rng, 0.0));
  }
  const auto folder = write_frames("moving", frames);
  CaptureReadOptions o;
  o.chunk_frames = 5;
  o.registration.patch_size = 64;
  MotionReference ref;
  const CaptureSums sums = read_capture(folder, o, ref);
  ASSERT_EQ(sums.info.frames, 20);
  double worst = 0;
  for (int i = 0; i < 20; ++i) worst = std::max(worst, (sums.shift_px[i] - truth[i]).norm());
  std::printf("registration: worst shift error %.4f px over 20 frames\n", worst);
  EXPECT_LT(worst, 0.08);
  // The average of frames 5..19, aligned: equals the reference at p + residual.
  const PhaseAverage avg = average_window(sums, {5, 15}, 15);
  EXPECT_EQ(avg.window.count, 15);
  double err = 0;
  int n = 0;
  for (int y = 20; y < 100; ++y)
    for (int x = 20; x < 140; ++x) {
      const double expected = texture(x - avg.residual_shift_px.x(), y - avg.residual_shift_px.y());
      // Averaging sub-pixel-jittered frames blurs: compare with the jitter-averaged truth.
      double blurred = 0;
      for (int f = 5; f < 20; ++f) {
        const Vec2 res = truth[f] - Vec2(sums.applied_shift[f].x, sums.applied_shift[f].y);
        blurred += texture(x - res.x(), y - res.y());
      }
      blurred /= 15;
      err = std::max(err, std::abs(avg.mean.at<float>(y, x) - blurred));
      (void)expected;
      ++n;
    }
  std::printf("aligned average vs truth: max %.5f (linear green)\n", err);
  EXPECT_LT(err, 0.004);  // 8-bit quantisation of each frame, averaged
  EXPECT_LT(avg.jitter_px_rms, 0.3);
}

TEST_F(CaptureTest, RefusesLargeMotionAndWrongSizes) {
  const Scene s;
  std::mt19937 rng(3);
  const auto folder = write_frames("jump", {render(s, {0, 0}, false, rng, 0), render(s, {14, 0}, false, rng, 0)});
  CaptureReadOptions o;
  o.registration.patch_size = 64;
  o.max_motion_px = 5;
  MotionReference ref;
  try {
    read_capture(folder, o, ref);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("moved"), std::string::npos) << e.what();
  }
  CaptureReadOptions sized;
  sized.expected_width = 640;
  sized.expected_height = 480;
  MotionReference ref2;
  EXPECT_THROW(read_capture(folder, sized, ref2), InputError);
  EXPECT_THROW(read_capture(dir_ / "missing", sized, ref2), InputError);
  fs::create_directories(dir_ / "empty");
  EXPECT_THROW(read_capture(dir_ / "empty", sized, ref2), InputError);
}

TEST_F(CaptureTest, SplitsOneVideoIntoBaselineAndPressAndMeasuresTheSignal) {
  Scene s;
  std::mt19937 rng(11);
  std::vector<cv::Mat> frames;
  const int press_at = 40;
  for (int i = 0; i < 80; ++i) frames.push_back(render(s, {0.1 * std::sin(i * 0.7), 0}, i >= press_at, rng, 1.0));
  const auto folder = write_frames("both", frames);
  CaptureReadOptions o;
  o.registration.patch_size = 64;
  o.chunk_frames = 4;
  MotionReference ref;
  const CaptureSums sums = read_capture(folder, o, ref);
  const PhaseSplit split = split_phases(sums, 30);
  std::printf("press found at frame %d (true %d), step %.1f sigma\n", split.press_frame, press_at, split.step_sigmas);
  EXPECT_NEAR(split.press_frame, press_at, 1);
  EXPECT_LE(split.baseline.first + split.baseline.count, press_at);
  EXPECT_GE(split.worn.first, press_at);
  const PhaseAverage base = average_window(sums, split.baseline, 20);
  const PhaseAverage worn = average_window(sums, split.worn, 20);

  // Identity inverse map: texel (i, j) ↔ pixel (i, j), 0.1 mm texels.
  InverseMap inv;
  inv.width = s.width;
  inv.height = s.height;
  inv.texel_mm = 0.1;
  inv.map_x.resize(s.width * s.height);
  inv.map_y.resize(s.width * s.height);
  inv.valid.assign(s.width * s.height, 1);
  for (int j = 0; j < s.height; ++j)
    for (int i = 0; i < s.width; ++i) {
      inv.map_x[inv.index(i, j)] = static_cast<float>(i);
      inv.map_y[inv.index(i, j)] = static_cast<float>(j);
    }
  BlanchingOptions bo;
  bo.smoothing_mm = 0.2;
  const BlanchingSignal sig = compute_blanching(base, worn, inv, bo);
  const double expected = std::log(s.press_gain);
  const float centre = sig.y.value[sig.y.grid.index(80, 60)];
  const float outside = sig.y.value[sig.y.grid.index(20, 20)];
  std::printf("signal: centre %.5f (expected %.5f), outside %.5f, noise sigma %.5f\n", centre, expected, outside, sig.noise_sigma);
  EXPECT_NEAR(centre, expected, 0.004);
  EXPECT_NEAR(outside, 0.0, 0.004);
  EXPECT_GT(sig.noise_sigma, 0.0);
  EXPECT_LT(sig.noise_sigma, 0.004);
  // A wrong reference disk (on the press) shifts the signal by the press itself.
  bo.reference_uv_mm = Vec2(8.0, 6.0);
  bo.reference_radius_mm = 1.0;
  const BlanchingSignal wrong = compute_blanching(base, worn, inv, bo);
  EXPECT_NEAR(wrong.y.value[wrong.y.grid.index(20, 20)], -expected, 0.004);
}

TEST_F(CaptureTest, CappedSumsAreReadAgainForTheWindowsOnly) {
  // One video whose sums outgrow max_sums_mb: they are released (sums_dropped, averaging refused);
  // read again keeping two windows, only their chunks hold sums and their averages equal those
  // of a read that keeps every chunk.
  Scene s;
  std::mt19937 rng(5);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 60; ++i) frames.push_back(render(s, {0, 0}, i >= 30, rng, 1.0));
  const auto folder = write_frames("both", frames);
  CaptureReadOptions o;
  o.register_motion = false;
  o.chunk_frames = 4;
  MotionReference ref;
  const CaptureSums all = read_capture(folder, o, ref);
  const double chunk_mb = (s.width * s.height * 4.0 + half_grid(cv::Size(s.width, s.height)).area() * 4.0) / 1048576;
  o.max_sums_mb = 3.5 * chunk_mb;
  const CaptureSums capped = read_capture(folder, o, ref);
  EXPECT_TRUE(capped.sums_dropped);
  EXPECT_FALSE(all.sums_dropped);
  int held = 0;
  for (const cv::Mat& m : capped.chunk_sum) held += !m.empty();
  EXPECT_EQ(held, 0);
  EXPECT_EQ(capped.blocks.size(), all.blocks.size());
  const FrameWindow base{6, 20}, worn{36, 20};
  EXPECT_THROW(average_window(capped, base, 16), InputError);
  o.max_sums_mb = 0;
  o.keep_windows = {base, worn};
  const CaptureSums windows = read_capture(folder, o, ref);
  for (int k = 0; k < static_cast<int>(windows.chunk_sum.size()); ++k) {
    const bool in = (k * 4 < 26 && k * 4 + 4 > 6) || (k * 4 < 56 && k * 4 + 4 > 36);
    EXPECT_EQ(!windows.chunk_sum[k].empty(), in) << "chunk " << k;
  }
  for (const FrameWindow& w : {base, worn}) {
    const PhaseAverage a = average_window(all, w, 16), b = average_window(windows, w, 16);
    EXPECT_EQ(a.window.first, b.window.first);
    EXPECT_EQ(a.window.count, b.window.count);
    EXPECT_EQ(cv::norm(a.mean, b.mean, cv::NORM_INF), 0.0);
  }
  EXPECT_THROW(average_window(windows, FrameWindow{26, 8}, 4), InputError);
}

TEST_F(CaptureTest, NoPressIsAMissingPhase) {
  const Scene s;
  std::mt19937 rng(5);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 40; ++i) frames.push_back(render(s, {0, 0}, false, rng, 1.0));
  const auto folder = write_frames("still", frames);
  CaptureReadOptions o;
  o.registration.patch_size = 64;
  MotionReference ref;
  const CaptureSums sums = read_capture(folder, o, ref);
  EXPECT_THROW(split_phases(sums, 10), InputError);
  EXPECT_THROW(average_window(sums, last_frames(sums, 100), 100), InputError);
}

}  // namespace
}  // namespace clearfit
