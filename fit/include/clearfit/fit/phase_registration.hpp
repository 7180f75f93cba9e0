#pragma once
// Registration of the phases on the chart: skin that slid or bulged between
// the not-worn (baseline) and the worn capture. Without it, texture that moved
// under the part (ridges, mottling) is read as colour change, i.e. as pressure.
//
// Method. Both window averages are resampled onto the chart (each through its
// own inverse map) as a texture that blanching does not change: the feature
// f = ln R − red_green_ratio · ln G (blanching multiplies each channel by
// exp(−k_c·ΔB) with k_R ≈ 0.2·k_G, SKIN.md, so it cancels; red is summed at
// full resolution, photometric.hpp: at half resolution the finest lines alias), high-passed (f minus its Gaussian blur of
// highpass_mm, normalised convolution over the seen texels) and blurred by
// coarse_mm: without its finest lines, since ridges repeat every ~0.3 mm,
// about as far as skin slides, and a flow that follows them locks onto the
// wrong ridge. A dense flow between the two textures (OpenCV's DIS optical
// flow, coarse to fine with variational refinement, on a grid of half the
// chart's resolution when the blur allows) is then regularised: a Gaussian of
// smoothing_mm weighted by each texel's local texture energy (pressed places, glare and
// unseen texels weigh little or nothing), twice, the second time without the
// vectors farther than 3 robust deviations from the first. The field is
// applied to the baseline: its inverse map reads the skin point that moved to
// each texel (displaced_inverse), so every later use of the baseline average
// (the signal, its noise, the pictures) sees it where the worn capture does.
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace clearfit {

struct PhaseRegistrationOptions {
  bool enabled = true;
  double red_green_ratio = 0.2;     ///< feature ln R − ratio · ln G (k_R / k_G of the skin model)
  double highpass_mm = 1.0;         ///< texture: the feature minus its Gaussian blur of this σ, mm
  double coarse_mm = 0.15;          ///< first pass: the texture blurred by this σ, mm (no fine lines), then the whole texture
  double smoothing_mm = 0.4;        ///< regularisation: texture-weighted Gaussian of the field, σ in mm
  double max_displacement_mm = 1.0; ///< a larger displacement anywhere is reported as unsure
  double min_match = 0.5;           ///< texture correlation after registration below this: unsure
  double max_weak_fraction = 0.3;   ///< more of the seen skin with too little texture to follow: unsure
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

struct PhaseRegistration {
  bool applied = false;
  /// The skin's displacement from the not-worn to the worn capture on the chart
  /// grid, mm (u, v components); NaN where the texel is not seen in both.
  ChartField dx_mm, dy_mm;
  double median_mm = 0, p95_mm = 0, max_mm = 0;  ///< magnitude over the seen texels
  /// Normalised correlation of the two textures over the seen texels, as they
  /// lie and after the baseline is displaced (1: identical).
  double match_before = 0, match_after = 0;
  double weak_texture_fraction = 0;  ///< seen texels whose texture is under a tenth of the median energy
  long long texels = 0;              ///< seen in both
  std::vector<std::string> warnings; ///< unsure: each with its figure
  double ms = 0;
};

/// Measures the field (see the file comment). `baseline` and `worn` need
/// red (CaptureReadOptions::red); each is resampled through its inverse
/// map (same grid), with its residual shift. `excluded` (per texel, may be
/// empty): left out (glare). Never throws for data reasons: too little seen or
/// too little texture comes back with applied = false and a warning.
PhaseRegistration register_phases(const PhaseAverage& baseline, const PhaseAverage& worn, const InverseMap& baseline_inverse,
                                  const InverseMap& worn_inverse, const std::vector<std::uint8_t>& excluded,
                                  const PhaseRegistrationOptions& options);

/// The baseline's inverse map with the field applied: texel x reads the pixel
/// of chart point x − d(x) (bilinear over the map's valid taps, renormalised;
/// when they carry less than half the weight, at the seen skin's edge, the
/// texel keeps its own pixel). Unchanged where the field is undefined.
InverseMap displaced_inverse(const InverseMap& baseline_inverse, const PhaseRegistration& registration);

}  // namespace clearfit
