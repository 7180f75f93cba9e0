#pragma once
// Where the contact surface's outline lies in a phase's average: the camera's move between the phases.
//
// Each capture is registered to its own first frame, so a move of the camera (or of the arm with the part
// on it) between the not-worn capture's first frame and the worn one's is not undone by the per-frame
// registration. The skin's texture cannot tell that move from the skin sliding under the part: both move
// the texture. The part's outline can: the edge of the skin seen through the contact surface moves with
// the camera, not with the skin. So each average is fitted with the outline the refraction map predicts
// (the share of each pixel that sees the skin, a step to a sixteenth of a pixel), displaced by a shift: J(x) ≈ a(x) + b(x)·S(x − t) over a band around the
// outline, J the average and S the seen mask, both blurred by smoothing_px, a and b affine in the image
// (illumination fall-off: a and b quadratic in the image; affine left 0.05 px of opposite biases at the
// band's two ends), t and a small rotation and stretch (per axis) about the seen region's centroid by Gauss–Newton with Tukey
// weights (glare, pressed skin at the edge). σ of t: a jackknife over 16 sectors of the band (its
// residuals are correlated along it). The worn capture is then read where its outline puts the part.
#include <clearfit/geometry/mesh.hpp>

#include <limits>
#include <opencv2/core.hpp>
#include <string>

namespace clearfit {

struct OutlineOptions {
  bool enabled = true;           ///< measure the camera's move between the phases from the outline
  double band_px = 4.0;          ///< half-width of the band around the seen region's outline, px
  double smoothing_px = 1.0;     ///< Gaussian σ applied to the average and to the mask, px
  /// A larger 1-σ (either axis) of the move: not used (the outline is not seen well). A still wristband capture
  /// with places near its outline gave 0.13 px (its shift 0.07 px, which applied still improved the centres).
  double max_sigma_px = 0.2;
  double min_contrast = 0.05;    ///< the step across the outline, relative to the skin's level: less is no outline
  double max_shift_px = 6.0;     ///< a larger move is not believed (and not used)
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

struct OutlineFit {
  bool found = false;            ///< a fit with enough band, contrast and a σ within max_sigma_px
  Vec2 shift_px = Vec2::Zero();  ///< the average shows the map's outline displaced by this (px)
  Vec2 sigma_px = Vec2::Constant(std::numeric_limits<double>::quiet_NaN());  ///< 1-σ per axis (jackknife)
  double rotation_rad = 0;       ///< and turned by this about the seen region's centroid (fitted so that it does not bias the shift)
  /// and stretched by this (relative, per image axis) about that centroid: fitted so that an outline seen larger
  /// or smaller than the map's does not bias the shift; not applied.
  Vec2 stretch = Vec2::Zero();
  double contrast = 0;           ///< (skin − beside) / skin across the outline, median along the band
  long long pixels = 0;          ///< band pixels used
  std::string problem;           ///< why not found (empty when found)
};

/// Fits the outline of `seen_share` (CV_32F, the share of each pixel that sees the skin through the contact
/// surface, RefractionMap::seen_fraction over the average's roi) in `average` (CV_32F, the same size).
/// `exclude` (CV_8U, may be empty): pixels left out (saturated, glare).
OutlineFit locate_outline(const cv::Mat& average, const cv::Mat& seen_share, const cv::Mat& exclude, const OutlineOptions& o);

}  // namespace clearfit
