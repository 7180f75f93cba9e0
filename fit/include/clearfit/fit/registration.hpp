#pragma once
// Frame-to-reference motion that blanching cannot fool (issue 12, item 1).
//
// What is registered. Blanching multiplies the skin's light by a smooth field
// that changes green most and red least (absorption k_R ≈ 0.2·k_G, SKIN.md).
// Each patch is read as ln R − ρ·ln G (ρ = green_ratio ≈ k_R/k_G): the
// blanching cancels, exposure becomes a constant, and the skin's texture
// (albedo, common to the channels) stays at 1 − ρ of its contrast; minus its
// Gaussian blur at `highpass_sigma_px` taken over the seen skin only
// (normalised convolution), so the fall-off, slow fields and the part's edge drop out.
//
// Where. A grid × grid set of patches spread over the region of interest (on the skin).
// Glare (glare_pixels, judged against the patch's medians) with a margin of `glare_margin_px` is
// left out like what lies beyond the skin: out of the high-pass (normalised convolution) and out of
// the fit, in that frame (and out of the template for good where a frame averaged into it has it);
// a patch whose template area is more than `max_glare_fraction` glare is left out of that frame. The reference is the average of the first
// `reference_frames` frames, each moved back by its measured motion; when it is closed,
// each of them is measured again against the average of the others (its own noise in
// the average would hold it where it was put), and the average is made again with those
// motions taken relative to the first frame's (so the motions stay the first frame's).
//
// How each patch is found. Gauss–Newton on the zero-mean, gain-normalised difference
// between the template and the frame sampled (prefiltered B-spline, spline_sampler.hpp) where
// the current motion puts it, turn and scale included. The Jacobian is the gradient of the
// template with its noise filtered out (a Wiener filter from the template's own spectrum and
// the averaged frames' spread): the raw template's gradient is mostly noise along the skin's
// ridges (measured on dark skin: three quarters of Σ ty², reading patches 3–5× their
// Cramér–Rao bound). Each patch's covariance follows from its residual.
//
// How they combine. A similarity transform of the image (translation,
// rotation, scale about the roi's centre) is fitted to the patch translations,
// each weighted by its information (inverse covariance, shared with the patches it
// overlaps), by iteratively reweighted least squares with Tukey's biweight on the
// residuals' Mahalanobis norms: a patch that blanching, glare or a sliding
// fold disturbs more than the others is rejected. A turn, and a scale, within
// `turn_significance` of its own standard error (their covariance from the patches') is dropped
// and the rest fitted again; with fewer than six patches kept both are (translation only: the weighted mean). When the turn or
// scale changed the patches' sampling, they are measured again with it.
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
  /// 1: full resolution; 2: half (pyrDown). Half resolution folds texture finer than 4 px
  /// (fingerprint ridges at about 12 px/mm) back into the image as patterns that do not move
  /// with the skin (measured: 0.3–0.8 px errors on the slab scene), so full resolution is the default.
  int downsample = 1;
  double smooth_sigma_px = 0;       ///< Gaussian against noise, px at the registered resolution (0: none)
  double highpass_sigma_px = 16.0;  ///< Gaussian subtracted (fall-off, slow fields), px at the registered resolution
  int iterations = 30;              ///< Gauss–Newton iterations per patch at most
  /// The Jacobian keeps frequencies up to this, cycles per registered px (radial): texture finer than two
  /// pixels folds back below it and moves the other way (fingerprint ridges at 0.62 cycles/px are seen at
  /// 0.38 and moving −1.6 times the skin: the wristband at quarter scale read 1.35 times the motion, reversed).
  double max_frequency = 0.3;
  /// B-spline order (3 or 5) of the frames' interpolation and of the gradients (spline_sampler.hpp).
  int spline_order = 5;
  /// Frames averaged into the reference (each registered against the average so far and
  /// moved back before it is added): the reference's noise falls as 1/√n.
  int reference_frames = 8;
  /// A patch whose template area (where the frame's motion puts it) is more than this share glare, its margin
  /// included, is left out of that frame; less glare is masked (glare_margin_px).
  double max_glare_fraction = 0.5;
  /// Glare's pixels (glare_pixels) grown by this, registered px, are left out of the frame's high-pass and fit.
  int glare_margin_px = 3;
  double tukey_c = 4.685;           ///< Tukey biweight constant, in units of the residuals' robust spread (at least their standard errors)
  double min_sigma_px = 0.02;       ///< floor of a patch's standard error, px (added in quadrature: noise-free patches agree to about this)
  /// A patch whose standard error (either axis) exceeds this, px, is left out of the frame: it has no texture to be
  /// registered by (measured: 0.6–18 px on textureless skin, where its noise alone pulled it; at most 0.1 px on the
  /// textured test scenes, dark skin and strong blanching included).
  double max_sigma_px = 0.25;
  /// A frame whose patches are all left out, against a reference that never had one registered, is skin without
  /// texture (its motion kept: RegistrationResult::no_texture) when the first frame's patches hold, as their median,
  /// less texture than this: their power above the noise over the noise's, at frequencies up to max_frequency
  /// (measured: textureless skin −0.2 to 1.8, its camera highlight the most; light skin 1.4–3.5). Otherwise it is lost.
  double min_texture = 1.0;
  /// A fitted turn, and a fitted scale, smaller than this many of its own standard errors is dropped (the turn alone
  /// tested with the scale, they let a noisy scale through with a real turn: 0.5° read 0.07–0.10 px off, 0.05–0.07 tested alone).
  double turn_significance = 3.0;
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
  /// No patch could be registered, in this frame nor in any since the reference was set, and the first frame's
  /// patches hold little texture (RegistrationOptions::min_texture): skin without texture to follow, which is not a
  /// motion beyond recognition (the caller keeps the frame where the previous one was).
  bool no_texture = false;
};

/// The reference's filtered patches; measures later frames against it. Shared by
/// both captures of an assessment so that both align to one reference.
///
/// The reference is the first frame, then the average of the first `reference_frames`
/// frames given to add_to_reference(), each moved back by its measured motion; the
/// motions of those frames are measured again against the whole average when it is
/// closed (close_reference()).
///
/// Not for two threads at once: measuring keeps each patch's skin terms for the next frame.
class MotionRegistration {
 public:
  /// Patches of a grid over `roi` (clipped to the image; a patch that would leave it is moved inside).
  /// `seen` (optional, CV_8U, roi size): the pixels that see the skin; each grid cell's patch is
  /// moved within its cell to see the most skin, and left out when less than 3/4 of it does.
  MotionRegistration(cv::Size image, const cv::Rect& roi, const RegistrationOptions& options, const cv::Mat& seen = {});
  /// The smallest image side (pixels) the registration works on with these options: smaller
  /// images make the constructor throw std::invalid_argument.
  static int min_image_side(const RegistrationOptions& options) { return 16 + 2 * options.downsample * (kApron + 4); }
  bool has_reference() const { return frames_averaged_ > 0; }
  /// Starts the reference with `bgr` (its motion is the identity); drops any earlier one.
  void set_reference(const cv::Mat& bgr);
  /// While the reference is open: `bgr`'s motion against the average so far (started from
  /// `start`), and `bgr` moved back by it added to the average. The first call sets the reference.
  RegistrationResult add_to_reference(const cv::Mat& bgr, const Similarity& start);
  /// True until the reference is set and while add_to_reference() still averages (fewer than reference_frames frames so far).
  bool reference_open() const { return !has_reference() || (open_ && frames_averaged_ < options_.reference_frames); }
  /// Ends the averaging: the frames averaged, measured again against the whole average, each
  /// with its place among the add_to_reference() calls (0: the first).
  std::vector<std::pair<int, RegistrationResult>> close_reference();
  /// `bgr`'s motion against the reference, started from `start` (e.g. the previous frame's).
  RegistrationResult measure(const cv::Mat& bgr, const Similarity& start) const;
  /// The image pixels (full resolution) that measuring a frame reads when the motion it starts from
  /// moves no corner of the roi by more than `motion_px`: each patch's template, apron and search
  /// margin where such a motion puts it, with the filters' support around them (clipped to the image).
  cv::Rect support(double motion_px) const;
  const std::vector<cv::Rect>& patches() const { return rects_; }
  const cv::Rect& roi() const { return roi_; }
  cv::Size image() const { return image_; }
  const RegistrationOptions& options() const { return options_; }

 private:
  static constexpr int kApron = 2;  ///< template border kept for its gradients, registration px
  static constexpr int kSearchMargin = 8;  ///< room around the moved template for the correction and the interpolation, registration px
  struct Patch {
    cv::Rect area;                  ///< the template, registration px
    cv::Mat sum, sq;                ///< sum of the frames averaged and of their squares, with the apron (CV_32F)
    int count = 0;                  ///< frames in `sum`
    cv::Mat t, tx, ty;              ///< zero-mean average and its gradients (area size), 0 off the skin
    cv::Mat jx, jy;                 ///< the gradients of the average with its noise filtered out (wiener()): the Jacobian
    cv::Mat tf;                     ///< that filtered average, zero-mean (area size), 0 off the skin
    cv::Mat weight;                 ///< CV_8U (area size): the template's pixels that count (on the skin)
    double h[4] = {0, 0, 0, 0};     ///< Σ jx·tx, Σ jx·ty, Σ jy·tx, Σ jy·ty
    double m[3] = {0, 0, 0};        ///< Σ jx², Σ jx·jy, Σ jy²
    double tt = 0, ff = 0, pixels = 0;  ///< Σ t², Σ tf², and the pixels that count (weight)
    double texture = 0;             ///< the first frame's texture against its noise (RegistrationOptions::min_texture)
    bool usable = false;
  };
  /// One frame's filtered region around each patch (registration px, origin in the same).
  struct Region {
    cv::Mat f;
    cv::Mat coef;                   ///< f's spline coefficients (SplineSampler)
    cv::Mat skin;                   ///< CV_8U: the pixels of `f` that see the skin (empty: all)
    cv::Point origin;
    cv::Mat glare_mask;             ///< CV_8U, f's size: the glare with its margin, left out (empty: none)
    bool glare = false;             ///< more glare than max_glare_fraction: left out
  };
  using Regions = std::vector<Region>;
  /// A patch's skin terms of the normalised convolution for one region and integer shift (full-resolution
  /// px): the moved seen mask over the region, and over `crop` (registration px in the region) the
  /// divisors of the signal and of its blur and the pixels on the skin. They change only when the
  /// region or the shift does, so each patch keeps the last ones.
  struct SkinBlur {
    cv::Rect region, crop;
    cv::Point shift;
    cv::Mat skin;                   ///< CV_32F, region size: the seen mask moved by `shift`
    cv::Mat mask_div, low_div;      ///< CV_32F, crop size: max(smoothed mask, 1e-3) and max(its blur, 1e-3)
    cv::Mat on_skin;                ///< CV_8U, crop size: smoothed mask > 0.99
    cv::Mat off_skin;               ///< CV_8U, crop size: smoothed mask 0
  };
  /// `cache` when it holds these region, shift and crop, else `cache` refilled with them.
  const SkinBlur& skin_blur(const cv::Rect& region, cv::Point shift, const cv::Rect& crop, SkinBlur& cache) const;
  /// Those terms made afresh, the pixels of `glare` (CV_8U, region size; empty: none) taken off the skin.
  SkinBlur skin_terms(const cv::Rect& region, cv::Point shift, const cv::Rect& crop, const cv::Mat& glare) const;
  /// Brings a full-resolution image to the registered resolution (pyrDown) and smooths it (smooth_sigma_px).
  void smooth(cv::Mat& m) const;
  /// Filtered image (registration resolution) over `area` (registration px, clipped to the image),
  /// the skin's high-pass taken over the skin only (the seen mask moved by `shift`, full-resolution px;
  /// its terms from the patch's `cache`) less its glare, found against the medians of `patch` (full-resolution px).
  Region filtered(const cv::Mat& bgr, const cv::Rect& area, cv::Point shift, SkinBlur& cache, const cv::Rect& patch) const;
  /// The whole registered pixels `m` moves patch k's centre by: what its skin terms are moved by (read()).
  cv::Point whole_shift(std::size_t k, const Similarity& m) const;
  /// Each patch's region of `bgr` where `expected` puts it, with a margin.
  Regions read(const cv::Mat& bgr, const Similarity& expected) const;
  /// The motion of the frame whose regions these are; with `whole`, that motion with its turn and
  /// scale even where they are not significant (what a frame averaged is moved back by).
  RegistrationResult solve(const Regions& regions, const Similarity& start, Similarity* whole = nullptr) const;
  /// Each kept patch's region moved back by `motion` onto its template (with the apron), zero-mean; empty where not kept.
  /// `glare` (optional): per patch, the template's pixels the region's glare reaches (empty: none).
  std::vector<cv::Mat> warp_back(const Regions& regions, const Similarity& motion, const std::vector<std::uint8_t>& keep,
                                 std::vector<cv::Mat>* glare = nullptr) const;
  /// The template pixels that, sampled at `bx`, `by` (region px), read the region's glare, grown by the gradients' reach.
  cv::Mat glare_reach(const Region& region, const cv::Mat& bx, const cv::Mat& by) const;
  /// Sampling positions (region px, `origin` the region's) of patch k's template plus `apron` under motion `s`.
  void base_maps(std::size_t k, cv::Point origin, const Similarity& s, int apron, cv::Mat& bx, cv::Mat& by) const;
  /// No turn or scale worth a hundredth of a pixel at the patch's corners: its samples are one grid moved.
  bool uniform(std::size_t k, const Similarity& m) const;
  /// Adds the frame (moved back: `warped`) to the averages and refreshes the templates; `glare` (optional, per
  /// patch, template size) is taken out of the templates' weights for good.
  void accumulate(const std::vector<cv::Mat>& warped, const std::vector<cv::Mat>* glare = nullptr);
  /// The patch's template, its gradients and Jacobian from its sums.
  void refresh(Patch& p) const;
  cv::Size image_;
  cv::Rect roi_;
  RegistrationOptions options_;
  std::vector<cv::Rect> rects_;
  std::vector<Patch> patches_;
  /// The pixels of the reference frame that the seen mask has and that look like skin: those far darker than
  /// the skin the mask sees are left out (the not-worn capture, filmed through its own geometry, sees the
  /// background where the worn one's map sees skin; its edge in a template pulled the patch to the integer
  /// shifts the mask is moved by).
  void restrict_to_skin(const cv::Mat& bgr);
  cv::Mat seen_map_;                ///< CV_8U, image size: the skin the map sees (eroded); empty: all
  cv::Mat seen_;                    ///< CV_8U, image size: seen_map_ less what the reference frame shows is not skin
  int frames_averaged_ = 0;
  bool open_ = false;
  std::vector<Regions> kept_;       ///< the averaged frames' regions, until close_reference()
  std::vector<std::vector<cv::Mat>> kept_warped_;  ///< what each averaged frame added to each patch's sum
  std::vector<Similarity> kept_motion_;
  std::vector<int> kept_call_;      ///< each kept frame's place among the add_to_reference() calls
  int calls_ = 0;
  /// Some frame had a patch registered since the reference was set (RegistrationResult::no_texture). Written
  /// by solve(): one registration is measured from one thread at a time.
  mutable bool textured_ = false;
  int border_ = 0;                  ///< filter support, registration px
  /// Per patch: the skin terms last used (filtered()). A cache written by read(), so one registration
  /// is measured from one thread at a time (as read_capture does).
  mutable std::vector<SkinBlur> skin_blur_;
};

}  // namespace clearfit
