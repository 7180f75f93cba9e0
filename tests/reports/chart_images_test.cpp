// Chart heatmap PNGs: read back with OpenCV and checked pixel by pixel against
// the colormap, the texel layout (v up), the hotspot outlines and the bars.
#include <clearfit/reports/chart_images.hpp>
#include <clearfit/reports/colormap.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

namespace fs = std::filesystem;

namespace clearfit {
namespace {

constexpr int kW = 60, kH = 40;  // texels
constexpr double kTexelMm = 0.25;

// A ramp in u from 0 to 30 kPa, NaN on texels i in [50, 54], j in [30, 34].
ChartField ramp_field() {
  ChartField f;
  f.grid.width = kW;
  f.grid.height = kH;
  f.grid.texel_mm = kTexelMm;
  f.value.resize(f.grid.size());
  for (int j = 0; j < kH; ++j) {
    for (int i = 0; i < kW; ++i) {
      bool hole = i >= 50 && i <= 54 && j >= 30 && j <= 34;
      f.value[f.grid.index(i, j)] = hole ? NAN : static_cast<float>(30.0 * i / (kW - 1));
    }
  }
  return f;
}

Rgb8 pixel(const cv::Mat& img, int x, int y) {
  cv::Vec3b p = img.at<cv::Vec3b>(y, x);
  return {p[2], p[1], p[0]};
}

// Image pixel at the centre of texel (i, j): v up, so grid row j is drawn at row H-1-j.
cv::Point texel_centre(const ChartImageLayout& L, int i, int j) {
  const double s = static_cast<double>(L.chart_w) / kW;
  return {L.chart_x + static_cast<int>((i + 0.5) * s), L.chart_y + static_cast<int>((kH - 1 - j + 0.5) * s)};
}

bool black_or_white(const Rgb8& c) { return c == Rgb8{0, 0, 0} || c == Rgb8{255, 255, 255}; }

class ChartImages : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("clearfit_chart_images_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure() && std::getenv("CLEARFIT_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(dir_);
  }
  fs::path dir_;
};

TEST_F(ChartImages, ChartColourBarAndScaleBarFollowTheInput) {
  const ChartField f = ramp_field();
  ChartImageInput in;
  in.field = &f;
  in.range_lo = 0;
  in.range_hi = 30;
  in.unit = "kPa";
  in.title = "Pressure on the contact surface";
  const ChartImageLayout L = write_chart_heatmap_png(in, dir_ / "chart.png");
  const cv::Mat img = cv::imread((dir_ / "chart.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, L.width);
  EXPECT_EQ(img.rows, L.height);
  EXPECT_GE(L.chart_w, 800);
  EXPECT_EQ(L.chart_w * kH, L.chart_h * kW);  // square texels
  EXPECT_NEAR(L.px_per_mm, L.chart_w / (kW * kTexelMm), 1e-9);
  EXPECT_LT(L.bar_x + L.bar_w, L.width);

  const Colormap& cm = Colormap::get("viridis");
  // Texels: the colormap of their value; the NaN hole in the no-data grey.
  for (int i : {0, 7, 31, 59}) {
    for (int j : {0, 20, 39}) {
      cv::Point p = texel_centre(L, i, j);
      EXPECT_EQ(pixel(img, p.x, p.y), cm.srgb8(i / double(kW - 1))) << i << "," << j;
    }
  }
  cv::Point hole = texel_centre(L, 52, 32);
  EXPECT_EQ(pixel(img, hole.x, hole.y), cm.no_data_srgb8());
  // v up: the hole (rows 30..34 of 40) is in the upper part of the picture.
  EXPECT_LT(hole.y, L.chart_y + L.chart_h / 2);

  // Colour bar rows: range_hi at the top, range_lo at the bottom, linear between.
  for (int y = 0; y < L.bar_h; y += 7) {
    EXPECT_EQ(pixel(img, L.bar_x + L.bar_w / 2, L.bar_y + y), cm.srgb8(1.0 - double(y) / (L.bar_h - 1))) << y;
  }
  EXPECT_EQ(L.ticks, (std::vector<double>{0, 5, 10, 15, 20, 25, 30}));

  // Scale bar: a 1-2-5 length no longer than a fifth of the chart, drawn black.
  EXPECT_DOUBLE_EQ(L.scale_bar_mm, 2.0);  // chart 15 mm wide → 3 mm → 2 mm
  EXPECT_NEAR(L.scale_bar_px, 2.0 * L.px_per_mm, 0.5);
  EXPECT_EQ(pixel(img, L.scale_bar_x + L.scale_bar_px / 2, L.scale_bar_y), (Rgb8{0, 0, 0}));
  EXPECT_EQ(pixel(img, L.scale_bar_x + L.scale_bar_px + 3, L.scale_bar_y), (Rgb8{255, 255, 255}));

  // No outlines without labels: no black or white pixel inside the chart.
  int marks = 0;
  for (int y = L.chart_y; y < L.chart_y + L.chart_h; ++y) {
    for (int x = L.chart_x; x < L.chart_x + L.chart_w; ++x) marks += black_or_white(pixel(img, x, y));
  }
  EXPECT_EQ(marks, 0);
}

TEST_F(ChartImages, HotspotRegionsAreOutlined) {
  const ChartField f = ramp_field();
  std::vector<int> labels(f.grid.size(), 0);
  for (int j = 5; j <= 15; ++j) {
    for (int i = 10; i <= 20; ++i) labels[f.grid.index(i, j)] = 3;
  }
  ChartImageInput in;
  in.field = &f;
  in.hotspot_labels = labels;
  in.unit = "kPa";
  const ChartImageLayout L = write_chart_heatmap_png(in, dir_ / "hot.png");
  const cv::Mat img = cv::imread((dir_ / "hot.png").string(), cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, L.width);

  const double s = static_cast<double>(L.chart_w) / kW;
  const int left = L.chart_x + static_cast<int>(10 * s), right = L.chart_x + static_cast<int>(21 * s) - 1;
  const int top = L.chart_y + static_cast<int>((kH - 16) * s),
            bottom = L.chart_y + static_cast<int>((kH - 5) * s) - 1;
  const int mid_y = (top + bottom) / 2, mid_x = (left + right) / 2;
  // The outline runs along all four sides of the region ...
  auto marked_near = [&](int x, int y, bool horizontal) {
    for (int d = -2; d <= 2; ++d) {
      if (black_or_white(horizontal ? pixel(img, x + d, y) : pixel(img, x, y + d))) return true;
    }
    return false;
  };
  EXPECT_TRUE(marked_near(left, mid_y, true));
  EXPECT_TRUE(marked_near(right, mid_y, true));
  EXPECT_TRUE(marked_near(mid_x, top, false));
  EXPECT_TRUE(marked_near(mid_x, bottom, false));
  // ... the inside keeps its colour, and away from the region nothing is drawn.
  const Colormap& cm = Colormap::get("viridis");
  cv::Point inside = texel_centre(L, 15, 10);
  EXPECT_EQ(pixel(img, inside.x, inside.y), cm.srgb8(15.0 / (kW - 1)));
  int marks_far = 0;
  for (int x = L.chart_x; x < L.chart_x + L.chart_w; ++x) {
    cv::Point p = texel_centre(L, 0, 35);
    marks_far += black_or_white(pixel(img, x, p.y));
  }
  EXPECT_EQ(marks_far, 0);
  // The id is written beside the region: near-white (anti-aliased) text pixels to its right.
  int text = 0;
  for (int y = top; y < top + 30; ++y) {
    for (int x = right + 3; x < right + 40; ++x) {
      Rgb8 c = pixel(img, x, y);
      text += c.r > 200 && c.g > 200 && c.b > 200;
    }
  }
  EXPECT_GT(text, 5);
}

TEST_F(ChartImages, DivergingSignalWithoutUnit) {
  ChartField f = ramp_field();
  for (float& v : f.value) v = (v - 15) * 0.001f;  // signed, unitless
  ChartImageInput in;
  in.field = &f;
  in.colormap = "coolwarm";
  in.range_lo = -0.015;
  in.range_hi = 0.015;
  in.title = "Difference";
  const ChartImageLayout L = write_chart_heatmap_png(in, dir_ / "diff.png");
  const cv::Mat img = cv::imread((dir_ / "diff.png").string(), cv::IMREAD_COLOR);
  ASSERT_EQ(img.rows, L.height);
  const Colormap& cm = Colormap::get("coolwarm");
  EXPECT_EQ(pixel(img, L.bar_x + 3, L.bar_y), cm.srgb8(1.0));
  EXPECT_EQ(pixel(img, L.bar_x + 3, L.bar_y + L.bar_h - 1), cm.srgb8(0.0));
  EXPECT_NEAR(L.ticks.front(), -0.015, 1e-12);
  EXPECT_EQ(L.ticks.size(), 7u);
  EXPECT_NE(std::find(L.ticks.begin(), L.ticks.end(), 0.0), L.ticks.end());
}

TEST(NiceTicks, OneTwoFiveSteps) {
  EXPECT_EQ(nice_ticks(0, 30), (std::vector<double>{0, 5, 10, 15, 20, 25, 30}));
  std::vector<double> t = nice_ticks(0, 0.05);
  ASSERT_EQ(t.size(), 6u);
  EXPECT_NEAR(t[1], 0.01, 1e-12);
  EXPECT_EQ(nice_ticks(3.7, 3.71).size() >= 2, true);
  EXPECT_THROW(nice_ticks(1, 1), std::invalid_argument);
}

TEST(ChartImagesInput, BadInputIsRefusedAndNothingIsWritten) {
  const ChartField f = ramp_field();
  const fs::path path =
      fs::temp_directory_path() / ("clearfit_chart_images_bad_" + std::to_string(::getpid()) + ".png");
  ChartImageInput in;
  in.field = &f;
  in.hotspot_labels.assign(5, 1);
  EXPECT_THROW(write_chart_heatmap_png(in, path), std::invalid_argument);
  in.hotspot_labels.clear();
  in.range_hi = in.range_lo;
  EXPECT_THROW(write_chart_heatmap_png(in, path), std::invalid_argument);
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace clearfit
