#pragma once
// Frame-to-reference motion that blanching cannot fool (issue 12, item 1).
//
// What is registered. Blanching multiplies the skin's light by a smooth field
// that changes green most and red least (absorption k_R ≈ 0.2·k_G, SKIN.md).
// Each patch is read as ln R − ρ·ln G (ρ = green_ratio ≈ k_R/k_G): the
// blanching cancels, exposure becomes a constant, and the skin's texture
// (albedo, common to the channels) stays at 1 − ρ of its contrast; at half
// resolution (pyrDown), minus its Gaussian blur at `highpass_sigma_px` (the
// fall-off and what is left of slow fields drop out).
//
// Where. A grid × grid set of patches spread over the region of interest (on the skin);
// a patch whose reference or current frame shows glare (glare_fraction) is
// left out of that frame. Each patch's translation is found to a fraction of a
// pixel by enhanced correlation (ECC, translation) of the filtered patch, started
// from the previous frame's motion.
//
// How they combine. A similarity transform of the image (translation,
// rotation, scale about the roi's centre) is fitted to the patch translations
// by iteratively reweighted least squares with Tukey's biweight on residuals
// scaled by their robust spread: a patch that blanching, glare or a sliding
// fold disturbs more than the others is rejected. With fewer than three patches
// left, translation only (their reweighted mean).
#include <clearfit/geometry/mesh.hpp>
#include <opencv2/core.hpp>

#include <vector>

namespace clearfit {

struct RegistrationOptions {
  int grid = 3;                     ///< patches per side, spread over the roi
  int patch_size = 128;             ///< patch edge, full-resolution px (shrunk to fit grid patches across the roi)
  /// The image registered is ln R − ρ·ln G: blanching changes ln R by about ρ = k_R/k_G ≈ 0.2 of
  /// ln G (SKIN.md), so it cancels, while the texture (albedo, common to the channels) stays at 1 − ρ.
  double green_ratio = 0.2;
  int downsample = 2;               ///< 1: full resolution; 2: half (pyrDown)
  double smooth_sigma_px = 0;       ///< Gaussian against noise, px at the registered resolution (0: none)
  double highpass_sigma_px = 8.0;   ///< Gaussian subtracted (fall-off, slow fields), px at the registered resolution
  int iterations = 20;              ///< ECC iterations per patch at most
  double max_glare_fraction = 0.01; ///< a patch with more glare pixels than this (glare_fraction) is left out
  double tukey_c = 4.685;           ///< Tukey biweight constant, in units of the residuals' robust σ
  double min_sigma_px = 0.02;       ///< floor of that σ (noise-free patches agree to better than this)
  void validate() const;            ///< throws std::invalid_argument naming the field
};

/// Motion of the image against the reference: the content at reference pixel q
/// is seen at q + displacement(q) (all in full-resolution px).
struct Similarity {
  Vec2 centre = Vec2::Zero();  ///< fixed point of the rotation and scale (the roi's centre)
  Vec2 t = Vec2::Zero();       ///< displacement at the centre
  double a = 0, b = 0;         ///< s·cos θ − 1 and s·sin θ
  Vec2 displacement(const Vec2& q) const {
    const Vec2 r = q - centre;
    return t + Vec2(a * r.x() - b * r.y(), b * r.x() + a * r.y());
  }
  double angle_rad() const;
  double scale() const;
  /// Largest displacement over the corners of `rect`.
  double max_displacement(const cv::Rect& rect) const;
};

struct RegistrationResult {
  Similarity motion;
  bool found = false;                ///< false: no patch could be registered (motion is then NaN)
  int patches = 0, patches_used = 0; ///< patches registered this frame; kept by the robust fit
  std::vector<Vec2> patch_shift;     ///< per patch (NaN when left out): its translation
  std::vector<std::uint8_t> inlier;  ///< per patch: kept by the robust fit
  std::vector<std::uint8_t> glare;   ///< per patch: left out for glare
};

/// The reference frame's filtered patches; measures later frames against it.
/// Shared by both captures of an assessment so that both align to one frame.
class MotionRegistration {
 public:
  /// Patches of a grid over `roi` (clipped to the image; a patch that would leave it is moved inside).
  /// `seen` (optional, CV_8U, roi size): the pixels that see the skin; each grid cell's patch is
  /// moved within its cell to see the most skin, and left out when less than 3/4 of it does.
  MotionRegistration(cv::Size image, const cv::Rect& roi, const RegistrationOptions& options, const cv::Mat& seen = {});
  bool has_reference() const { return !reference_.empty(); }
  void set_reference(const cv::Mat& bgr);
  /// `bgr`'s motion against the reference, started from `start` (e.g. the previous frame's).
  RegistrationResult measure(const cv::Mat& bgr, const Similarity& start) const;
  const std::vector<cv::Rect>& patches() const { return rects_; }
  const cv::Rect& roi() const { return roi_; }
  cv::Size image() const { return image_; }
  const RegistrationOptions& options() const { return options_; }

 private:
  struct Patch {
    cv::Mat t, tx, ty;          ///< filtered reference (at the registered resolution) and its gradients
    double h[3] = {0, 0, 0};    ///< Hessian Σ tx², Σ tx·ty, Σ ty²
    bool usable = false;
  };
  /// Filtered half-resolution image of `rect` moved by `offset` (full-res px, even), with a border.
  cv::Mat filtered(const cv::Mat& bgr, const cv::Rect& rect, cv::Point& origin_half) const;
  cv::Size image_;
  cv::Rect roi_;
  RegistrationOptions options_;
  std::vector<cv::Rect> rects_;
  std::vector<Patch> reference_;
  int border_half_ = 0;
};

}  // namespace clearfit
