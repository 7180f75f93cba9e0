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
#include <clearfit/refraction/inverse_map.hpp>

#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct BlanchingOptions {
  double smoothing_mm = 0.25;            ///< Gaussian σ on the chart, mm (0: none)
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
};

struct BlanchingSignal {
  ChartField y;             ///< the feature, smoothed; NaN where unseen
  ChartField sigma_y;       ///< 1-σ noise of y per texel (after smoothing)
  ChartField plain_difference;  ///< study's difference of averages, 8-bit green code units
  ChartField worn_green, baseline_green;  ///< linear green averages on the chart (unsmoothed)
  double reference_log_ratio = 0;  ///< ln(G_ref / G_ref0)
  std::string reference;           ///< how the reference was chosen, in words
  double noise_sigma = 0;          ///< median of sigma_y over the seen texels
  double temporal_noise_sigma = 0; ///< noise_sigma from the frames' spread alone
  double spatial_noise_sigma = 0;  ///< the spatial term added to every texel's sigma_y in quadrature (spatial_noise; else 0)
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
