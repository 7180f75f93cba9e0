#pragma once
// Synthetic images of an AprilTag board seen through a lens: the ground truth
// for detection, refinement and calibration tests.
//
// Every pixel is the mean of n x n stratified, jittered point samples (the
// jitter is a fixed hash of the pixel and sample, so renders are repeatable and
// edge positions carry no quantisation bias); a pixel whose four corners see
// one colour and whose footprint is under half a bit cell is taken as uniform.
// The board-plane point of every pixel centre comes from the camera's rays
// (unproject_image) intersected with the plane z = 0 of the board frame; sample
// points between centres interpolate it bilinearly. A point is coloured by the
// tag bitmap of the family (apriltag_to_image), the white paper around the
// tags, or the background. Then an optional Gaussian blur, exposure, Gaussian
// noise, rounding and clipping to 8 bits.
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace clearfit {

struct RenderOptions {
  int supersample = 4;          ///< n: n x n samples per pixel (1..16)
  double black = 30;            ///< grey level of the tags' black cells before exposure
  double white = 220;           ///< grey level of the paper / white cells before exposure
  double background = 90;       ///< grey level beyond the paper (and rays that miss the board)
  double paper_margin_mm = -1;  ///< white paper around the outer black squares; < 0: Board::margin_mm()
  double exposure = 1.0;        ///< multiplies every level (> 1 overexposes: clipped at 255)
  double blur_sigma_px = 0;     ///< Gaussian blur after sampling (0: none)
  double noise_sigma = 0;       ///< Gaussian noise, grey levels (0: none)
  std::uint64_t seed = 1;       ///< noise seed (std::mt19937_64)
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// Renders `board` placed at `cam_from_board` (board frame: board.hpp; mm) as
/// seen by `camera` (its imager size; its extrinsics are ignored). 8-bit grey,
/// camera.height x camera.width. `rays` may pass a precomputed
/// unproject_image(camera, 1) of this camera to save its cost across views
/// (std::invalid_argument if its size or intrinsics_hash does not match).
/// Samples seeing the back of the board or nothing get `background`.
cv::Mat render_board(const Board& board, const CameraModel& camera, const Rigid3& cam_from_board,
                     const RenderOptions& options = {}, const RayGrid* rays = nullptr);

/// The true pixels (mrcal convention) of every grid node, row-major (board
/// order), as (x, y, weight): weight 1 for a tag corner that projects inside
/// the imager (at least `margin_px` from its border) in front of the camera,
/// -1 otherwise (also for nodes between tags). Same layout as
/// BoardObservation::corners, so the two compare entry by entry.
std::vector<Eigen::Vector3d> true_corners(const Board& board, const CameraModel& camera,
                                          const Rigid3& cam_from_board, double margin_px = 0);

}  // namespace clearfit
