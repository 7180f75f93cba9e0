#pragma once
// Glare on the clear part (issue 12, item 4): specular highlights are white
// light the resin reflects into the camera. They are found in the two window
// averages (green at full resolution, blue at half: photometric.hpp), masked
// with a margin and left out of the signal (the texels behind them are unseen,
// never 0 kPa).
//
// Why blue. Glare adds the same light w to every channel, so it raises blue
// (the skin's darkest channel, B ≈ c·G with c ≈ 0.6–0.85) relatively more
// than green: d ln B = d ln G / c. Blanching raises green far more than blue:
// d ln B ≈ ρ·d ln G with ρ ≈ 0.3 (haemoglobin's absorption in the camera's
// bands). Exposure and white balance shift ln G and ln B by constants, taken
// out as medians over the seen skin. Per half-resolution pixel, smoothed:
//   change between the phases  γ = (ΔlnB − ρ·ΔlnG) / (1/c − ρ)   (≈ Δw/G; blanching gives 0)
//   static in one phase        s = (ln(B/G) − median) / (1/c − 1) (≈ w/G; blanching gives < 0)
// ρ is measured on the data (the median ratio ΔlnB/ΔlnG over clearly
// blanched pixels below the glare's ratio), else 0.3. A pixel is glare when
// |γ| or s passes max(k·robust σ, a floor), or when green or blue is near
// saturation; the region grows to half those thresholds (hysteresis), by
// `margin_px`, and out to where its light measured around it is below `tail_light`. The seen skin's outline (`outline_band_px`, off by default) can
// be judged by saturation only: its pixels mix skin with what lies beside the part.
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <string>
#include <vector>

namespace clearfit {

struct GlareOptions {
  bool enabled = true;
  double threshold_sigmas = 5;   ///< k: a pixel's score against its robust noise
  double min_change = 0.002;     ///< floor of |γ|: glare changing by 0.2 % of the green (a ~0.3 kPa signal)
  double min_static = 0.1;       ///< floor of s: glare in both phases at 10 % of the green (it dims the signal by as much)
  double saturation = 0.95;      ///< linear green or blue mean at or above this is glare
  double smooth_px = 1.5;        ///< Gaussian σ on the half-resolution grid
  int margin_px = 6;             ///< grown by this many camera pixels
  /// ... or out to where a highlight's light, measured as means over rings around it, falls below this share of the
  /// skin's green (one in both phases; one that changes between them: half of min_change, what would read as
  /// pressure), where that is farther (at most the region's radius; glare.cpp measured_tails). 0: the margin only.
  double tail_light = 0.005;
  /// The seen skin's outline: pixels this near an unseen one (camera px) hold skin and what lies beside the part
  /// in shares that change between the phases, as glare's colour does; they are left out of the smoothing and
  /// the noise and masked only when saturated (the margin covers them beside glare found farther in). Off (0) by
  /// default: at 4 px it frees the edge of false masks, but those masks also hide false signal at a band's
  /// oblique ends (an H.264 capture, LossyCli: a false place there and Pearson 0.53 against 0.83 at 0).
  double outline_band_px = 0;
  double max_fraction = 0.5;     ///< a capture whose seen skin is more glare than this is refused
  double blanching_ratio = 0.3;  ///< ρ when it cannot be measured
  void validate() const;         ///< throws std::invalid_argument naming the field
};

struct GlareMask {
  cv::Mat mask;            ///< CV_8U, roi size (aligned to the reference frame): 255 = glare
  cv::Rect roi;
  double fraction = 0;     ///< of the seen pixels
  double fraction_glare = 0;  ///< of the seen pixels, the highlights with the fixed margin only (what "mostly glare" weighs)
  double fraction_baseline = 0, fraction_worn = 0;  ///< seen pixels with glare in that phase (static, saturated, or appearing in it)
  int regions = 0;
  double blue_over_green = 0;   ///< c: the skin's linear B/G (both phases' median)
  double blanching_ratio = 0;   ///< ρ used
  bool ratio_measured = false;  ///< ρ measured on the data (else the default)
  double change_sigma = 0, static_sigma = 0;  ///< robust noise of γ and s
  std::vector<std::string> warnings;  ///< an unsure detection, with its figure
  bool empty() const { return mask.empty(); }
};

/// Finds the glare (see the file comment). `seen`: CV_8U roi-size mask of the
/// pixels that see the skin. Needs both averages' blue_half (read with
/// CaptureReadOptions::colour); returns an empty mask otherwise or when disabled.
GlareMask detect_glare(const PhaseAverage& baseline, const PhaseAverage& worn, const cv::Mat& seen, const GlareOptions& options);

/// One frame (BGR8), for registration: the fraction of the pixels of `patch` that look like
/// strong glare — a channel at 250 or more, or whiter (linear B/G at least halfway from the
/// patch's median to 1) and brighter (green 1.2× the median) than the skin. A highlight about
/// as bright as the skin or brighter is found; weak glare is left to detect_glare.
double glare_fraction(const cv::Mat& bgr, const cv::Rect& patch);

/// The pixels of `region` (CV_8U, region size; 255: glare; none off the image) that glare_fraction would count,
/// judged against the medians of `patch`.
cv::Mat glare_pixels(const cv::Mat& bgr, const cv::Rect& patch, const cv::Rect& region);

/// Per chart texel: 1 where the texel's camera pixel (plus `shift_px`) lies in the mask.
std::vector<std::uint8_t> glare_texels(const GlareMask& glare, const InverseMap& inverse, const Vec2& shift_px);

/// Marks the hotspots that touch an excluded texel (8-neighbourhood of their region).
/// `labels`: the hotspot id per texel (find_hotspots).
void flag_hotspots_at_mask(std::vector<Hotspot>& hotspots, const std::vector<int>& labels,
                           const std::vector<std::uint8_t>& excluded, const ChartGrid& grid);

}  // namespace clearfit
