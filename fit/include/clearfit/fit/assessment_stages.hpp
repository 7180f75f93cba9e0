#pragma once
// The assessment's stages that compute on plain values (assess_captures in assessment.hpp runs them in
// order, between reading the captures and writing the vertices): the checks that refuse or warn about
// captures, where on the skin each texel lies by the pose and by the camera model, the blur's
// first-order effect, the signal's σ, and the signal turned into pressure. Each is a pure function of
// its arguments (warnings appended to the vector given), so tests hold them to closed forms.
#include <clearfit/fit/assessment.hpp>

#include <string>
#include <vector>

namespace clearfit {

// ---- Checks on the captures (stage 3) ----

/// Refuses a capture that is mostly glare (the largest of the glare fractions over both phases above
/// o.max_fraction: InputError naming the worse phase's source); warns how many highlights it masked.
void check_glare(const GlareMask& g, const PhaseReport& base, const PhaseReport& worn, const GlareOptions& o,
                 std::vector<std::string>& warnings);

/// Warns when the exposure or white balance changed inside a window (chunk gains spanning more than
/// 2 %: normalised, but worth locking) and when each chunk's gain is known to worse than 0.2 %.
void warn_gains(const PhaseReport& p, const std::string& role, std::vector<std::string>& warnings);

/// Refuses a window that is overexposed (saturated fraction above o.max_saturated_fraction plus
/// `glare_fraction`, the share of the roi masked as glare, whose saturation is allowed) or too dark
/// (mean green code below o.min_mean_code): InputError naming `source` and the window's frames.
void check_exposure(const PhaseAverage& avg, const std::string& source, const std::string& role, const AssessmentOptions& o,
                    double glare_fraction);

// ---- Where on the skin each texel lies (stage 4) ----

/// Per texel, 1-σ (mm, per axis) of where the texel's skin lies across the camera's line of sight: a pose
/// error (δθ about the camera axes, δt) moves a point p of the part (camera frame) by δθ × (p − t) + δt.
/// The lateral shift stands for the shift on the skin (the skin's tilt to the ray and refraction ignored).
/// NaN outside the chart (raster.face < 0).
ChartField position_sigma(const ChartRaster& raster, const Rigid3& cam_from_part, const PoseCovariance& covariance);

/// The camera's projection uncertainty on the chart: a pixel's ray errs by δq (σ_q px per image axis, the
/// worst direction's σ taken for both), which moves the skin point a texel reads by A·δq, A = (∂pixel/∂uv)⁻¹
/// (the inverse map's Jacobian by central differences, one-sided at its edges). Per texel: σ_q itself (px),
/// the skin position's σ per axis, σ_q·‖A‖_F/√2 (mm), and the signal's, σ_q·|Aᵀ∇y|. NaN where the inverse
/// map has no pixel or its Jacobian is singular (the signal's term also where y is undefined).
struct IntrinsicsTerm {
  ChartField pixel_sigma_px, position_mm, signal;
};
/// `width`, `height`: the camera's imager (ProjectionUncertainty::at's cells span it).
IntrinsicsTerm intrinsics_term(const InverseMap& inv, const ChartField& y, const ProjectionUncertainty& u, int width, int height);

/// The camera model's projection uncertainty over the seen contact surface (ProjectionSigmaOnContact in
/// assessment.hpp), from intrinsics_term's σ_q where `y` is defined; `inv` gives the texels' pixels.
ProjectionSigmaOnContact projection_sigma_on_contact(const IntrinsicsTerm& term, const ChartField& y, const InverseMap& inv,
                                                     double threshold_px);
/// The warning when the part falls where the camera model is unsure (largest_px above the threshold): the
/// figures, and what to do (calibrate again with boards covering that part of the view). Nothing otherwise.
void warn_projection_sigma(const ProjectionSigmaOnContact& s, std::vector<std::string>& warnings);

/// The pose's and the intrinsics' position σ in quadrature (either may be empty; NaN in one: the other).
ChartField position_sigma_total(const ChartField& pose, const ChartField& intrinsics);

/// Adds the position's σ to each hotspot's centre of pressure and centroid: a pose error shifts the whole place
/// (two lateral axes, mean σ_pos² over the place's texels), in quadrature with the noise's term.
/// `labels`: place id per texel (0 = none), as find_hotspots writes them.
void add_position_to_centres(std::vector<Hotspot>& hotspots, const std::vector<int>& labels, const ChartField& position_mm);

// ---- The signal's blur and σ (stage 4) ----

/// The deblur's difference of Gaussians, y' = y + Σ weight·(y − G_scale∗y): two terms, weights 2β²/c² and −β²/(2c²) at
/// scales c and √2·c (β² = skin_blur² + smoothing², c = BlanchingOptions::curvature_smoothing_mm). For features wider
/// than c it is y − ½β²∇²y (the blur's first-order effect undone: Σ weight·scale² = β²) with no k⁴ term left (Σ
/// weight·scale⁴ = 0), where a Laplacian of y smoothed by c reads the curvature of a wide place low (a 1.5 mm place's
/// peak by half at c = 1 mm); for finer detail (noise) its gain stays under 1 + 1.5β²/c².
struct DeblurTerm {
  double weight, scale_mm;
};
std::vector<DeblurTerm> deblur_terms(const BlanchingOptions& o);

/// The deblur's gain on the signal's per-texel noise (σ of y' over σ of y), for noise correlated as the signal's
/// smoothing (a Gaussian of max(smoothing_mm, half a texel)): closed form over the terms' Gaussians; at least 1.
/// 1.20 at 0.3 mm skin blur, 0.25 mm smoothing and c = 1 mm.
double deblur_noise_gain(const BlanchingOptions& o, double texel_mm);

/// Per texel, the blur's effect on the signal that the deblur undoes: y − y' (deblur_terms; about
/// ½·(blur² + smoothing²)·∇²y, BlanchingOptions::skin_blur_mm, smoothing_mm). The signal reads the contact pressure
/// blurred by the skin and by the feature's smoothing, which lowers a peak and raises a foot by this much. The
/// Gaussians are normalised over the seen texels; 0 where a 4-neighbour is unseen and on the grid's border.
ChartField blur_effect(const BlanchingSignal& signal, const BlanchingOptions& o);

/// The signal the pressure is read from: y with the blur's first-order effect (blur_effect) undone.
ChartField sharpened_signal(const ChartField& y, const ChartField& blur);

/// The signal's σ: its noise (signal.sigma_y, times `noise_gain`: the deblur's, deblur_noise_gain, where the sharpened signal
/// is read; 1 where y is), the blur's first-order effect (the pressure undoes it, and
/// its size stands for what the first order misses), the intrinsics' term (IntrinsicsTerm::signal; may be
/// empty) and, where the pose is uncertain, |∇y'|·σ_pos, in quadrature, with y' the sharpened signal (∇ by
/// central differences on the chart, one-sided beside unseen texels; position_mm may be empty).
ChartField signal_sigma(const BlanchingSignal& signal, const ChartField& position_mm, const ChartField& intrinsics_signal,
                        const ChartField& blur, double noise_gain = 1.0);

// ---- Pressure (stage 5) ----

/// The detection gate of one texel: the calibration's `gate` (a signal) holds for a texel of the capture's typical
/// noise (`typical_sigma`, the median σ_y); a texel whose own `sigma_y` is larger needs that many times more,
/// gate · max(1, sigma_y / typical_sigma): the same significance everywhere. Beside a glare mask or the seen outline
/// a texel's smoothing holds fewer camera pixels (and at the band's oblique ends one pixel spans several texels), so
/// its σ_y is larger: within 5 texels of a mask 1.37× the median on average, up to 2.2× (quarter-scale wristband,
/// 27 glare cases, seeds 21-25), while y/σ_y kept a spread of 1.0 there as inside. With the calibration's gate
/// alone (3 σ of its presses' noise: 5.5-6 σ of these captures' median σ_y, 3-4 σ where σ_y is 1.5-2× it) such
/// texels crossed it on noise: a false 0.64 mm² place of 5.3 kPa beside a highlight that appears when worn, 0.3-0.5 mm²
/// places of 4.8-5.0 kPa at the band's oblique end on one seed of five, and PhotometricCli's glare scene sat at 0.99 of
/// the gate beside its mask. With the local gate the unpressed texel nearest its gate is at 0.80 of it within 15 texels
/// of a mask (was 1.22) and 0.79 elsewhere (was 1.15): 0 false places, the true places unchanged (the hysteresis
/// reads their tails).
/// `gate` itself where either σ is unknown or not positive.
double local_gate(double gate, double sigma_y, double typical_sigma);

/// The σ a texel's detection is judged by: its noise σ_y and, when the gap was estimated, the gap's term
/// (Assessment::gap_signal_sigma) in quadrature.
double detection_sigma(const Assessment& a, std::size_t texel);

/// The signal turned into pressure through the calibration (PressureCalibration::invert of the sharpened
/// signal, a.signal_sigma its σ): fills a.calibrated, a.pressure, a.pressure_sigma, a.pressure_status and
/// the summary figures: below-detection and saturated fractions of the seen texels; peak and mean kPa over every
/// seen texel, below detection as 0 kPa (σ NaN), saturated at its lower bound. A texel (saturated or not) below the
/// calibration's detection signal, raised where its detection_sigma is above the median σ_y (local_gate), is below
/// detection. With `spatial_noise` (a lossy capture, or phases with their own geometry) a texel below
/// o.signal_threshold_sigmas of its own detection_sigma is below detection too.
/// Reads a.signal, a.blur_effect (may be empty) and a.signal_sigma; returns 1 per saturated texel.
/// Also fills a.detection_limit (detection_limit below, at a.signal.noise_sigma).
std::vector<std::uint8_t> calibrated_pressure(const PressureCalibration& calibration, bool spatial_noise, const AssessmentOptions& o,
                                              Assessment& a);

/// What the deblur leaves of the blur, signed, in the signal's unit: r = y' − D(G_β∗y'), with D the deblur (deblur_terms)
/// and β² = skin_blur² + smoothing². D approximates G_β⁻¹ and misses M = G_β⁻¹ − D (chiefly the β⁴∇⁴/8 of G_β⁻¹'s
/// series and the difference of Gaussians' own −β²c⁴∇⁶/24); y' = D y, so r = M G_β y' = M y − M G_β M y: the miss
/// on y less a second-order term. On the noise-free chain (scripts/deblur-bias.py, its last part) of a 10 kPa Gaussian
/// place the miss averages 0.118 kPa over the place read at ≥ 6.5 kPa and r reads 0.094 (σ 1.5 mm; 0.475 and 0.298 at
/// 1 mm, 0.041 and 0.034 at 2 mm). NaN where a 4-neighbour is unseen (the deblur leaves such a texel as it is) and on
/// the grid's border.
ChartField deblur_residual(const ChartField& sharpened, const BlanchingOptions& o);

/// What the logistic's curvature leaves in the estimate (kPa, signed, truth less estimate): the signal reads the
/// logistic f of the pressure blurred by the skin (b = `skin_blur_mm`, before the logistic), and G_b∗f(p) =
/// f(G_b∗p) + ½b²f''(p)|∇p|² to first order in b², so the deblurred signal is f(p) − ½b²f''|∇p|² and the pressure read
/// from it ½b²(f''/f')|∇p|² low, f''/f' = (1 − 2σ((p − p50)/w))/w: low below p50 where the slope is steep (a place's
/// outline), high above it. |∇p| is read on `pressure` blurred by b (normalised over its finite texels). 0 for a
/// linear calibration or b = 0; NaN where `pressure` is.
ChartField logistic_residual(const PressureCalibration& calibration, const ChartField& pressure, double skin_blur_mm);

/// The parts of each texel's pressure σ that are not noise (PressureSigmaParts): the calibration's parameters alone, the
/// blur's first-order term's share (the inverse with σ_y = |blur_effect| beyond the parameters'), each through the
/// calibration's inverse at the sharpened signal, and the residual: the inverse at y' + deblur_residual (smoothed by
/// β, its noise left out) less that at y', plus logistic_residual on the pressure read (o.skin_blur_mm). NaN where a.pressure_sigma is (the residual also
/// where it is unknown). Reads a.signal, a.blur_effect (may be empty: no blur share, no residual).
PressureSigmaParts pressure_sigma_parts(const PressureCalibration& calibration, const Assessment& a, const BlanchingOptions& o);

/// The detection limit calibrated_pressure applies, for a texel of σ_y = `noise_sigma` (the capture's median): the
/// gate is the calibration's detection_signal (detection_sigmas of its presses' noise) and, with `spatial_noise`, at
/// least o.signal_threshold_sigmas · noise_sigma; kpa is the calibration's inverse there (its top when the gate is
/// beyond saturation). tail_kpa: the inverse at o.hysteresis_sigmas · noise_sigma, where a detected place's tail
/// ends (NaN when that is not under the gate: the hysteresis is off).
DetectionLimit detection_limit(const PressureCalibration& calibration, double noise_sigma, bool spatial_noise, const AssessmentOptions& o);

/// One warning per hotspot threshold (kPa) below the detection limit, naming the threshold and the limit in kPa and
/// what it counts in. Below the limit and below the tail's (tail_kpa; or with the hysteresis off): a place's outline
/// there is where the signal stops being significant, not where the pressure crosses the threshold, so its areas are
/// underestimated (and their σ does not model it; SigmaCoverage's captures at 3 kPa, under a 3.4 kPa tail: 9-19 %
/// small, z down to -20). Between the tail's and the limit: a place is found only where it reaches the limit, but the
/// areas of those found hold (at 4.3 kPa under a 5.3-5.6 kPa limit: -8 % and +1 %, within their σ). Nothing when the
/// limit is NaN.
void warn_thresholds_below_detection(const std::vector<double>& thresholds_kpa, const DetectionLimit& limit,
                                     std::vector<std::string>& warnings);

// ---- The values at the mesh's vertices (stage 7) ----

/// Which chart vertices the camera sees in the worn capture, and how far (texels) a vertex may look for its
/// value. A vertex is seen where a texel the worn map sees (`inv.valid`, not `excluded`: the glare mask) lies
/// within `pixels` camera pixels of it, a pixel measured on the skin at that texel (its footprint's longer
/// axis, 1/σ_min(∂pixel/∂uv): long where the skin is seen obliquely), and at least kVertexReachTexels. The
/// texels between a contact-boundary vertex and the first seen pixel lie beyond the contact surface, so a
/// fixed reach in texels leaves such vertices unseen. Per vertex: that reach (the largest of the texels that
/// see it), NaN where the camera does not see it or it has no chart coordinate.
std::vector<float> vertex_reach_texels(const InverseMap& inv, const std::vector<std::uint8_t>& excluded, const Chart& chart,
                                       double pixels);

/// The field at the vertices `reach_texels` says are seen: the bilinear sample (ChartField::sample), else the
/// nearest defined texel within the vertex's reach plus `extra_mm` (the signal's smoothing: where the signal
/// stops short of the seen skin, as along the boundary a held baseline's map cannot see, the nearest value
/// is within the field's own resolution). NaN elsewhere.
std::vector<float> vertex_values(const ChartField& field, const Chart& chart, const std::vector<float>& reach_texels, double extra_mm);

}  // namespace clearfit
