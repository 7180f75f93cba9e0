#pragma once
// The not-worn capture compared with the worn one when each has its own geometry (a part held off
// the skin, or absent): the same skin is seen at different pixels, through different Fresnel
// transmittances, under a different share of the image's fall-off (vignetting.hpp). Private to
// the assessment.
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/vignetting.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <clearfit/refraction/map.hpp>

#include <vector>

namespace clearfit {

struct BaselineAsWorn {
  PhaseAverage average;  ///< the baseline read where it sees each worn pixel's skin, divided by T and V ratios
  cv::Mat comparable;    ///< CV_8U roi-size: 255 where the worn pixel's skin is seen in the baseline too
  VignettingEstimate vignetting;
};

/// The baseline average in the worn capture's geometry, for comparing the phases pixel by pixel
/// (the glare mask): a roi pixel that sees the skin in the worn map reads the baseline where its
/// own inverse map `base_inv` sees the same chart point, scaled by T_worn(p)/T_base(p_b) and by the
/// fall-off ratio V(p)/V(p_b) estimated on the way (vignetting.hpp); the other pixels are not
/// comparable (and read where they are).
BaselineAsWorn baseline_as_worn(const PhaseAverage& base, const PhaseAverage& worn, const RefractionMap& worn_map,
                                const RefractionMap& base_map, const InverseMap& base_inv, const VignettingOptions& options);

/// Per texel ln(T_worn·V_worn / (T_base·V_base)): each map's Fresnel transmittance at the texel's
/// pixel (bilinear) and the fall-off 1 + v·r² there; NaN where either map does not see the texel.
std::vector<float> log_phase_ratio(const RefractionMap& worn, const InverseMap& worn_inv, const RefractionMap& base,
                                   const InverseMap& base_inv, double v);

/// The average with NaN where `map` does not see the skin or sees it at its edge in the image (a
/// neighbour does not), so a texel whose bilinear taps reach the skin's edge (the part's rim, the
/// background) is unseen rather than a mixture.
PhaseAverage nan_where_unseen(const PhaseAverage& average, const RefractionMap& map);

}  // namespace clearfit
