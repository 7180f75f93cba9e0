// Half-resolution blue per chunk and per-chunk gains (see photometric.hpp).
#include <clearfit/fit/photometric.hpp>
#include <clearfit/fit/srgb.hpp>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace clearfit {

cv::Size half_grid(cv::Size roi) { return {(roi.width + 1) / 2, (roi.height + 1) / 2}; }

void accumulate_half_blue(const cv::Mat& bgr, const cv::Rect& roi, cv::Point d, cv::Mat& sum) {
  const float* lut = srgb::to_linear_table8();
  const int w = bgr.cols, h = bgr.rows;
  const cv::Size half = half_grid(roi.size());
  CV_Assert(sum.type() == CV_32F && sum.size() == half);
  tbb::parallel_for(tbb::blocked_range<int>(0, half.height, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int j = rows.begin(); j < rows.end(); ++j) {
      const auto* src = bgr.ptr<cv::Vec3b>(std::clamp(roi.y + 2 * j + d.y, 0, h - 1));
      float* dst = sum.ptr<float>(j);
      const int x0 = roi.x + d.x;
      for (int i = 0; i < half.width; ++i) {
        const int a = std::clamp(x0 + 2 * i, 0, w - 1), b = std::clamp(x0 + 2 * i + 1, 0, w - 1);
        dst[i] += 0.5f * (lut[src[a][0]] + lut[src[b][0]]);
      }
    }
  });
}

void accumulate_red(const cv::Mat& bgr, const cv::Rect& roi, cv::Point d, cv::Mat& sum) {
  const float* lut = srgb::to_linear_table8();
  const int w = bgr.cols, h = bgr.rows;
  CV_Assert(sum.type() == CV_32F && sum.size() == roi.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, roi.height, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const auto* src = bgr.ptr<cv::Vec3b>(std::clamp(roi.y + y + d.y, 0, h - 1));
      float* dst = sum.ptr<float>(y);
      const int x0 = roi.x + d.x, lo = std::clamp(-x0, 0, roi.width), hi = std::clamp(w - x0, lo, roi.width);
      for (int x = 0; x < lo; ++x) dst[x] += lut[src[0][2]];
      for (int x = lo; x < hi; ++x) dst[x] += lut[src[x0 + x][2]];
      for (int x = hi; x < roi.width; ++x) dst[x] += lut[src[w - 1][2]];
    }
  });
}

ChunkGains estimate_chunk_gains(const std::vector<cv::Mat>& sums, const std::vector<int>& counts, int first, int end,
                                const cv::Mat& mean) {
  ChunkGains g;
  // A sparse grid of about 20 000 pixels: the median of as many ratios is exact to ~1e-4.
  const int step = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(mean.total()) / 20000.0)));
  std::vector<cv::Point> pixels;
  for (int y = step / 2; y < mean.rows; y += step)
    for (int x = step / 2; x < mean.cols; x += step)
      if (mean.at<float>(y, x) > 1e-3f) pixels.emplace_back(x, y);
  std::vector<double> sigmas;
  for (int k = first; k < end; ++k) {
    double gain = 1;
    if (counts[k] > 0 && pixels.size() >= 16) {
      std::vector<float> r;
      r.reserve(pixels.size());
      for (const cv::Point& p : pixels) r.push_back(sums[k].at<float>(p) / counts[k] / mean.at<float>(p));
      const auto mid = r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2);
      std::nth_element(r.begin(), mid, r.end());
      gain = *mid;
      std::vector<float> dev;
      dev.reserve(r.size());
      for (float v : r) dev.push_back(std::abs(v - static_cast<float>(gain)));
      const auto dmid = dev.begin() + static_cast<std::ptrdiff_t>(dev.size() / 2);
      std::nth_element(dev.begin(), dmid, dev.end());
      sigmas.push_back(1.4826 * 1.2533 * *dmid / std::sqrt(static_cast<double>(r.size())));  // median's σ
    }
    if (!(gain > 0) || !std::isfinite(gain)) gain = 1;
    g.gain.push_back(gain);
  }
  if (!g.gain.empty()) {
    g.min = *std::min_element(g.gain.begin(), g.gain.end());
    g.max = *std::max_element(g.gain.begin(), g.gain.end());
  }
  if (!sigmas.empty()) {
    std::nth_element(sigmas.begin(), sigmas.begin() + static_cast<std::ptrdiff_t>(sigmas.size() / 2), sigmas.end());
    g.sigma = sigmas[sigmas.size() / 2];
  }
  return g;
}

}  // namespace clearfit
