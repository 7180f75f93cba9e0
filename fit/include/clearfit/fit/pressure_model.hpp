#pragma once
// The per-person blanching → pressure calibration (SKIN.md, "A calibration
// model (per person)").
//
// Signal y = ln[(G/G0)/(G_ref/G_ref0)] (dimensionless; 0 = no change).
// Forward model (logistic): y(p) = y_max · Ψ((p − p50)/w), with the normalised
// logistic Ψ(z) = (σ(z) − σ(z0)) / (1 − σ(z0)), z0 = −p50/w, so y(0) = 0 and
// y → y_max. The study's linear model y = a + b·p is offered for comparison
// (PAPER.md: mean R² = 0.439).
//
// Calibration presses (known indenter, known force) are read from a CSV file,
// fitted robustly (Levenberg–Marquardt inside iteratively reweighted least
// squares), written to / read from a `clearfit.pressure-calibration/1` JSON
// file, and inverted in closed form with an uncertainty. The inverse never
// extrapolates: below the detection limit (3 σ of the signal noise) it reports
// "below detection", above the saturation signal it reports "saturated" with
// a lower bound.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace clearfit {

/// One calibration press: an indenter of known diameter pressed with a known
/// force; `signal` is the feature y averaged over the indenter area.
struct CalibrationPress {
  std::string trial;                 ///< trial label from the file (non-empty)
  double indenter_diameter_mm = 0;   ///< NaN when the file does not give it
  double force_n = 0;                ///< NaN when the file does not give it
  double mean_pressure_kpa = 0;      ///< given, or force / (π r²)
  double signal = 0;                 ///< y, dimensionless
  int line = 0;                      ///< line in the CSV file (0: built in memory)
  /// The radially resolved signal (`clearfit presses`): ring k spans
  /// [ring_edges_mm[k], ring_edges_mm[k+1]) from the indenter's axis on the skin;
  /// ring_signal[k] is y averaged there. Empty when the file has no profile.
  std::vector<double> ring_edges_mm, ring_signal;
  /// A spherical indenter's radius (mm; column `sphere_radius_mm`): its pressure is Hertz's over a
  /// contact radius that grows with the force, and indenter_diameter_mm is the disc `signal` was read
  /// over. NaN: a flat indenter.
  double sphere_radius_mm = std::numeric_limits<double>::quiet_NaN();
};

/// Reads calibration presses from a CSV file with a header row naming the
/// columns (any order): `trial`, `signal`, and `mean_pressure_kpa` or both
/// `force_n` and `indenter_diameter_mm` (all four may be given; an empty field
/// counts as not given). Mean pressure = 1000 · F / (π (d/2)²) kPa (F in N, d in
/// mm); when force, diameter and mean pressure are all given they must agree
/// within 1 % (+0.01 kPa). Blank lines and lines starting with '#' are
/// skipped; CRLF line ends are accepted. Unknown columns are ignored and named
/// in `notes` (if given). Every field is validated: throws InputError naming
/// the file, the line and column, what was expected (missing column, text in a
/// number, non-finite value, negative force or pressure, non-positive
/// diameter, wrong field count, inconsistent pressure, no data rows).
/// Optional columns `ring_edges_mm` (n + 1 increasing radii) and `ring_signal`
/// (n values), each ';'-separated, give the radial profile; other columns
/// written by `clearfit presses` (force_sd_n, hold_frames, rest_frames, sphere_radius_mm) are known;
/// sphere_radius_mm, when given, must be > 0.
std::vector<CalibrationPress> read_presses_csv(const std::filesystem::path& path,
                                               std::vector<std::string>* notes = nullptr);

enum class PressureModelKind { logistic, linear };
const char* to_string(PressureModelKind kind);

/// The logistic model's parameters.
struct LogisticParams {
  double y_max = 0;      ///< saturation signal (> 0)
  double p50_kpa = 0;    ///< pressure of the logistic's midpoint, kPa
  double width_kpa = 0;  ///< logistic width w (> 0), kPa
};

/// y(p) of the logistic model (p in kPa). Exactly 0 at p = 0.
double logistic_signal(const LogisticParams& m, double p_kpa);
/// ∂y/∂(y_max, p50, w) at p (analytic), for the fit and the uncertainty.
Eigen::Vector3d logistic_gradient(const LogisticParams& m, double p_kpa);

/// Status of an inverted signal value.
enum class PressureStatus : std::uint8_t {
  ok = 0,               ///< pressure_kpa is the estimate
  below_detection = 1,  ///< signal < detection limit: pressure_kpa NaN, bound_kpa an upper bound
  saturated = 2,        ///< signal > saturation: pressure_kpa = bound_kpa, a lower bound
  invalid = 3,          ///< non-finite signal: everything NaN
};
const char* to_string(PressureStatus status);

struct PressureEstimate {
  double pressure_kpa = 0;  ///< see PressureStatus
  double sigma_kpa = 0;     ///< 1-σ uncertainty (signal noise and parameter covariance); NaN unless ok
  double bound_kpa = 0;     ///< upper bound (below detection), lower bound (saturated), else NaN
  PressureStatus status = PressureStatus::ok;
};

/// A fitted per-person calibration: what the calibration file holds.
struct PressureCalibration {
  PressureModelKind model = PressureModelKind::logistic;
  LogisticParams logistic;            ///< used when model == logistic
  double intercept = 0;               ///< linear: a (signal at 0 kPa)
  double slope_per_kpa = 0;           ///< linear: b (> 0), 1/kPa
  /// Covariance of (y_max, p50_kpa, width_kpa) for logistic, of (a, b) in the
  /// top-left 2×2 for linear (the rest zero).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double noise_sigma = 0;             ///< 1-σ noise of one press's signal (robust scale of the residuals)
  std::string person;                 ///< who was calibrated (non-empty)
  std::string camera_hash;            ///< intrinsics hash (16 hex digits) or empty: any camera
  std::string created;                ///< ISO 8601 UTC time of the fit
  double p_min_kpa = 0, p_max_kpa = 0;  ///< range of the calibration presses' mean pressure
  double rmse_kpa = 0;                ///< quality (informational): inverse-predicted vs known pressure
  double r2 = 0;                      ///< R² of the signal for this model
  double r2_linear = 0;               ///< R² of the study's linear model on the same presses
  int presses = 0;                    ///< number of presses fitted
  /// The skin's lateral blur (mm) the field fit assumed: its curve maps the signal to the contact pressure blurred by
  /// it, so an assessment undoes the same blur (skin_blur.hpp). NaN: not modelled (the uniform fit, F/πa² against the
  /// disc's mean signal) or a file written before it was recorded.
  double skin_blur_mm = std::numeric_limits<double>::quiet_NaN();
  std::filesystem::path path;         ///< file it was read from (empty in memory); named in errors

  /// Forward model y(p), p in kPa.
  double signal(double p_kpa) const;
  /// A signal is detected when it exceeds this many of its own noise σ: the calibration's presses
  /// (detection_signal) and, in an assessment whose capture has its own noise, each texel's σ.
  static constexpr double detection_sigmas = 3.0;
  /// Detection limit: detection_sigmas · noise_sigma.
  double detection_signal() const { return detection_sigmas * noise_sigma; }
  /// Highest signal inverted without flag: the smaller of 95 % of y_max and
  /// the signal at p_max_kpa (logistic), the signal at p_max_kpa (linear,
  /// which has no saturation): above it the inverse would extrapolate.
  double saturation_signal() const;
  /// Inverse at one signal value (closed form). sigma_y: 1-σ noise of this
  /// value (NaN: use noise_sigma). Propagation: σ_p² = (dp/dy)² σ_y² + gᵀ C g
  /// with g = ∂p/∂θ at fixed y and C the parameter covariance. Below the
  /// detection limit (or an inverse below 0 kPa) → below_detection; above
  /// saturation_signal() → saturated with the pressure there as lower bound.
  PressureEstimate invert(double y, double sigma_y = std::numeric_limits<double>::quiet_NaN()) const;
  /// Vectorised inverse over a field (e.g. a ChartField's values), parallel.
  /// pressure_kpa, sigma_kpa and status must have signal.size() elements;
  /// sigma_y is empty (noise_sigma everywhere) or one value per element.
  /// pressure_kpa / sigma_kpa follow PressureEstimate (bounds are not stored:
  /// saturated elements hold their lower bound, below-detection ones NaN).
  /// detection_limit: the signal below which an element is below detection (NaN: detection_signal()).
  void invert(std::span<const float> signal, std::span<const float> sigma_y, std::span<float> pressure_kpa,
              std::span<float> sigma_kpa, std::span<std::uint8_t> status,
              double detection_limit = std::numeric_limits<double>::quiet_NaN()) const;
  /// Standard errors: square roots of the covariance diagonal.
  Eigen::Vector3d standard_errors() const;
};

enum class RobustLoss { none, huber, tukey };
const char* to_string(RobustLoss loss);

struct PressureFitOptions {
  PressureModelKind model = PressureModelKind::logistic;  ///< the model stored as the calibration
  /// Loss of the logistic fit: none (plain least squares), huber (k = 1.345),
  /// tukey (biweight c = 4.685, started from the Huber solution). The linear
  /// model is always ordinary least squares (as in the study).
  RobustLoss loss = RobustLoss::tukey;
  std::string person;        ///< required, non-empty
  std::string camera_hash;   ///< optional
  std::string source;        ///< name of the presses' file, for error messages
  int max_iterations = 200;  ///< LM iterations per IRLS round
  /// Throws std::invalid_argument naming the field when an option is unusable.
  void validate() const;
};

/// One press's residuals after the fit.
struct PressResidual {
  std::string trial;
  double pressure_kpa = 0;        ///< known mean pressure
  double signal = 0;              ///< measured y
  double residual_signal = 0;     ///< y − y_model(p) (of the stored model)
  double residual_linear = 0;     ///< y − (a + b p)
  double predicted_kpa = 0;       ///< inverse of y (NaN unless the status is ok)
  double residual_kpa = 0;        ///< predicted − known (NaN unless ok)
  double weight = 1;              ///< final robust weight (logistic fit), 1 = full
  PressureStatus status = PressureStatus::ok;
};

struct LinearFit {
  double intercept = 0, slope_per_kpa = 0;
  double se_intercept = 0, se_slope = 0;
  double r2 = 0;
};

struct PressureFitResult {
  PressureCalibration calibration;  ///< the model chosen in the options
  LogisticParams logistic;          ///< the logistic fit (always made)
  Eigen::Vector3d logistic_se = Eigen::Vector3d::Zero();  ///< SE of (y_max, p50, w)
  double r2_logistic = 0;
  LinearFit linear;                 ///< the study's model, OLS
  /// RMSE of inverse-predicted vs known pressure over the presses inside the
  /// invertible range: known pressure between the detection and saturation
  /// pressures, signal inverted without flag (of the stored model).
  double rmse_kpa = 0;
  int presses_in_range = 0;         ///< presses used for rmse_kpa
  double rmse_kpa_inliers = 0;      ///< the same without the presses the robust fit down-weighted (weight < 0.5)
  int levels = 0;                   ///< distinct pressure levels found
  bool converged = true;
  int iterations = 0;               ///< LM iterations over all IRLS rounds
  /// The Hertz field fit (a spherical indenter): the skin's plane-strain modulus E* (kPa) it used,
  /// fitted (with its SE) or given (SE 0); NaN for the other fits.
  double e_star_kpa = std::numeric_limits<double>::quiet_NaN(), e_star_se_kpa = std::numeric_limits<double>::quiet_NaN();
  std::vector<PressResidual> residuals;
  std::vector<std::string> warnings;  ///< too few levels, no data near p50, no saturation, non-monotone, outliers
};

/// Fits the calibration. Initial guess: a coarse grid over (p50, w) with y_max
/// solved linearly; then Levenberg–Marquardt on (ln y_max, p50, ln w) (so
/// y_max, w > 0) with robust weights by IRLS (scale: Huber's proposal 2,
/// started from 1.4826 · MAD; the Tukey stage keeps the Huber fit's scale).
/// Covariance: Huber's M-estimator formula s²·[Σψ²/(n−3)]/mean ψ'·(Σψ' g gᵀ)⁻¹
/// (σ̂²(JᵀJ)⁻¹ for plain least squares). noise_sigma: s·sqrt(Σψ²/((n−3)E[ψ²])),
/// consistent for Gaussian noise, bounded influence of outliers. Throws InputError (naming options.source) when
/// there are fewer than 4 presses, all at one pressure, or the signal does
/// not rise with pressure.
PressureFitResult fit_pressure_calibration(const std::vector<CalibrationPress>& presses,
                                           const PressureFitOptions& options);

/// Writes `cal` as JSON (`clearfit.pressure-calibration/1`), atomically.
void write_pressure_calibration(const PressureCalibration& cal, const std::filesystem::path& path);
/// Reads a calibration file. Throws InputError naming the file and the key
/// (or the line of a JSON syntax error) for a wrong schema, a missing key, a
/// wrong type or an impossible value (y_max ≤ 0, w ≤ 0, noise < 0, ...).
PressureCalibration read_pressure_calibration(const std::filesystem::path& path);

/// 16 lowercase hex digits of a CameraModel::intrinsics_hash().
std::string format_intrinsics_hash(std::uint64_t hash);
/// Throws InputError when the scene's person differs from the calibration's,
/// or when both have a camera hash and they differ (names both values).
/// Returns notes (e.g. "the calibration names no camera; not checked").
std::vector<std::string> check_calibration_matches(const PressureCalibration& cal, const std::string& person,
                                                   const std::string& camera_hash);

}  // namespace clearfit
