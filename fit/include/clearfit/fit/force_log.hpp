#pragma once
// Calibration sessions, the force side: a force gauge's log (its own clock),
// the presses found in it, and the alignment of its clock to the video's.
//
// A lab calibrates a wearer by pressing a clear indenter on the skin while a
// gauge logs the force and a camera films the skin through the indenter. The
// gauge and the camera do not share a clock: gauge time = (1 + drift)·video
// time + offset, offset unknown (seconds), drift unknown (hundreds of ppm).
// Both are found from the data: the force trace, passed through the
// blanching's first-order response, is matched to the image signal of the
// indenter area (coarse: correlation over offsets; fine: the press onsets and
// releases seen in both, by least squares, with σ). No clap or LED is needed.
#include <clearfit/geometry/mesh.hpp>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit {

/// A force log in newtons on the gauge's clock (seconds), times strictly increasing.
struct ForceLog {
  std::filesystem::path source;
  std::vector<double> time_s, force_n;
  std::vector<int> line;  ///< line of each sample in the file
  double tare_n = 0;      ///< the resting force subtracted (see read_force_log)
  std::vector<std::string> notes;
};

/// Reads a CSV force log with a header naming a time column and a force column
/// with their units: time `time_s`, `time_ms`, `t_s`, `t_ms`, `timestamp_s`, `timestamp_ms`;
/// force `force_n`, `force_mn`, `force_kgf`, `force_gf`, `force_lbf` (case-insensitive;
/// other columns ignored). Any sample rate, '#' comments and blank lines
/// skipped. The tare (the gauge's reading at rest, possibly non-zero) is the
/// median of the samples within 20 mN of the rests' level (the lowest fifth's
/// median) and is subtracted. Throws InputError
/// naming the file and line: no header, a column without units, text or NaN in
/// a number, times not strictly increasing or duplicated, fewer than 10
/// samples, clipped force (the maximum repeated on more than 2 % of samples,
/// the gauge's range exceeded).
ForceLog read_force_log(const std::filesystem::path& path);

/// One press found in the force: ramp, hold, release, rest.
struct ForcePress {
  double start_s = 0, end_s = 0;          ///< force above the press threshold (gauge clock)
  double hold_start_s = 0, hold_end_s = 0;  ///< the settled part of the hold
  double rest_start_s = 0, rest_end_s = 0;  ///< the rest before the press (this press's own baseline)
  double force_n = 0;                     ///< median force over the settled hold
  double force_sd_n = 0;                  ///< its spread there
};

struct PressSegmentation {
  double threshold_n = 0.02;     ///< a press: force above this (after tare)
  double settle_s = 1.0;         ///< the hold's first second is left to settle (overshoot, blanching lag)
  double min_hold_s = 1.0;       ///< shorter holds are not presses
  double min_rest_s = 1.0;       ///< the rest before a press used as its baseline
  double settled_band = 0.05;    ///< the settled hold: force within ±5 % of its median
  void validate() const;         ///< throws std::invalid_argument naming the field
};

/// The presses of a log, in order. Throws InputError naming the log when none is found.
std::vector<ForcePress> find_presses(const ForceLog& log, const PressSegmentation& options = {});

/// gauge time = (1 + drift)·video time + offset, with 1-σ errors.
struct ClockAlignment {
  double offset_s = 0, drift = 0;
  double offset_sigma_s = 0, drift_sigma = 0;
  double lag_s = 0;             ///< the blanching model's half-rise delay behind a force step (τ_on·ln 2), assumed in the match
  double correlation = 0;       ///< of the aligned traces
  double second_peak_ratio = 0; ///< next-best correlation peak over the best (ambiguity: close to 1)
  int events = 0;               ///< onsets and releases matched
  bool trace_fit = false;       ///< refined by the fit of the whole trace around the presses (else: the events' fit)
  double tau_on_s = NAN, tau_off_s = NAN;  ///< the blanching's time constants the trace fit found (NaN without it)
  double to_gauge(double video_s) const { return (1 + drift) * video_s + offset_s; }
  double to_video(double gauge_s) const { return (gauge_s - offset_s) / (1 + drift); }
};

struct AlignmentOptions {
  double max_offset_s = 60;      ///< search |offset| up to this
  double max_drift = 2e-3;       ///< |drift| up to this (2000 ppm)
  double tau_on_s = 0.3, tau_off_s = 1.5;  ///< blanching's response to force (SKIN.md), for the coarse match
  double ambiguity = 0.9;        ///< refuse when the second peak reaches this fraction of the best
  void validate() const;
};

/// Aligns the gauge's clock to the video's from the image signal of the indenter
/// area (`signal` sampled at `video_time_s`; rising with blanching). Throws
/// InputError (naming the log) when the alignment is ambiguous (periodic presses
/// of equal force, too few presses), or when fewer than 3 press events match.
ClockAlignment align_clocks(const ForceLog& log, const std::vector<ForcePress>& presses,
                            const std::vector<double>& video_time_s, const std::vector<double>& signal,
                            const AlignmentOptions& options = {});

}  // namespace clearfit
