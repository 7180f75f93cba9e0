#pragma once
// The only place that calls mrcal's optimizer (mrcal_optimize,
// mrcal_optimizer_callback and the state/measurement layout functions). Its C
// API is not stable across major releases; this codes against Debian's 2.2.
// Private to camera/src. One camera at the reference frame, one board.
#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace clearfit::detail {

/// A single-camera board problem in mrcal's terms; the in/out members are a
/// seed on input and the solution on output.
struct BoardProblem {
  std::string lensmodel;
  int imager_width = 0, imager_height = 0;
  int grid_width = 0, grid_height = 0;
  double spacing_mm = 0;
  std::vector<double> intrinsics;             ///< in/out
  std::vector<std::array<double, 6>> frames;  ///< in/out: rt cam_from_board per view
  std::array<double, 2> warp{0, 0};           ///< in/out: calobject_warp x2, y2
  /// (x, y, weight) per corner, views x rows x cols; weight < 0 is ignored,
  /// and new outliers are marked < 0 on output.
  std::vector<Eigen::Vector3d> corners;
  /// mrcal sees every corner weight times this (> 0). Its regularisation does
  /// not scale with the residuals: it is sized for corners of about 1 px
  /// noise, so with sharper corners it outweighs the data; a scale of
  /// 1 px / noise gives it its intended share. Residuals, RMS and Jacobians
  /// come back in pixels (divided by it); weights read back are the given ones.
  double weight_scale = 1.0;
};

struct Selection {
  bool core = false, distortions = false, frames = true, warp = false;
  bool regularization = false, outlier_rejection = false;
};

struct SolveOutput {
  bool ok = false;
  double rms_px = 0;
  int outliers = 0;  ///< mrcal's count, including the corners given as missing
  int outlier_passes = 0;  ///< times mrcal threw out outliers and solved again
  /// What mrcal printed besides its outlier passes (its warnings, or why it failed), one line each,
  /// without its source prefix; mrcal's standard error is captured, not shown.
  std::vector<std::string> messages;
  /// Board residuals (weighted by the corner weights, in pixels; x then y
  /// per corner, views x rows x cols), outliers 0.
  std::vector<double> board_residuals;
};

/// mrcal_optimize on the problem; what it prints on stderr is captured into the output.
SolveOutput optimize(BoardProblem& problem, const Selection& selection);

/// The Jacobian of all of mrcal's measurements (boards then regularisation),
/// divided by the problem's weight_scale, with respect to the packed state, by central differences of
/// mrcal_optimizer_callback, and the facts needed to propagate it.
struct PackedJacobian {
  Eigen::MatrixXd J;             ///< Nmeasurements x Nstate
  int n_board_measurements = 0;  ///< the first rows
  std::vector<double> board_residuals;
  /// Unpacked state = packed state * scale (per state element).
  Eigen::VectorXd scale;
  int istate_intrinsics = -1, istate_frames = -1;
};
PackedJacobian packed_jacobian(const BoardProblem& problem, const Selection& selection);

}  // namespace clearfit::detail
