#pragma once
// Colour and exposure of real captures (issue 12, item 5, and the colour the
// glare mask needs, item 4).
//
// Colour kept per chunk. Green is summed at full resolution (capture.hpp);
// blue, which glare (white light) raises far more than blanching does, is
// summed at half resolution: half-grid pixel (i, j) is the mean linear blue of
// roi pixels (2i, 2j) and (2i + 1, 2j) (even rows only: the rows the frame
// statistics already read), at the frame's integer motion shift. That is a
// quarter of the green's memory and about a fifth of its work.
//
// Exposure, white balance and flicker. Within an averaging window the skin
// does not change, so each chunk (5 frames) is the window's mean times a gain
// (exposure steps and drifts, white balance, flicker, pulse). The gain of a
// chunk is the median, over a sparse grid of the seen pixels, of chunk mean /
// window mean (robust to glare, saturation and anything local); each chunk is
// divided by its gain before the window's mean and the noise from the spread
// of the chunks are formed, so a gain step neither inflates the noise nor
// shrinks hotspots. Gains between the phases cancel in the blanching
// signal's reference normalisation (blanching.hpp).
#include <opencv2/core.hpp>

#include <vector>

namespace clearfit {

/// The half-resolution grid of a roi (see the file comment).
cv::Size half_grid(cv::Size roi);

/// Adds the frame's linear blue at integer shift d (the roi pixel p reads
/// the frame at p + d, clamped at the image edge) to `sum` (CV_32F, half_grid).
void accumulate_half_blue(const cv::Mat& bgr, const cv::Rect& roi, cv::Point d, cv::Mat& sum);

/// Adds the frame's linear red at integer shift d, at full resolution, to `sum`
/// (CV_32F, roi size): the texture the phases are registered on
/// (phase_registration.hpp; at half resolution its finest lines alias).
void accumulate_red(const cv::Mat& bgr, const cv::Rect& roi, cv::Point d, cv::Mat& sum);

/// Per-chunk gains of a window (see the file comment).
struct ChunkGains {
  std::vector<double> gain;   ///< per chunk of the window, relative to the window's mean
  double min = 1, max = 1;    ///< extremes
  double sigma = 0;           ///< typical 1-σ uncertainty of a chunk's gain (robust spread of the ratios / √n)
};

/// Gains of chunks `first` .. `end` − 1 given their sums and frame counts,
/// relative to `mean` (CV_32F, the window's plain mean of the same pixels).
/// Pixels darker than 1e-3 are ignored.
ChunkGains estimate_chunk_gains(const std::vector<cv::Mat>& sums, const std::vector<int>& counts, int first, int end,
                                const cv::Mat& mean);

}  // namespace clearfit
