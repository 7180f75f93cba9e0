#pragma once
// The blanching signal on the contact chart. Both window averages (linear
// green) are resampled through the inverse refraction map onto the chart's
// texel grid — once each, with the window's residual sub-pixel motion added to
// the map — and compared there:
//   y_raw = ln(G / G0)                       (worn over baseline, per texel)
//   y     = y_raw − ln(G_ref / G_ref0)       (normalised by a reference region)
// then smoothed with a Gaussian of `smoothing_mm` (normalised convolution, so
// unseen texels neither count nor spread). The reference region is either a
// disk on the chart given by the user or, by default, the robust mode of y_raw
// over the seen texels (median after discarding values more than 3 MAD above
// it, iterated): it assumes the pressed area is less than half of what is
// seen, and says so when the signal covers more. Pulse and flicker modulate
// the whole image alike and cancel in this normalisation.
// The study's plain difference (worn − baseline average of the green code, in
// 8-bit units) is kept for comparison with its figures.
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/fit/skin_blur.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct BlanchingOptions {
  double smoothing_mm = 0.25;            ///< Gaussian σ on the chart, mm (0: none)
  /// The skin spreads the contact pressure laterally before it blanches (skin_blur.hpp: a Gaussian of
  /// about 0.3 mm; scene key assess.skin_blur_mm), and the feature is smoothed by smoothing_mm on top: the
  /// signal reads the contact pressure blurred by both, lower at a peak and higher at a foot by
  /// ½·(blur² + smoothing²)·∇²y. That resolution error is part of each texel's σ (assessment.cpp).
  double skin_blur_mm = SkinBlur{}.sigma_mm;
  /// The scale (mm) over which the deblur reads that term: y' = y + Σ a·(y − G∗y), a difference of Gaussians at this
  /// scale and √2 times it (assessment_stages.hpp, deblur_terms): y − ½·(blur² + smoothing²)·∇²y for features wider
  /// than it, a bounded gain on finer detail (mostly noise). Until 2026-11-29 ∇²y on y smoothed this much more: it read
  /// a 1.5 mm place's curvature about half, and that place's mean 0.27 kPa low (the difference of Gaussians: 0.14).
  /// Measured with it: 0.75 / 1.0 mm gave the study plate's sensitivity at 5.5 kPa 89.4 / 96.6 % (the Laplacian
  /// smoothed 0.2 / 0.5 / 1.0 mm: 73 / 87 / 99-100 %).
  double curvature_smoothing_mm = 1.0;  ///< scene key assess.curvature_smoothing_mm
  std::optional<Vec2> reference_uv_mm;   ///< centre of a reference disk on the chart
  double reference_radius_mm = 2.0;      ///< its radius
  std::vector<std::uint8_t> excluded;    ///< per chart texel: 1 = left out, unseen (glare, glare.hpp); empty: none
  /// Lossy captures: their compression error is fixed in time and correlated in space, so the
  /// spread of the frames misses it. The noise then also holds a spatial term: the robust spread
  /// of the smoothed feature over the unpressed skin (where both phases see the same skin, what
  /// is left is error), beyond what the frames' spread explains.
  bool spatial_noise = false;
  /// Per chart texel: ln(T_worn / T_baseline), the two phases' Fresnel
  /// transmittances when each has its own map (baseline_map.hpp), subtracted
  /// from y_raw; empty: none (one map, they cancel).
  std::vector<float> log_transmittance_ratio;
  /// y = ln(smooth(G) / smooth(G0)) instead of smooth(ln(G / G0)): the phases' greens are averaged
  /// before their ratio is taken. Needed when the phases see a texel through pixels of different
  /// footprints (a baseline with its own geometry): a pixel averages the skin's texture over its
  /// footprint, and E[ln G] grows as the footprint does (Jensen: by about half the texture's
  /// variance left in the pixel), so the log ratio of differently sampled texture is biased where
  /// the footprints differ (the band's oblique ends: false places of 5–6 kPa); averaging the linear
  /// greens over the same texels first removes it. Where one map serves both phases the two agree.
  bool ratio_of_smoothed = false;
  /// The noise also holds a local spatial term: texture that does not cancel between the phases
  /// (sampled by pixels of different footprints, aliased differently: the band's oblique ends with a
  /// held baseline). Per texel, the mean square of the smoothed feature's negative values within a
  /// Gaussian window of `local_noise_window_mm` (blanching only raises the feature, so the negative
  /// side is the error's, whatever is pressed), less the frames' own share, is added to sigma_y in
  /// quadrature; a window with too few negative texels (a fifth of its seen ones: blanched skin)
  /// adds nothing, so a pressed place keeps its own noise.
  bool local_spatial_noise = false;
  double local_noise_window_mm = 2.0;
  /// Throws std::invalid_argument naming the field as its scene key (assess.smoothing_mm, assess.skin_blur_mm,
  /// ...), its value and the rule.
  void validate() const;
};

struct BlanchingSignal {
  ChartField y;             ///< the feature, smoothed; NaN where unseen
  ChartField sigma_y;       ///< 1-σ noise of y per texel: over the camera pixels its kernel holds on the seen skin
  ChartField plain_difference;  ///< study's difference of averages, 8-bit green code units
  ChartField worn_green, baseline_green;  ///< linear green averages on the chart (unsmoothed)
  double reference_log_ratio = 0;  ///< ln(G_ref / G_ref0)
  std::string reference;           ///< how the reference was chosen, in words
  double noise_sigma = 0;          ///< median of sigma_y over the seen texels
  double temporal_noise_sigma = 0; ///< noise_sigma from the frames' spread alone
  double spatial_noise_sigma = 0;  ///< the spatial term added to sigma_y in quadrature at the median texel, more where its kernel holds fewer camera pixels (spatial_noise; else 0)
  double local_noise_sigma_p95 = 0; ///< local_spatial_noise: the 95th percentile of the local term over the seen texels
  long long texels_seen = 0;
  std::vector<std::string> warnings;
};

/// Computes the signal (see the file comment). `inverse` gives per texel the
/// camera pixel; `baseline_inverse` (optional, same grid) the baseline's own
/// pixel when the not-worn capture has its own geometry (baseline_map.hpp),
/// else `inverse` serves both and both averages must come from one reference
/// frame (one MotionReference). Throws InputError when no texel is seen, or
/// the reference disk holds no seen texel.
BlanchingSignal compute_blanching(const PhaseAverage& baseline, const PhaseAverage& worn, const InverseMap& inverse,
                                  const BlanchingOptions& options = {}, const InverseMap* baseline_inverse = nullptr);

/// Resamples a camera-image average onto the chart (bilinear; NaN outside the
/// image or where the texel is not seen): the texel's pixel plus the average's
/// residual shift, minus its roi origin.
ChartField resample_to_chart(const PhaseAverage& average, const InverseMap& inverse);

/// Gaussian smoothing of a field that has NaN holes (normalised convolution);
/// holes stay holes. sigma_mm ≤ 0 returns the field unchanged.
ChartField smooth_field(const ChartField& field, double sigma_mm);

}  // namespace clearfit
