// Frame reading as people have them: phone videos (H.264/HEVC, 4:2:0, limited or
// full range, BT.601/709 matrices, rotation metadata) encoded here with the ffmpeg
// program at known colours, and 16-bit frame folders whose extra bits must reach
// the averages.
#include <clearfit/error.hpp>
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/frame_reader.hpp>
#include <clearfit/fit/srgb.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <unistd.h>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

// Six 64 px patches (2 rows × 3 columns, aligned to the 4:2:0 chroma blocks), BGR.
const cv::Vec3b kPatches[6] = {{40, 200, 90}, {200, 60, 30}, {128, 128, 128}, {30, 40, 210}, {225, 225, 225}, {90, 160, 200}};

cv::Mat patch_image() {
  cv::Mat img(128, 192, CV_8UC3);
  for (int i = 0; i < 6; ++i) img(cv::Rect((i % 3) * 64, (i / 3) * 64, 64, 64)).setTo(cv::Scalar(kPatches[i][0], kPatches[i][1], kPatches[i][2]));
  return img;
}

/// Where the centre of patch i lands after turning the 192×128 image clockwise by `cw` degrees.
cv::Point rotated_centre(int i, int cw) {
  const int x = (i % 3) * 64 + 32, y = (i / 3) * 64 + 32, w = 192, h = 128;
  switch (cw) {
    case 90: return {h - 1 - y, x};
    case 180: return {w - 1 - x, h - 1 - y};
    case 270: return {y, w - 1 - x};
    default: return {x, y};
  }
}

class FrameReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("clearfit_frames_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  /// Runs ffmpeg (scripts/bootstrap.sh installs it); fails the test when it is missing or fails.
  void ffmpeg(const std::string& args) {
    const std::string cmd = "ffmpeg -nostdin -v error -y " + args + " > " + (dir_ / "ffmpeg.log").string() + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << "ffmpeg failed (install the ffmpeg package): " << cmd;
  }
  fs::path dir_;
};

struct Encoding {
  std::string name, codec, pix_fmt, matrix, range;
  int rotate_cw;
  std::string expect_codec, expect_matrix;
  bool expect_limited;
  int depth;
};

TEST_F(FrameReaderTest, PhoneVideosDecodeToTheirColoursUpright) {
  const fs::path png = dir_ / "patches.png";
  cv::imwrite(png.string(), patch_image());
  const std::vector<Encoding> encodings = {
      {"h264_709_tv_rot90", "libx264 -qp 0", "yuv420p", "bt709", "tv", 90, "h264", "bt709", true, 8},
      {"h264_601_tv_rot270", "libx264 -qp 0", "yuv420p", "bt601", "tv", 270, "h264", "bt601", true, 8},
      {"h264_601_pc", "libx264 -qp 0", "yuvj420p", "bt601", "pc", 0, "h264", "bt601", false, 8},
      {"hevc_709_tv_10bit_rot180", "libx265 -x265-params lossless=1:log-level=error", "yuv420p10le", "bt709", "tv", 180, "hevc",
       "bt709", true, 16},
  };
  for (const Encoding& e : encodings) {
    SCOPED_TRACE(e.name);
    const fs::path coded = dir_ / (e.name + "_coded.mp4"), video = dir_ / (e.name + ".mp4");
    const std::string space = e.matrix == "bt709" ? "bt709" : "smpte170m";
    ffmpeg("-loop 1 -i " + png.string() + " -frames:v 3 -r 10 -vf scale=out_color_matrix=" + e.matrix + ":out_range=" + e.range +
           " -c:v " + e.codec + " -pix_fmt " + e.pix_fmt + " -color_range " + e.range + " -colorspace " + space + " " + coded.string());
    // A rotation tag, which FFmpeg's muxer writes as a display matrix as phones do, set on a copy of the stream.
    ffmpeg("-i " + coded.string() + " -c copy -metadata:s:v:0 rotate=" + std::to_string(e.rotate_cw) + " " + video.string());
    // The orientation a player shows: ffmpeg's own decoder turns frames upright by the display
    // matrix; which quarter turn maps the patches onto its picture?
    const fs::path upright = dir_ / (e.name + "_upright.png");
    ffmpeg("-i " + video.string() + " -frames:v 1 " + upright.string());
    const cv::Mat shown = cv::imread(upright.string());
    int player_cw = -1;
    for (int cw : {0, 90, 180, 270}) {
      if ((cw % 180 != 0 ? 128 : 192) != shown.cols) continue;
      bool all = true;
      for (int i = 0; i < 6; ++i) all = all && cv::norm(cv::Vec3d(shown.at<cv::Vec3b>(rotated_centre(i, cw))) - cv::Vec3d(kPatches[i])) < 30;
      if (all) player_cw = cw;
    }
    ASSERT_GE(player_cw, 0) << "ffmpeg's upright frame matches no quarter turn of the patches";
    FrameReader reader(video);
    const CaptureInfo& info = reader.info();
    EXPECT_EQ(info.codec, e.expect_codec);
    EXPECT_TRUE(info.lossy);
    EXPECT_EQ(info.colour_matrix, e.expect_matrix);
    EXPECT_EQ(info.limited_range, e.expect_limited);
    EXPECT_EQ(info.rotation_deg, player_cw);
    EXPECT_NE(player_cw % 180, e.rotate_cw % 180 == 0 ? 90 : 0);  // the tag turned the picture (by +90 or −90: FFmpeg 5.1's tag sign)
    const bool quarter = player_cw % 180 != 0;
    EXPECT_EQ(info.width, quarter ? 128 : 192);
    EXPECT_EQ(info.height, quarter ? 192 : 128);
    int frames = 0;
    cv::Mat f;
    while (reader.read(f)) {
      ++frames;
      ASSERT_EQ(f.cols, info.width);
      ASSERT_EQ(f.rows, info.height);
      ASSERT_EQ(f.depth(), e.depth == 16 ? CV_16U : CV_8U);
      for (int i = 0; i < 6; ++i) {
        const cv::Point p = rotated_centre(i, player_cw);
        for (int c = 0; c < 3; ++c) {
          const double got = e.depth == 16 ? f.at<cv::Vec3w>(p)[c] / 257.0 : f.at<cv::Vec3b>(p)[c];
          // Lossless YUV: only the RGB → YUV → RGB rounding remains (a wrong matrix errs by up to 20 codes, a wrong range by 15).
          EXPECT_NEAR(got, kPatches[i][c], 2.5) << "patch " << i << " channel " << c;
        }
      }
    }
    EXPECT_EQ(frames, 3);
  }
}

TEST_F(FrameReaderTest, SixteenBitFramesKeepTheirBits) {
  const fs::path folder = dir_ / "deep";
  fs::create_directories(folder);
  cv::Mat img(16, 24, CV_16UC3);
  cv::randu(img, 0, 65536);
  cv::imwrite((folder / "f0.png").string(), img);
  cv::imwrite((folder / "f1.tif").string(), img);
  FrameReader reader(folder);
  EXPECT_EQ(reader.info().bit_depth, 16);
  EXPECT_FALSE(reader.info().lossy);
  cv::Mat f;
  for (int k = 0; k < 2; ++k) {
    ASSERT_TRUE(reader.read(f));
    ASSERT_EQ(f.type(), CV_16UC3);
    EXPECT_EQ(cv::norm(f, img, cv::NORM_INF), 0.0);
  }
  EXPECT_FALSE(reader.read(f));
  // A folder mixing depths is refused, naming the frame.
  cv::Mat shallow;
  img.convertTo(shallow, CV_8U, 1.0 / 257);
  cv::imwrite((folder / "f2.png").string(), shallow);
  FrameReader mixed(folder);
  mixed.read(f);
  mixed.read(f);
  EXPECT_THROW(mixed.read(f), InputError);
}

// A flat grey capture whose press raises the 16-bit code by 100 (0.39 of an 8-bit step) with
// noise of 0.08 step: read at 8 bits both phases round to the same code and the press
// vanishes; read at 16 bits the averages carry it.
TEST_F(FrameReaderTest, SixteenBitPressBelowOneEightBitStepIsMeasured) {
  const int w = 96, h = 64, frames = 20;
  const int level = 160 * 257, step = 100;  // 16-bit codes
  const cv::Rect disk(36, 20, 24, 24);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 20.0);
  auto write = [&](const std::string& name, bool pressed) {
    const fs::path folder = dir_ / name;
    fs::create_directories(folder);
    for (int t = 0; t < frames; ++t) {
      cv::Mat img(h, w, CV_16UC3);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const double code = level + (pressed && disk.contains({x, y}) ? step : 0) + noise(rng);
          const auto c = static_cast<std::uint16_t>(std::lround(std::clamp(code, 0.0, 65535.0)));
          img.at<cv::Vec3w>(y, x) = cv::Vec3w(c, c, c);
        }
      char file[32];
      std::snprintf(file, sizeof file, "f%04d.png", t);
      cv::imwrite((folder / file).string(), img);
    }
    return folder;
  };
  CaptureReadOptions o;
  o.register_motion = false;
  o.colour = false;
  MotionReference ref;
  const CaptureSums base = read_capture(write("base", false), o, ref);
  const CaptureSums worn = read_capture(write("worn", true), o, ref);
  EXPECT_EQ(base.info.bit_depth, 16);
  const PhaseAverage a0 = average_window(base, last_frames(base, frames), frames, false);
  const PhaseAverage a1 = average_window(worn, last_frames(worn, frames), frames, false);
  const double expected = srgb::to_linear((level + step) / 65535.0) - srgb::to_linear(level / 65535.0);
  cv::Mat diff = a1.mean - a0.mean;
  const double inside = cv::mean(diff(disk))[0];
  cv::Mat outside_mask = cv::Mat::ones(diff.size(), CV_8U);
  outside_mask(disk).setTo(0);
  const double outside = cv::mean(diff, outside_mask)[0];
  EXPECT_NEAR(inside, expected, 0.05 * expected);
  EXPECT_NEAR(outside, 0.0, 0.05 * expected);
  // Per pixel the step stands out of the averages' own noise.
  const double sigma = std::sqrt(cv::mean(a0.variance(disk))[0] + cv::mean(a1.variance(disk))[0]);
  EXPECT_GT(expected / sigma, 5.0);
  EXPECT_NEAR(base.mean_code.front(), 160.0, 0.5);  // statistics in 8-bit units
}

// Converting only a region (FrameReader::set_region) gives the whole frame's values there, bit for
// bit, for the layouts cameras and clearfit's simulator write: 4:2:0 (H.264), 4:2:0 at 10 bits
// (HEVC), packed RGB (huffyuv) and 4:2:2 (FFV1); the rest of the frame is black (beyond a margin of 10 px),
// and the last frame can still be had whole. The region's corners are odd, off the chroma blocks.
TEST_F(FrameReaderTest, ARegionIsConvertedAsTheWholeFrameIs) {
  cv::Mat noise(120, 200, CV_8UC3);
  cv::RNG(11).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(), 1.2);  // colour that varies within a chroma block
  const fs::path png = dir_ / "noise.png";
  cv::imwrite(png.string(), noise);
  const std::vector<std::pair<std::string, std::string>> encodings = {
      {"h264.mp4", "libx264 -qp 0 -pix_fmt yuv420p"},
      {"hevc10.mp4", "libx265 -x265-params lossless=1:log-level=error -pix_fmt yuv420p10le"},
      {"huffyuv.mkv", "huffyuv -pix_fmt bgra"},
      {"ffv1.mkv", "ffv1 -pix_fmt yuv422p"},
  };
  const cv::Rect region(37, 21, 101, 67);
  for (const auto& [name, codec] : encodings) {
    SCOPED_TRACE(name);
    const fs::path video = dir_ / name;
    ffmpeg("-loop 1 -i " + png.string() + " -frames:v 3 -r 10 -c:v " + codec + " " + video.string());
    FrameReader whole(video), part(video);
    part.set_region(region);
    cv::Mat a, b;
    int frames = 0;
    while (whole.read(a)) {
      ASSERT_TRUE(part.read(b));
      ASSERT_EQ(a.type(), b.type());
      ASSERT_EQ(a.size(), b.size());
      EXPECT_EQ(cv::norm(a(region), b(region), cv::NORM_INF), 0.0) << "frame " << frames;
      cv::Mat outside = b.clone();
      outside(cv::Rect(region.x - 10, region.y - 10, region.width + 20, region.height + 20)).setTo(0);
      EXPECT_EQ(cv::norm(outside, cv::NORM_INF), 0.0) << "frame " << frames;
      ++frames;
    }
    EXPECT_FALSE(part.read(b));
    EXPECT_EQ(frames, 3);
    EXPECT_EQ(cv::norm(part.whole_last_frame(), a, cv::NORM_INF), 0.0);
  }
}

}  // namespace
}  // namespace clearfit
