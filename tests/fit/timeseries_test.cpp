// The time series recorder (bounded memory: bins merge in pairs, their means kept) and
// the time-constant fits, on series generated here with known onset and refill.
#include <clearfit/fit/srgb.hpp>
#include <clearfit/fit/timeseries.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace clearfit {
namespace {

/// A BGR8 frame of one green code everywhere.
cv::Mat flat_frame(int code, cv::Size size = {64, 48}) { return cv::Mat(size, CV_8UC3, cv::Scalar(0, code, 0)); }

TEST(TimeSeriesRecorder, BoundedMemoryKeepsTheMeans) {
  TimeSeriesOptions o;
  o.cell_px = 8;
  o.max_mb = 0.001;  // below the floor: 16 bins
  const cv::Rect roi(8, 8, 40, 24);
  TimeSeriesRecorder rec(roi, o);
  EXPECT_EQ(rec.cells(), cv::Size(5, 3));
  const int frames = 1000;
  for (int f = 0; f < frames; ++f) rec.add(flat_frame(f % 256), {0, 0});
  EXPECT_EQ(rec.frames(), frames);
  EXPECT_LE(rec.bins(), 16);
  EXPECT_EQ(rec.bin_frames(), 64);  // 1000 frames in at most 16 bins: 1 → 2 → ... → 64
  EXPECT_EQ(rec.bins(), (frames + 63) / 64);
  EXPECT_LE(rec.bytes(), 16 * rec.cell_count() * sizeof(float) + 16 * sizeof(int) + 64);
  const float* lut = srgb::to_linear_table8();
  for (int b = 0; b < rec.bins(); ++b) {
    double expected = 0;
    const int f0 = b * 64, f1 = std::min(frames, f0 + 64);
    for (int f = f0; f < f1; ++f) expected += lut[f % 256];
    expected /= f1 - f0;
    ASSERT_EQ(rec.count(b), f1 - f0);
    for (int c = 0; c < static_cast<int>(rec.cell_count()); ++c) EXPECT_NEAR(rec.mean(b, c), expected, 1e-5) << "bin " << b;
  }
}

TEST(TimeSeriesRecorder, CellsFollowTheShift) {
  // A bright square at (24..31, 16..23) of the frame; with shift (8, 0) it lands in cell (1, 1) of roi (0, 0).
  cv::Mat frame = flat_frame(40);
  frame(cv::Rect(24, 16, 8, 8)).setTo(cv::Scalar(0, 200, 0));
  TimeSeriesOptions o;
  o.cell_px = 8;
  TimeSeriesRecorder rec(cv::Rect(8, 8, 48, 32), o);
  rec.add(frame, {8, 0});
  const float* lut = srgb::to_linear_table8();
  EXPECT_NEAR(rec.mean(0, 1 * rec.cells().width + 1), lut[200], 1e-6);
  EXPECT_NEAR(rec.mean(0, 1 * rec.cells().width + 2), lut[40], 1e-6);
}

/// Bins of `m` frames from frame 0 to `frames` of y(t) (averaged over the bin's frames) plus noise.
BinnedSeries make_series(const std::function<double(double)>& y, int frames, int m, double fps, double noise, unsigned seed,
                         int from = 0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  BinnedSeries s;
  s.fps = fps;
  for (int f = from; f + m <= frames; f += m) {
    double v = 0;
    for (int k = f; k < f + m; ++k) v += y(k / fps) + n(rng);
    s.y.push_back(v / m);
    s.first.push_back(f);
    s.count.push_back(m);
  }
  return s;
}

TEST(TimeConstantFits, RefillRecoversTau) {
  // τ between 0.3 and 3 s, sampled per frame and per 4 frames, with noise of 2 % of the step per frame: within 10 %.
  for (double tau : {0.3, 0.37, 0.85, 1.9, 2.8, 3.0})
    for (int m : {1, 4}) {
      const double fps = 30, tr = 2.0, a = 0.05, c = 0.002;
      auto y = [&](double t) { return t < tr ? a + c : c + a * std::exp(-(t - tr) / tau); };
      const int frames = static_cast<int>((tr + 4 * tau) * fps);
      const BinnedSeries s = make_series(y, frames, m, fps, 0.001, 7, static_cast<int>(tr * fps));
      const TimeConstantFit f = fit_refill(s, tr);
      ASSERT_TRUE(f.fitted) << f.note;
      EXPECT_NEAR(f.tau_s, tau, 0.10 * tau) << "m " << m;
      EXPECT_GT(f.tau_sigma_s, 0);
      EXPECT_LT(std::abs(f.tau_s - tau), 5 * f.tau_sigma_s + 0.01 * tau);
      EXPECT_NEAR(f.offset, c, 0.003);
    }
}

TEST(TimeConstantFits, OnsetWithinAFrame) {
  for (double t0 : {1.234, 2.05})
    for (double tau : {0.15, 0.4}) {
      const double fps = 60;
      auto y = [&](double t) { return t > t0 ? 0.04 * (1 - std::exp(-(t - t0) / tau)) : 0.0; };
      const BinnedSeries s = make_series(y, static_cast<int>((t0 + 3) * fps), 1, fps, 0.0008, 3);
      const TimeConstantFit f = fit_onset(s, 1.5);
      ASSERT_TRUE(f.fitted) << f.note;
      EXPECT_NEAR(f.t0_s, t0, 1 / fps);
      EXPECT_NEAR(f.tau_s, tau, 0.1 * tau);
      EXPECT_NEAR(f.amplitude, 0.04, 0.002);
    }
}

TEST(TimeConstantFits, TooFewSamplesSaySo) {
  BinnedSeries s;
  s.fps = 30;
  s.y = {0.1, 0.05, 0.02};
  s.first = {0, 1, 2};
  s.count = {1, 1, 1};
  const TimeConstantFit f = fit_refill(s, 0.0);
  EXPECT_FALSE(f.fitted);
  EXPECT_NE(f.note.find("too few samples"), std::string::npos);
  EXPECT_FALSE(fit_onset(s, 0.0).fitted);
}

TEST(TimeSeriesOptions, RulesNameTheKey) {
  TimeSeriesOptions o;
  o.cell_px = 0;
  try {
    o.validate();
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("timeseries.cell_px"), std::string::npos);
  }
}

}  // namespace
}  // namespace clearfit
