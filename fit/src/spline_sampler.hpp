#pragma once
// Interpolation of an image by a B-spline of order 3 or 5, with the interpolant's exact gradient, for the
// motion registration (registration.cpp). Method: Unser, "Splines: a perfect fit for signal and image
// processing", IEEE Signal Processing Magazine 16(6), 1999: the image's spline coefficients come from a
// recursive prefilter (mirror boundaries), after which every value and gradient is a separable sum of
// order + 1 taps per axis. The prefiltered spline interpolates the samples.
//
// Why not Catmull-Rom (cubic convolution). On skin texture near 0.28 cycles/px (fingerprint ridges of
// 0.31 mm at 12 px/mm) Catmull-Rom misplaces a shifted sinusoid by up to 0.059 px; the cubic B-spline by
// 0.012 px, the quintic by 0.002 px (phase error of the interpolant at the worst fractional offset).
// The gradient of the interpolant is also what a Gauss-Newton step needs: a finite difference (Scharr)
// reads that frequency's slope at 0.4 of its value, so the steps overshoot 2.4-fold and cycle.
#include <opencv2/core.hpp>

#include <vector>

namespace clearfit {

class SplineSampler {
 public:
  explicit SplineSampler(int order);  ///< 3 or 5; throws std::invalid_argument otherwise
  int order() const { return order_; }
  /// Taps read before floor(x) (1 for cubic, 2 for quintic) and after it (2, 3).
  int before() const { return order_ / 2; }
  int after() const { return order_ - order_ / 2; }
  /// The spline coefficients of `image` (CV_32F; at least 2 × 2), in place.
  void coefficients(cv::Mat& image) const;
  /// The interpolant of the coefficients `coef` at (bx + dx, by + dy) for each element of the position
  /// maps `bx`, `by` (CV_32F, px in `coef`), into `out`; with `gx`, `gy`, also its gradient there.
  /// `uniform`: the positions are a grid moved by one offset (bx, by the grid's x and y), sampled as one
  /// separable filter. Returns false when a position's taps leave `coef`.
  bool sample(const cv::Mat& coef, const cv::Mat& bx, const cv::Mat& by, double dx, double dy, bool uniform, cv::Mat& out,
              cv::Mat* gx = nullptr, cv::Mat* gy = nullptr) const;
  /// The interpolant's gradient at every pixel of `coef` (at the samples themselves), with mirrored borders.
  void gradient(const cv::Mat& coef, cv::Mat& gx, cv::Mat& gy) const;

 private:
  /// Weights of the order + 1 taps from floor(x) − before() for x's fraction t in [0, 1), and their derivatives
  /// unless `dw` is null.
  void weights(float t, float* w, float* dw) const;
  int order_;
  /// weights() at t = i / 1024, i = 0..1024: per node the order + 1 weights, then their derivatives (one table per
  /// order, built once). The per-position path interpolates it linearly (error ~1e-7, a float's rounding): the
  /// quintic's closed form at each position cost 14 % of the bundled sample's assessment.
  const std::vector<float>* table_ = nullptr;
};

}  // namespace clearfit
