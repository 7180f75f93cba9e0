#pragma once
// The not-worn capture's gap, estimated from the captures. With the part held
// off the skin (or absent) the baseline sees each skin point at another pixel
// than the worn capture; the gap that makes them agree is the one whose
// baseline map (refraction/baseline_map.hpp) carries the baseline's skin
// texture onto the worn texture on the chart.
//
// Method. Both averages are turned into texture: log linear green minus its
// Gaussian blur of highpass_mm (normalised convolution over the seen skin),
// which removes illumination, transmittance and the smooth blanching; the
// worn one on the chart (through the worn inverse map), the baseline one in
// its camera image. For a candidate gap each baseline pixel's chart uv (the
// baseline map at that gap) reads the worn texture there; the match is the
// normalised correlation with the baseline pixel's texture.
//  1. Coarse: every step_mm over [0, max_mm]; the best with a parabola
//     through its neighbours. Then the texture's move between the phases'
//     first frames (max_shift_px: each phase is registered to its own first
//     frame, and a camera move or a skin slide would read as parallax): the
//     shift of the baseline image found by correlation at whole pixels, then
//     Gauss–Newton on the shift and a gain, over the unpressed samples away
//     from the seen skin's edge; the coarse search again with it, twice.
//  2. Pressed places are left out: pixels where the log ratio of the two
//     averages (smoothed) stands more than 4 robust deviations above its
//     median at that gap.
//  3. Fine: five gaps step_mm/2 apart around it; per block of 32 × 32 pixels
//     the squared residual (baseline texture − gain × worn texture) at each,
//     summed, and a parabola through the sums: its vertex is the estimate
//     (recentred up to three times; step_mm/4 apart gave parabolas through
//     noise once the shift was free: σ 0.43 mm on a slid skin, 0.04 at
//     step_mm/2). σ: the spread of the vertex over
//     `bootstrap` resamplings of the blocks with replacement (block
//     bootstrap: neighbouring pixels are not independent).
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/refraction/baseline_map.hpp>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace clearfit {

struct GapSearchOptions {
  double max_mm = 5.0;         ///< the gaps searched: [0, max_mm]
  double step_mm = 0.25;       ///< coarse grid
  double highpass_mm = 2.5;    ///< texture: log green minus its blur of this σ, mm on the skin
  double max_sigma_mm = 0.1;   ///< a larger 1-σ: the gap cannot be estimated
  double warn_sigma_mm = 0.05; ///< a larger 1-σ (up to max_sigma_mm): used, with a warning giving it
  double min_match = 0.1;      ///< a lower texture correlation at the estimate: cannot be estimated
  /// Motion between the phases: each phase is registered to its own first frame, so a move of the
  /// camera (or a slide of the skin) from the not-worn capture's first frame to the worn one's is
  /// measured with the gap (a shift of the baseline image up to this many px); 0: not measured.
  double max_shift_px = 6.0;
  /// The estimate's σ carried into each texel's signal σ (the signal read at the gap ± σ; assessment.cpp,
  /// gap_signal_sigma), so that the detection gate rises where the gap moves what the baseline reads.
  bool sigma_in_signal = true;
  int bootstrap = 200;
  std::uint64_t seed = 1;
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

struct GapEstimate {
  double gap_mm = 0, sigma_mm = 0;
  bool estimated = false;      ///< trustworthy: an interior best match, σ <= max_sigma_mm, match >= min_match
  double match = 0;            ///< texture correlation at the estimate (1: identical)
  double shift_mm_per_mm = 0;  ///< median movement of the baseline's skin points on the chart per mm of gap
  long long pixels = 0;        ///< baseline pixels compared at the estimate
  long long pressed_pixels = 0;  ///< left out as pressed
  std::vector<std::pair<double, double>> curve;  ///< coarse search: gap (mm), 1 − correlation
  /// The texture's move between the phases (GapSearchOptions::max_shift_px): the baseline image at
  /// pixel p + phase_shift_px shows the skin the worn capture shows at p (px, 1-σ per axis from the
  /// block bootstrap; it leaves out errors common to all blocks, e.g. a rotation).
  Vec2 phase_shift_px = Vec2::Zero(), phase_shift_sigma_px = Vec2::Zero();
  bool phase_shift_measured = false;
  std::string problem;         ///< why it is not trustworthy (empty when estimated)
};

/// Estimates the gap (see the file comment). `baseline`: the not-worn
/// average (camera image, roi); `worn_green`: the worn average resampled onto
/// the chart (linear green, NaN unseen). Never throws for data reasons: a gap
/// that cannot be estimated comes back with estimated = false and `problem`.
GapEstimate estimate_gap(const BaselineRays& rays, const PhaseAverage& baseline, const ChartField& worn_green,
                         const GapSearchOptions& options = {});

}  // namespace clearfit
