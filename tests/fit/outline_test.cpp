// The contact surface's outline in an average (fit/outline.hpp), against images drawn with a known move.
#include <clearfit/fit/outline.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

namespace clearfit {
namespace {

constexpr int kWidth = 260, kHeight = 150;

/// Inside the rounded rectangle the map sees (centre, half sizes, corner radius), at point (x, y); `grow_y` px
/// more above and below.
bool inside(double x, double y, double cx, double cy, double grow_y = 0) {
  const double hx = 100, hy = 50 + grow_y, r = 20;
  const double qx = std::max(std::abs(x - cx) - (hx - r), 0.0), qy = std::max(std::abs(y - cy) - (hy - r), 0.0);
  return qx * qx + qy * qy <= r * r;
}

/// The map's seen share: of a 4 × 4 grid of points over each pixel, those inside the outline at its place
/// (as compute_refraction_map measures it with rays; the images below are drawn 8 × 8).
cv::Mat seen_mask() {
  cv::Mat1f seen(kHeight, kWidth, 0.f);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      int n = 0;
      for (int b = 0; b < 4; ++b)
        for (int a = 0; a < 4; ++a) n += inside(x + (a + 0.5) / 4 - 0.5, y + (b + 0.5) / 4 - 0.5, 130, 75);
      seen(y, x) = static_cast<float>(n) / 16;
    }
  return seen;
}

/// An average: skin (a smooth random texture moved by `texture_shift`) seen inside the outline moved by
/// `outline_shift` (and taller by 2 `grow_y`), a darker background beside it, a quadratic fall-off of the light,
/// 8 × 8 supersampled.
cv::Mat average(const Vec2& outline_shift, const Vec2& texture_shift, double background, std::uint64_t seed, double grow_y = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI), freq(0.5, 2.0);
  double fx[12], fy[12], ph[12];
  for (int k = 0; k < 12; ++k) fx[k] = freq(rng) * (k % 2 ? 1 : -1), fy[k] = freq(rng), ph[k] = phase(rng);
  cv::Mat img(kHeight, kWidth, CV_32F);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      double sum = 0;
      for (int b = 0; b < 8; ++b)
        for (int a = 0; a < 8; ++a) {
          const double sx = x + (a + 0.5) / 8 - 0.5, sy = y + (b + 0.5) / 8 - 0.5;
          const bool skin = inside(sx - outline_shift.x(), sy - outline_shift.y(), 130, 75, grow_y);
          double texture = 0;
          for (int k = 0; k < 12; ++k) texture += std::sin(fx[k] * (sx - texture_shift.x()) + fy[k] * (sy - texture_shift.y()) + ph[k]);
          sum += skin ? 0.3 * (1 + 0.02 * texture) : background;  // skin texture of about 5 %
        }
      const double r2 = ((x - 130.0) * (x - 130.0) + (y - 75.0) * (y - 75.0)) / (130.0 * 130 + 75.0 * 75);
      img.at<float>(y, x) = static_cast<float>(sum / 64 * (1 - 0.3 * r2));
    }
  return img;
}

TEST(Outline, FindsTheOutlinesMoveNotTheTexturesSlide) {
  // The camera moved by (0.43, −0.61) px; the skin under the part slid by another (1.2, 0.7) px.
  const Vec2 move(0.43, -0.61), slide(1.2, 0.7);
  const OutlineFit f = locate_outline(average(move, move + slide, 0.06, 3), seen_mask(), {}, OutlineOptions{});
  ASSERT_TRUE(f.found) << f.problem << " shift " << f.shift_px.transpose() << " sigma " << f.sigma_px.transpose() << " rot " << f.rotation_rad;
  EXPECT_NEAR(f.shift_px.x(), move.x(), 0.03);
  EXPECT_NEAR(f.shift_px.y(), move.y(), 0.03);
  EXPECT_LT(f.sigma_px.maxCoeff(), 0.05);
  EXPECT_NEAR(f.rotation_rad, 0.0, 1e-3);
  EXPECT_GT(f.contrast, 0.5);
}

TEST(Outline, NoMoveReadsNoMove) {
  const OutlineFit f = locate_outline(average(Vec2::Zero(), Vec2(2.0, -1.0), 0.06, 5), seen_mask(), {}, OutlineOptions{});
  ASSERT_TRUE(f.found) << f.problem;
  EXPECT_LT(f.shift_px.norm(), 0.03);
}

TEST(Outline, AnOutlineDrawnLargerIsNoMove) {
  // The top and bottom edges drawn 0.25 px outside the map's (as a render that draws whole the edge rows the
  // map sees 3/4 of), the part moved by (0.3, −0.2) px: the move is read, the stretch apart. A shift alone
  // settled on one edge (the slab of cli/SigmaCoverage: 0.17 px towards the top).
  const Vec2 move(0.3, -0.2);
  const OutlineFit f = locate_outline(average(move, move, 0.06, 11, 0.25), seen_mask(), {}, OutlineOptions{});
  ASSERT_TRUE(f.found) << f.problem;
  EXPECT_NEAR(f.shift_px.x(), move.x(), 0.03);
  EXPECT_NEAR(f.shift_px.y(), move.y(), 0.03) << "stretch " << f.stretch.transpose();
  EXPECT_GT(f.stretch.y(), 0.6 * 0.25 / 50);  // the corners move by less than the stretch would move them
  EXPECT_NEAR(f.stretch.x(), 0.0, 0.001);
}

TEST(Outline, SkinAllAroundIsNoOutline) {
  // Beside the part the camera sees skin as bright as through it: no step, nothing to measure.
  const OutlineFit f = locate_outline(average(Vec2(0.5, 0.5), Vec2::Zero(), 0.3, 7), seen_mask(), {}, OutlineOptions{});
  EXPECT_FALSE(f.found);
  EXPECT_FALSE(f.problem.empty());
}

TEST(Outline, OptionsAreChecked) {
  OutlineOptions o;
  o.band_px = 0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.min_contrast = 1.5;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  EXPECT_NO_THROW(OutlineOptions{}.validate());
}

}  // namespace
}  // namespace clearfit
