#pragma once
// Vignetting between the phases when each has its own geometry (a baseline
// filmed with the part held off the skin, or without it: baseline_gap.hpp).
//
// The lens and the light dim the image towards its corners. With one map both
// phases read a skin point at the same pixel, so the fall-off cancels in the
// ratio worn / baseline. With two maps they read it at pixels some tens of
// pixels apart (the gap's parallax), and a fall-off of 25 % at the corner
// leaves a grey ratio of about 0.5 % there: read as blanching, that is a few
// kPa, in broad bands. The fall-off is estimated from the captures themselves:
// per pixel that sees the same skin in both phases,
//   d = ln(G_worn(p) / G_base(p_b))  =  c + ln V(p) − ln V(p_b) + blanching,
// with the radial model V(p) = 1 + v·r²(p), r² the squared distance from the
// image centre over the squared half-diagonal (v is the change of the
// illumination at the corner: −0.25 for a quarter lost). c (exposure) and v are
// fitted robustly (Tukey's biweight on the MAD scale, Gauss–Newton on v):
// blanching only raises d and falls out as outliers where it is strong.
// Without parallax (|r²(p) − r²(p_b)| tiny everywhere) v is not estimated.
#include <cmath>
#include <string>
#include <vector>

namespace clearfit {

struct VignettingOptions {
  bool enabled = true;
  double max_abs = 0.9;          ///< |v| beyond this is refused as not vignetting (kept at 0, with a warning)
  double min_spread = 2e-4;      ///< below this rms spread of r²(p) − r²(p_b) the phases' parallax cannot tell v
  int stride_px = 3;             ///< every this many pixels per axis (neighbours share texture and noise)
  double pressed_margin_mm = 2.0;  ///< pixels this near a pressed place are left out (its mild foot would read as fall-off)
  void validate() const;         ///< throws std::invalid_argument naming the field
};

/// One pixel seen in both phases: d = ln(G_worn / G_base) (transmittances divided out), and the
/// squared normalised radii of its pixel in the worn and in the baseline image.
struct VignettingSample {
  float d = 0, r2_worn = 0, r2_base = 0;
};

struct VignettingEstimate {
  bool estimated = false;   ///< false: v = 0 is used (disabled, no parallax, or refused: `problem` says)
  double v = 0;             ///< illumination change at the corner (V = 1 + v·r²)
  double sigma = 0;         ///< formal 1-σ of v (the samples' spread; neighbours are not independent)
  double spread = 0;        ///< rms of r²(p) − r²(p_b) over the samples
  long long samples = 0;    ///< pixels used
  double inlier_fraction = 0;  ///< of the samples, with non-zero biweight
  std::string problem;      ///< why it was not estimated
};

/// Squared normalised radius of pixel (x, y) in a width × height image (0 at the centre, 1 at a corner).
double vignetting_r2(double x, double y, int width, int height);

/// ln V(p) for the model V = 1 + v·r² (see the file comment).
inline double log_vignetting(double v, double r2) { return std::log1p(v * r2); }

/// Fits c and v to the samples (see the file comment).
VignettingEstimate estimate_vignetting(const std::vector<VignettingSample>& samples, const VignettingOptions& options = {});

}  // namespace clearfit
