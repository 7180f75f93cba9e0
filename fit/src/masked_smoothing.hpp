#pragma once
// Gaussian smoothing over a mask's pixels only (normalised convolution), shared by the glare check and
// the baseline photometry.
#include <opencv2/core.hpp>

namespace clearfit {

/// Mean of `image` (CV_32F) over the pixels where `mask` (CV_8U, 255 = use) is set, within a Gaussian of
/// `sigma_px`; `border` is OpenCV's border mode for both convolutions.
cv::Mat masked_gaussian(const cv::Mat& image, const cv::Mat& mask, double sigma_px, int border);

}  // namespace clearfit
