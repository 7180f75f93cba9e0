#pragma once
// The worn phase over time. While a capture is read, every frame's linear
// green (aligned like the averages: at the frame's integer shift) is averaged
// over square cells of the roi (`cell_px`) and summed into time bins of
// `bin_frames` frames. Memory is bounded: when the bins would exceed the budget
// (`max_mb`), neighbouring bins are merged in pairs and the bin doubles, so a
// long capture keeps its whole duration at a coarser time step (the step is
// reported; see docs/assessment-outputs.md for the figures).
//
// After the assessment, the cells are turned into the blanching signal per bin,
// as the averages are (capture.hpp, blanching.hpp): y = ln(G / G0) against the
// baseline window, minus that bin's median over the seen cells (exposure,
// flicker and pulse change all cells alike). Per place (hotspots.hpp) and per
// level of it (the texels at or above each threshold in the worn average), the
// series is the mean green of its texels' cells; with a calibration also in kPa
// (the calibration's inverse of the series). From it:
//  - the onset: y = A·(1 − exp(−(t − t0)/τ_on)) after t0, 0 before, fitted
//    (Levenberg–Marquardt, Eigen) to the bins around the press, each bin
//    the model's mean over its frames: t0 and τ_on with 1-σ errors;
//  - for each threshold, the first time the level's series reaches it and the
//    time it spends at or above it (linear interpolation between bins);
//  - when the capture goes on after the part's removal (PhaseSplit::release_frame):
//    the refill y = c + A·exp(−(t − t_r)/τ) fitted to the bins after it: τ with its
//    1-σ error (from the fit's covariance, scaled by the residuals).
// Per texel of a coarse chart grid (`texel_mm`) the series is kept as well.
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct TimeSeriesOptions {
  bool enabled = true;
  int cell_px = 8;            ///< cell edge in the camera image, px
  double max_mb = 256;        ///< memory for the cell series; bins double beyond it
  double texel_mm = 0.5;      ///< coarse chart grid of the per-texel series
  double onset_window_s = 5;  ///< the onset fit uses the bins from 0.5 s before the press to this long after it
  /// The refill fit needs the capture to go on for this many τ after the removal
  /// (else it is not reported, with the reason).
  double min_refill_taus = 3;
  /// Throws InputError naming the key (timeseries.*) and the rule.
  void validate() const;
};

/// Cells × time bins of one capture (see the file comment).
class TimeSeriesRecorder {
 public:
  /// `roi`: the capture's roi (CaptureSums::roi); `expected_frames` (0: unknown) sizes the first allocation.
  TimeSeriesRecorder(const cv::Rect& roi, const TimeSeriesOptions& options, int expected_frames = 0);
  /// Adds one BGR frame (8 or 16 bits, sRGB-encoded) whose content is aligned to the reference at integer shift `shift`
  /// (aligned pixel (x, y) of the roi reads the frame at roi.tl() + (x, y) + shift, clamped).
  void add(const cv::Mat& frame, cv::Point shift);
  int frames() const { return frames_; }
  int bins() const { return bins_; }
  int bin_frames() const { return bin_frames_; }
  cv::Size cells() const { return cells_; }
  int cell_px() const { return cell_px_; }
  const cv::Rect& roi() const { return roi_; }
  /// Mean linear green of cell c over bin b (frames [b·bin_frames, ...)).
  float mean(int b, int c) const { return sum_[static_cast<std::size_t>(b) * cell_count() + c] / count_[b]; }
  int count(int b) const { return count_[b]; }
  std::size_t cell_count() const { return static_cast<std::size_t>(cells_.area()); }
  /// Bytes held (the bound: `max_mb`).
  std::size_t bytes() const { return sum_.capacity() * sizeof(float) + count_.capacity() * sizeof(int); }

 private:
  void merge_pairs();
  cv::Rect roi_;
  int cell_px_;
  cv::Size cells_;
  int max_bins_;
  int bin_frames_ = 1, bins_ = 0, frames_ = 0;
  std::vector<float> sum_;   ///< bins × cells, sums of the cells' mean green
  std::vector<int> count_;   ///< frames per bin
  std::vector<float> row_;   ///< scratch: one frame's cell sums
};

/// A least-squares time constant with its 1-σ error.
struct TimeConstantFit {
  bool fitted = false;
  double tau_s = 0, tau_sigma_s = 0;
  double t0_s = 0, t0_sigma_s = 0;   ///< onset: the start of the rise; refill: the removal time used (fixed)
  double amplitude = 0, offset = 0;  ///< A; c (refill only: the refilled level)
  double rms = 0;                    ///< residual rms, signal units
  int bins = 0;                      ///< bins fitted
  std::string note;                  ///< why it is not fitted, or a caution
};

/// One threshold of a place: its level's series against the threshold.
struct ThresholdTime {
  double threshold = 0;          ///< in the field's unit (kPa with a calibration, else signal)
  double signal = 0;             ///< the same as a signal value (the calibration's y(threshold); else = threshold)
  long long texels = 0;          ///< texels of the level (0: no part of the place reaches it)
  bool reached = false;
  double first_above_s = 0;      ///< first time at or above (valid when reached)
  double time_above_s = 0;       ///< total time at or above
};

/// One place over time.
struct HotspotTimeline {
  int hotspot = 0;                          ///< Hotspot::id
  std::vector<double> signal;               ///< per bin: y of the place (its lowest level)
  std::vector<double> kpa;                  ///< per bin, with a calibration (0 below detection, lower bound when saturated); else empty
  std::vector<std::vector<double>> level_signal;  ///< per threshold, per bin: y of the level (empty when it has no texel)
  std::vector<ThresholdTime> thresholds;
  TimeConstantFit onset, refill;
};

struct TimeAnalysis {
  bool present = false;
  double fps = 0;
  int frames = 0, bin_frames = 0, bins = 0;
  std::vector<double> time_s;               ///< bin centres (mean frame time), s from the first frame of the series
  int press_frame = 0;                      ///< of the series' capture (0 when the worn capture is its own file)
  int release_frame = -1;                   ///< -1: no removal seen
  std::vector<HotspotTimeline> hotspots;
  ChartGrid texel_grid;                     ///< the coarse chart grid
  std::vector<float> texel_signal;          ///< bins × texel_grid.size(), NaN where unseen
  std::vector<float> texel_kpa;             ///< same in kPa with a calibration (NaN also where invalid), else empty
  std::size_t memory_bytes = 0;             ///< held by the recorders while reading
  int cell_px = 0;
  std::vector<std::string> warnings;
};

/// What the time analysis needs of the assessment.
struct TimeInputs {
  const TimeSeriesRecorder* series = nullptr;    ///< the worn (or single) capture
  const TimeSeriesRecorder* baseline = nullptr;  ///< the baseline capture's, when it is a file of its own; else null
  FrameWindow baseline_window;                   ///< frames of G0 (in `baseline` when given, else in `series`)
  double fps = 0;
  int press_frame = 0, release_frame = -1;
  Vec2 residual_shift_px = Vec2::Zero();         ///< the worn window's (texel pixels are moved by it)
  const InverseMap* inverse = nullptr;
  /// The not-worn capture's own geometry (baseline_map.hpp): its inverse map (the same chart grid),
  /// its window's residual shift and per texel ln(T_worn / T_baseline). Frames of the not-worn view
  /// (before the press, after the removal; of `baseline` when it is a file of its own) are read
  /// through it, the others through `inverse`. Null: `inverse` serves every frame.
  const InverseMap* baseline_inverse = nullptr;
  Vec2 baseline_residual_shift_px = Vec2::Zero();
  const std::vector<float>* log_transmittance_ratio = nullptr;
  const ChartField* field = nullptr;             ///< the worn field the places were found on (kPa or signal)
  const std::vector<int>* labels = nullptr;      ///< place id per texel
  const std::vector<Hotspot>* hotspots = nullptr;
  std::vector<double> thresholds;                ///< ascending, in the field's unit
  const PressureCalibration* calibration = nullptr;
};

/// Runs the analysis (see the file comment). Never throws on a short capture: what cannot
/// be measured is left unfitted with its reason in `note` and a warning.
TimeAnalysis analyse_time(const TimeInputs& in, const TimeSeriesOptions& options);

/// Least-squares fits used above, exposed for tests. `t` are bin frame ranges:
/// bin k covers frames [first[k], first[k] + count[k]) at `fps`; the model is averaged over them.
struct BinnedSeries {
  std::vector<double> y;
  std::vector<int> first, count;
  double fps = 0;
};
/// y = A·(1 − exp(−(t − t0)/τ)) for t > t0, else 0; starts from t0_guess.
TimeConstantFit fit_onset(const BinnedSeries& s, double t0_guess_s);
/// y = c + A·exp(−(t − t_r)/τ) for t ≥ t_r.
TimeConstantFit fit_refill(const BinnedSeries& s, double t_release_s);

}  // namespace clearfit
