#pragma once
// The fit assessment: captures → window averages → blanching signal on the
// chart → pressure (with a per-person calibration) → hotspots → values per
// mesh vertex. The caller hands in the traced part (forward and inverse
// refraction maps); this module reads the captures and computes; the reports
// module turns the result into files.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose_file.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/fit/baseline_gap.hpp>
#include <clearfit/fit/blanching.hpp>
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/glare.hpp>
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/fit/outline.hpp>
#include <clearfit/fit/phase_registration.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/fit/timeseries.hpp>
#include <clearfit/fit/vignetting.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <clearfit/refraction/map.hpp>

#include <functional>
#include <optional>

namespace clearfit {

/// Either two captures (baseline = not worn, worn) or one holding both phases.
struct CaptureSources {
  std::filesystem::path baseline, worn, both;
};

struct AssessmentOptions {
  int window_frames = 100;           ///< frames averaged per phase (the study: 100)
  int chunk_frames = 5;              ///< granularity of the windows, frames
  bool compensate_motion = true;
  double max_motion_px = 10.0;
  /// Memory for one capture's chunk sums, MB. One video holding both phases whose sums outgrow
  /// it is read a second time, keeping the sums of its two windows only (bounded memory).
  double max_sums_mb = 1024;
  BlanchingOptions blanching;
  GlareOptions glare;                ///< specular highlights masked out of the signal (glare.hpp)
  bool normalise_gains = true;       ///< divide each chunk by its exposure / white-balance / flicker gain (photometric.hpp)
  GapSearchOptions gap;              ///< estimating the not-worn capture's gap (baseline_gap.hpp)
  OutlineOptions outline;            ///< the camera's move between the phases, from the part's outline (outline.hpp)
  PhaseRegistrationOptions phase_registration;  ///< skin that slid or bulged between the phases (phase_registration.hpp)
  VignettingOptions vignetting;      ///< the fall-off between phases seen at different pixels (vignetting.hpp)
  std::vector<double> thresholds_kpa{4.3, 5.5};  ///< capillary closing, the study's blanching onset
  /// Without a calibration: thresholds on the signal y, in multiples of the
  /// noise (default 5 σ) unless given as values.
  std::vector<double> signal_thresholds;
  double signal_threshold_sigmas = 5.0;
  /// With a calibration: a texel below detection keeps its estimate where its signal is at least this many
  /// of its own σ and it is connected, through such texels, to a detected one (hysteresis; the detection
  /// gate itself is the calibration's, or signal_threshold_sigmas with a capture's own noise). At the gate
  /// or above: off.
  double hysteresis_sigmas = 2.0;
  double min_hotspot_area_mm2 = 0.05;
  /// Lossy captures: a texel whose camera pixel lies within this many pixels of the seen skin's outline
  /// (in the worn capture or, through its own map, the baseline), or within half as many of the glare mask
  /// (in the worn capture), is unseen. The codec's blocks straddle the edge between the skin and what lies
  /// beside the part (or a highlight), and the error they leave there does not cancel between the phases (a
  /// held baseline reads the texel at another pixel). 16: one H.264 macroblock. On scripts/bench-lossy.sh
  /// (seeds 31 and 32, 640x360 and 960x540, CRF 18-28): 8 left a false place at the band's oblique end
  /// (CRF 18); the glare's edge at 16 too cost 24-39 % of the seen skin, at 8 15-24 %, both without a false place.
  double lossy_outline_px = 16;
  TimeSeriesOptions timeseries;          ///< the worn phase over time (timeseries.hpp)
  double max_saturated_fraction = 0.02;  ///< more saturated pixels than this in a window is an error
  double min_mean_code = 10.0;           ///< a darker window (mean 8-bit green) is an error
  /// The camera model's projection uncertainty (1-σ px, ProjectionUncertainty) above which the part is said
  /// to lie where the calibration did not reach: a warning names the largest σ over the seen contact
  /// surface and asks for boards covering that part of the view. 0.5 px: 30 boards, corners at 0.3 px: σ_q 0.085 px at the
  /// centre, 0.63 at the image corners (ctest -V -R MatchesMrcalCalibrateCameras); the error against the true lens 0.05-0.06,
  /// 0.45-0.68 at worst where corners were seen, 1.36-1.93 at worst (README "Calibration"). σ_q is noise, not bias.
  double max_projection_sigma_px = 0.5;
  /// Progress: stage name, done, total (0: unknown).
  std::function<void(const std::string&, int, int)> progress;
};

struct PhaseReport {
  std::string source;
  int frames_total = 0;
  FrameWindow window;
  double fps = 0;
  double motion_px_max = 0, jitter_px_rms = 0;
  double rotation_deg_max = 0, rotation_scale_px_max = 0;  ///< measured, not undone (capture.hpp)
  bool motion_compensated = false;
  double saturated_fraction = 0, mean_code = 0;
  double gain_min = 1, gain_max = 1, gain_sigma = 0;  ///< per-chunk gains divided out of the window (photometric.hpp)
  // How the capture was coded and decoded (frame_reader.hpp).
  std::string codec, pixel_format, colour_matrix;
  bool lossy = false, limited_range = false;
  int rotation_deg = 0, bit_depth = 8;
};

struct Coverage {
  double contact_area_mm2 = 0;   ///< the charted contact surface
  double seen_area_mm2 = 0;      ///< seen through the part, in both averages
  double hidden_outside_view_mm2 = 0;   ///< projects outside the image
  double hidden_blocked_mm2 = 0;        ///< inside the image but not seen through the part
  double glare_masked_mm2 = 0;          ///< seen through the part but masked as glare (glare.hpp)
  std::string blocked_reason;           ///< the forward map's dominant reason for pixels that miss the skin
};

/// The not-worn capture's geometry as assessed (baseline_map.hpp).
struct BaselineGeometryReport {
  BaselinePart part = BaselinePart::touching;
  double gap_mm = 0, gap_sigma_mm = 0;  ///< sigma 0 when given
  bool gap_estimated = false;           ///< estimated from the captures (auto)
  std::optional<GapEstimate> estimate;  ///< the estimate's details (auto)
  /// How far the skin texture moved in the image between the phases' first frames (the camera's
  /// move or the skin's slide: texture alone cannot tell them apart), measured with the gap
  /// (GapEstimate::phase_shift_px) so that it does not bias it; the phase registration follows it.
  Vec2 phase_shift_px = Vec2::Zero(), phase_shift_sigma_px = Vec2::Zero();
  bool phase_shift_measured = false;
  long long pixels_seeing_skin = 0;     ///< in the baseline's own map
  /// The gap's σ in the signal over the seen texels (Assessment::gap_signal_sigma): its median and largest; 0 when not carried.
  double signal_sigma_median = 0, signal_sigma_max = 0;
  double unseen_off_gap_mm2 = 0;        ///< seen at the gap but at neither gap ± σ: unseen (the seen skin's edge moves across it)
  VignettingEstimate vignetting;        ///< the fall-off divided out of the comparison (own geometry only)
};

/// The camera's move since the pose, from the contact surface's outline (outline.hpp): the worn average's
/// outline against the map's, and the worn capture read displaced by it.
struct PhaseMoveReport {
  bool measured = false;             ///< the worn capture's outline found
  bool applied = false;              ///< the worn capture was read displaced by move_px
  std::optional<Vec2> baseline_px;   ///< the not-worn capture's outline against its map's (reported only; not when not found)
  Vec2 worn_px = Vec2::Zero();       ///< the worn capture's first frame's outline against the map's
  Vec2 move_px = Vec2::Zero(), sigma_px = Vec2::Zero();     ///< the displacement applied, 1-σ per axis
  double contrast = 0;               ///< the step across the worn capture's outline (relative)
  std::string problem;               ///< why it was not measured (empty when measured)
};

/// The camera model's projection uncertainty over the seen contact surface (the texels where the signal
/// is defined): the largest σ_q (px) and the camera pixel it is at, the share of the seen texels above
/// the threshold, and the largest skin position σ (mm) it gives. Empty (texels 0) without the term.
struct ProjectionSigmaOnContact {
  long long texels = 0;            ///< seen texels with a σ_q
  double largest_px = 0;           ///< the largest σ_q over them
  Vec2 largest_at_px = Vec2::Zero();  ///< the camera pixel of that texel
  double median_px = 0;
  double threshold_px = 0;         ///< AssessmentOptions::max_projection_sigma_px
  double fraction_above = 0;       ///< of the seen texels, σ_q above the threshold
  double position_mm = 0;          ///< the largest skin position σ over the seen texels (mm, per axis)
};

/// Where a calibrated assessment stops seeing pressure: the detection gate on the signal for the median texel's noise,
/// and the pressure there (detection_limit in assessment_stages.hpp). Below it a texel reads 0 kPa unless it is a
/// detected place's tail (hysteresis, down to tail_kpa).
struct DetectionLimit {
  double signal = std::numeric_limits<double>::quiet_NaN();  ///< the gate's signal y
  double kpa = std::numeric_limits<double>::quiet_NaN();     ///< the pressure whose signal is at the gate
  double sigmas = 0;                                         ///< the gate in σ of the noise below
  double noise_sigma = 0;                                    ///< the noise the gate counts in: the capture's median σ_y, or the calibration presses'
  bool capture_noise = false;                                ///< the gate is the capture's own noise's (lossy, or a baseline with its own geometry)
  double tail_kpa = std::numeric_limits<double>::quiet_NaN(); ///< the pressure at hysteresis_sigmas of the capture's noise (NaN: the hysteresis is off)
};

/// The parts of a texel's pressure σ that are not noise, and the deblur's residual (kPa, on the chart grid; NaN where
/// pressure_sigma is). The hotspots (HotspotOptions) take `shared` undivided in a place's mean and area, take `blur`
/// out of the noise and leave it out of a place's figures, which take the mean of `residual` instead.
struct PressureSigmaParts {
  /// The calibration's parameters (one curve for every texel) and the estimated gap's term (one gap;
  /// Assessment::gap_signal_sigma): one error over a whole place.
  ChartField shared;
  /// The blur's first-order term (|blur_effect| through the inverse): each texel's allowance for what the deblur
  /// gets wrong there, larger than what a place's mean or outline gets wrong (the residual).
  ChartField blur;
  /// Signed, truth less estimate: what the deblur leaves (deblur_residual, in kPa) and what the logistic's curvature
  /// on the skin's blur leaves (logistic_residual); NaN where unknown.
  ChartField residual;
};

struct Assessment {
  PhaseReport baseline, worn;
  BaselineGeometryReport baseline_geometry;
  PhaseMoveReport phase_move;
  std::optional<PhaseSplit> split;
  BlanchingSignal signal;
  ChartRaster raster;
  bool calibrated = false;
  ChartField pressure;                       ///< kPa (0 below detection, NaN unseen); empty without a calibration
  /// 1-σ of `pressure`, kPa, where it is an estimate (PressureStatus::ok); NaN unseen, below detection
  /// (0 kPa there is a bound, not an estimate) and saturated (a lower bound).
  ChartField pressure_sigma;
  /// The parts of pressure_sigma that a place's figures take otherwise than noise (pressure_sigma_parts,
  /// assessment_stages.hpp).
  PressureSigmaParts pressure_sigma_parts;
  std::vector<std::uint8_t> pressure_status; ///< PressureStatus per texel (invalid where unseen)
  double below_detection_fraction = 0, saturated_fraction = 0;  ///< of seen texels
  double peak_kpa = 0, mean_kpa = 0;         ///< over every seen texel: below detection as 0, saturated at its lower bound
  DetectionLimit detection_limit;            ///< the capture's detection limit in kPa (assessment_stages.hpp); NaN uncalibrated
  std::vector<Hotspot> hotspots;
  std::vector<double> thresholds;            ///< the thresholds used, in the field's unit
  std::vector<int> hotspot_labels;           ///< place id per texel (0 = none), for outlines
  /// Per texel, 1-σ (mm, per axis across the line of sight) of where on the skin the texel lies, from the
  /// pose's covariance; empty when it is unknown. Its signal term |∇y|·σ is in signal_sigma.
  ChartField position_sigma_mm;
  /// Per texel, 1-σ (mm, per chart axis) of where on the skin the texel lies from the camera model's
  /// projection uncertainty (σ_q px at the texel's pixel through the inverse map's Jacobian A: σ_q·‖A‖_F/√2);
  /// empty when the model carries none. Its signal term σ_q·|Aᵀ∇y| is in signal_sigma; the hotspots'
  /// centres take it in quadrature with the pose's.
  ChartField intrinsics_sigma_mm;
  /// The projection uncertainty over the seen contact surface (assessment_stages.hpp); texels 0 without it.
  ProjectionSigmaOnContact projection_on_contact;
  /// 1-σ of the signal per texel: the noise (signal.sigma_y; with a calibration times the deblur's noise gain,
  /// deblur_noise_gain), the blur's term and the position term in quadrature; inverted into pressure_sigma, and
  /// the σ of the hotspots without a calibration.
  ChartField signal_sigma;
  /// 1-σ of the signal per texel from the estimated gap's σ (GapSearchOptions::sigma_in_signal): in signal_sigma and,
  /// with signal.sigma_y, in the detection gate; empty when the gap was given or the baseline touches.
  ChartField gap_signal_sigma;
  ChartField blur_effect;    ///< y − y', about ½·(skin blur² + smoothing²)·∇²y per texel (blur_effect): undone in the pressure, part of signal_sigma
  std::vector<float> vertex_pressure, vertex_signal;  ///< per mesh vertex, NaN where unseen / off the contact
  std::vector<float> vertex_pressure_sigma;  ///< 1-σ of vertex_pressure (kPa); NaN where pressure_sigma is undefined around it
  cv::Mat skin_camera;                       ///< last worn frame (BGR8), as the camera saw it, glare mask outlined in magenta
  cv::Mat skin_chart;                        ///< the same resampled onto the chart (BGR8)
  Coverage coverage;
  GlareMask glare;                           ///< the glare mask in the camera image (roi of the captures)
  std::vector<std::uint8_t> glare_texels;    ///< per chart texel: 1 = masked as glare
  PhaseRegistration phase_registration;      ///< the skin's displacement between the phases (applied = false when off)
  TimeAnalysis time;                         ///< the worn phase over time (timeseries.hpp); present = false when off
  std::vector<std::string> warnings;
  double read_ms = 0, work_ms = 0, total_ms = 0;
};

/// The traced part the assessment works on.
struct AssessmentScene {
  const Mesh* mesh = nullptr;
  const ContactSurface* contact = nullptr;
  const Chart* chart = nullptr;
  const CameraModel* camera = nullptr;
  Rigid3 cam_from_part;
  const RefractionMap* forward = nullptr;
  const InverseMap* inverse = nullptr;
  /// The pose's covariance (camera/pose_file.hpp); nullptr: unknown (no position term in the σ).
  const PoseCovariance* pose_covariance = nullptr;
  /// The not-worn capture's geometry: touching (forward and inverse serve both
  /// phases), or held / absent through `baseline_rays` at the gap given, or
  /// estimated from the captures (estimate_gap) when none is given.
  BaselinePart baseline_part = BaselinePart::touching;
  std::optional<double> baseline_gap_mm;
  const BaselineRays* baseline_rays = nullptr;
  InverseMapOptions inverse_options;  ///< those `inverse` was made with: the baseline's inverse map shares its grid
  /// The camera model's projection uncertainty (projection_uncertainty.hpp); nullptr: unknown (no term for it
  /// in the σ, and a warning says so).
  const ProjectionUncertainty* projection_uncertainty = nullptr;
};

/// Runs the assessment. Throws InputError on bad captures (see capture.hpp),
/// windows longer than the captures, saturated or dark windows, a missing
/// phase, a baseline gap that matters but cannot be estimated.
Assessment assess_captures(const AssessmentScene& scene, const CaptureSources& captures,
                           const std::optional<PressureCalibration>& calibration, const AssessmentOptions& options);

}  // namespace clearfit
