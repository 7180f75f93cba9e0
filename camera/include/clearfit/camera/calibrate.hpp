#pragma once
// Camera calibration from observations of a planar board whose corners form a
// uniform grid (mrcal's board model), solved by mrcal's optimizer (libmrcal),
// seeded without Python: the focal length from the board homographies (or a
// guess), the board poses by PnP on normalised points, then mrcal's staged
// solve (board poses only -> + intrinsics core -> everything, with the board's
// warp, regularisation and outlier rejection, then once more with mrcal's
// regularisation scaled to the corners' noise, kept where it fits better). Higher lens models are seeded
// from a lower one's solution (OPENCV12 from OPENCV8, splined from
// STEREOGRAPHIC).
//
// Conventions: pixels as mrcal (pixel (0,0) is the centre of the top-left
// pixel), lengths in mm, board point (row i, col j) at (j, i, 0) * spacing_mm
// in the board frame before the warp.
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/detect.hpp>  // BoardObservation
#include <clearfit/camera/pose.hpp>

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace clearfit {

/// The board's corner grid as mrcal sees it.
struct CalibrationGrid {
  int width = 0;          ///< corners per row
  int height = 0;         ///< corner rows
  double spacing_mm = 0;  ///< distance between neighbouring corners, mm
  /// Throws InputError naming the field when it is unusable.
  void validate() const;
  /// The grid of a board (its grid_width, grid_height, spacing_mm).
  static CalibrationGrid of(const Board& board) {
    return {board.grid_width, board.grid_height, board.spacing_mm};
  }
};

struct CalibrationOptions {
  /// Full mrcal lens model name (configuration included for splined models).
  std::string lensmodel = "LENSMODEL_OPENCV8";
  /// Focal length seed in pixels; 0: estimated from the board homographies,
  /// falling back to a horizontal field of view of fallback_fov_deg.
  double focal_px = 0;
  double fallback_fov_deg = 60.0;
  bool solve_calobject_warp = true;
  bool outlier_rejection = true;
  bool regularization = true;
  /// mrcal sizes its regularisation for corners of about 1 px noise: the final
  /// solve is repeated with the corner weights scaled by 1 px / the corners'
  /// noise (1 to 100), so it keeps its intended share of the cost when the
  /// corners are sharper, and that solution is kept when it fits the corners
  /// better than a chi-square of the distortion parameters allows (mrcal's
  /// sizing biased the model, as on a wide lens). false: mrcal's sizing
  /// always (what mrcal-calibrate-cameras does).
  bool scale_regularization_to_noise = true;
  /// Projection uncertainty (mrcal's method, from a finite-difference
  /// Jacobian of mrcal's residuals): costs about as much as the solve.
  bool compute_uncertainty = true;
  /// Uncertainty is evaluated for points at this distance from the camera;
  /// 0: the median board distance.
  double uncertainty_distance_mm = 0;
  int coverage_cells_x = 8;  ///< coverage grid over the imager
  int coverage_cells_y = 6;
  /// Uncertainty sampled at the nodes of a grid spanning the imager edge to edge, its corners included
  /// (projection_uncertainty.hpp): node i of n at i·(W − 1)/(n − 1); odd counts put a node at the centre.
  int uncertainty_nodes_x = 17;
  int uncertainty_nodes_y = 13;
  /// Fewer usable views is an error; fewer than recommended_views a warning.
  int min_views = 3;
  int recommended_views = 10;
  /// A view in which more than this fraction of the row/column triples of
  /// neighbouring corners are not in a row (second difference above half the
  /// local spacing) is refused: the board description disagrees with the
  /// printed board. Perspective and lens distortion stay far below.
  double max_grid_inconsistency = 0.05;
  /// Optional seed for the intrinsics (same lens model and imager size).
  std::optional<CameraModel> seed;
  /// Called with a short line before each stage (the CLI prints it).
  std::function<void(const std::string&)> progress;
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// One corner in the report.
struct CornerResidual {
  int view = 0, row = 0, col = 0;
  double error_px = 0;  ///< |projected - observed|, pixels
  Eigen::Vector2d observed{0, 0};
};

struct CalibrationResult {
  CameraModel model;            ///< cam_from_part = identity
  std::string lensmodel_chain;  ///< e.g. "LENSMODEL_PINHOLE -> LENSMODEL_OPENCV8"
  /// RMS reprojection error per coordinate over the inlier corners,
  /// sqrt(sum |r|^2 / 2n) (the residuals are weighted by the corner weights).
  double rms_px = 0;
  /// mrcal's own figure (mrcal_stats_t, what mrcal-calibrate-cameras prints):
  /// the same sum divided by 2 x all grid points, missing ones included.
  double mrcal_rms_px = 0;
  double seed_rms_px = 0;         ///< mrcal's RMS after the first stage (board poses only, seeded intrinsics)
  /// The corner weights were multiplied by this in the final solve (1 px over
  /// the corners' noise, 1 to 100), which scales mrcal's regularisation,
  /// sized for 1 px corners, to the data; 1 when mrcal's sizing was kept
  /// (see CalibrationOptions::scale_regularization_to_noise).
  double corner_weight_scale = 1;
  double focal_seed_px = 0;       ///< the focal length the solve started from
  std::string focal_seed_method;  ///< "option", "homographies", "field of view", "seed model"
  int corners_used = 0;           ///< inlier corners
  int outliers = 0;               ///< corners rejected by mrcal (given missing ones not counted)
  std::vector<CornerResidual> outlier_corners;
  std::vector<CornerResidual> worst_corners;  ///< the 10 largest inlier residuals, largest first
  /// Per view (same order as the input; views skipped for having no corners
  /// have used = false and NaN-free zeros).
  struct View {
    std::string image;
    bool used = false;
    int corners = 0;  ///< inlier corners
    double rms_px = 0;
    Rigid3 cam_from_board;   ///< board frame -> camera frame, mm
    double distance_mm = 0;  ///< distance of the board centre from the camera
    double tilt_deg = 0;     ///< angle between the board normal and the optical axis
  };
  std::vector<View> views;
  double calobject_warp_x_mm = 0, calobject_warp_y_mm = 0;  ///< mrcal's board sag (x2, y2)
  /// Number of inlier corners per coverage cell, row-major (cells_y rows).
  int coverage_cells_x = 0, coverage_cells_y = 0;
  std::vector<int> coverage;
  /// Worst-direction standard deviation of projection (pixels) at the nodes
  /// (CalibrationOptions::uncertainty_nodes_x), row-major; empty if not computed.
  int uncertainty_nodes_x = 0, uncertainty_nodes_y = 0;
  double uncertainty_distance_mm = 0;
  std::vector<double> uncertainty_px;
  double uncertainty_center_px = 0;    ///< at the imager centre
  double observed_pixel_sigma_px = 0;  ///< noise estimate: std of the inlier residual coordinates
  double solve_seconds = 0;            ///< seeding + mrcal solves
  double uncertainty_seconds = 0;
  std::vector<std::string> warnings;
  std::vector<std::string> notes;
};

/// Calibrates one camera from board views (see the file comment).
/// Views with no corners are skipped (a note); a view whose corners disagree
/// with the grid, mixed imager sizes, too few usable views, views that show
/// fewer distinct board poses than min_views (a view given twice), a solve
/// the views cannot determine (a focal length under a twentieth of the
/// imager's larger side: every board facing the camera at one distance) or a
/// failed solve throw InputError naming the view. Warnings (returned, never printed): few
/// views, all boards at about one distance (focal length and distance become
/// ambiguous), all boards facing the camera, empty regions of the imager,
/// a large RMS.
CalibrationResult calibrate_camera(const std::vector<BoardObservation>& views, const CalibrationGrid& grid,
                                   const CalibrationOptions& options = {});

/// Throws InputError (key 'lensmodel') when `lensmodel` is not a full mrcal
/// lens model name clearfit can calibrate (unknown, configuration missing,
/// CAHVORE); the hint lists the supported models.
void check_calibration_lensmodel(const std::string& lensmodel);

/// Projection difference (pixels) between two models of the same imager at
/// pixel q: q is unprojected through `a`, the ray projected through `b`. NaN
/// where unprojection fails. Both models are taken at the same camera frame.
double projection_difference_px(const CameraModel& a, const CameraModel& b, const Eigen::Vector2d& q);

/// Projection differences (pixels) between two models at the centres of an
/// nx x ny grid of cells over the imager, row-major: each centre q is
/// unprojected through `a`, rotated by R, projected through `b`. With
/// fit_weights empty R is the identity (projection_difference_px); else R is
/// the rotation that best aligns a's rays with b's rays over the cells of
/// positive weight (Kabsch), as mrcal's projection_diff does: a camera frame
/// calibrated from board views is defined only up to such a rotation, which
/// the board poses absorb. `also_at`: pixels whose differences follow the
/// grid's in the result (R still fitted over the grid), e.g. the image corners.
std::vector<double> projection_difference_grid(const CameraModel& a, const CameraModel& b, int nx, int ny,
                                               const std::vector<int>& fit_weights = {}, const std::vector<Vec2>& also_at = {});

/// Synthetic board views: the true corners of `grid` seen by `truth` from
/// random poses, plus Gaussian pixel noise. Used by tests and benchmarks.
struct SyntheticViewsOptions {
  int views = 30;
  double noise_px = 0.3;                                 ///< standard deviation per coordinate, pixels
  double min_distance_mm = 400, max_distance_mm = 1200;  ///< board centre distance
  double min_tilt_deg = 10, max_tilt_deg = 45;           ///< board normal vs optical axis
  unsigned seed = 1;                                     ///< std::mt19937 seed
  /// Corners outside the imager are missing (weight -1). A pose that leaves
  /// fewer than this fraction of the corners inside is drawn again (1: whole
  /// boards only, as chessboard detectors deliver).
  double min_inside_fraction = 0.5;
};
/// Views are named "frameNNN.png"; each entry of `cam_from_board` (if not
/// null) receives the true pose.
std::vector<BoardObservation> synthesize_views(const CameraModel& truth, const CalibrationGrid& grid,
                                               const SyntheticViewsOptions& options,
                                               std::vector<Rigid3>* cam_from_board = nullptr);

/// Reads mrcal's corners file (`# filename x y level` or with a weight
/// column): one row per corner, W*H rows per image in row-major board order,
/// `-` for a missing corner, one `filename - - -` row for an image without a
/// detection. Level l gives weight 1/2^l; when the header names a `weight`
/// column (or with_weights), the last column is the weight. Image sizes are not in the file: every view gets
/// width x height. Throws InputError naming the file and line.
std::vector<BoardObservation> read_corners_vnl(const std::filesystem::path& path, const CalibrationGrid& grid,
                                               int width, int height, bool with_weights = false);

/// Writes views in the format above with a level column (0 for weight 1,
/// else -log2(weight); missing corners as `-`), which mrcal-calibrate-cameras
/// reads without --corners-cache-has-weights; atomically. (detect.hpp's
/// write_corners_vnl writes a weight column instead.)
void write_corners_levels_vnl(const std::vector<BoardObservation>& views, const std::filesystem::path& path);

/// Converts an OpenCV calibration YAML/XML (cv::FileStorage: camera_matrix
/// 3x3, distortion_coefficients with 0, 4, 5, 8 or 12 values, image_width,
/// image_height) to the equivalent mrcal model: LENSMODEL_OPENCV4/5/8/12 by
/// coefficient count, LENSMODEL_PINHOLE when there are none or all are zero.
/// OpenCV puts pixel centres on integers like mrcal, so no shift applies.
/// Throws InputError naming the file and key (missing keys, skew, 14
/// coefficients (tilted model), a non-positive focal length).
CameraModel camera_from_opencv_yaml(const std::filesystem::path& path);

}  // namespace clearfit
