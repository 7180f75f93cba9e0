#pragma once
// AprilTag board detection for mrcal: corners in mrcal's pixel convention
// (pixel (0,0) = centre of the top-left pixel; the AprilTag library reports
// +0.5 px, which is subtracted), refined to sub-pixel, each with a weight,
// in mrcal's row-major board order with missing corners marked (weight < 0).
//
// Corner refinement fits straight lines to the four black-square edges of each
// tag (edge points from the intensity profile across the edge: where it crosses
// the mean of its dark and bright ends), and intersects them. Without a lens
// model the lines are fitted in pixels; with one (refine_corners with a model)
// they are fitted in undistorted normalized coordinates (x/z, y/z) where the
// tag edges really are straight, and the corners are projected back through
// the lens. The weight of a corner is min(1, 0.1 px / sigma) where sigma is its
// standard deviation estimated from the two edge fits' residuals (floored at
// 0.05); corners whose sigma exceeds 1 px are dropped (missing).
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/camera_model.hpp>

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace clearfit {

/// The corners of one board seen in one image.
struct BoardObservation {
  std::string image;  ///< the image's name (file path as given, or a caller's label)
  int width = 0;      ///< image size, pixels
  int height = 0;
  /// grid_height * grid_width entries in row-major board order: (x, y, weight),
  /// pixels in mrcal's convention; weight < 0 (x = y = -1) means missing.
  std::vector<Eigen::Vector3d> corners;
  /// What happened, for people: rejected tags and why, other families seen, ...
  std::vector<std::string> notes;
  int tags_used = 0;  ///< board tags whose corners are in `corners`

  /// Corners with weight >= 0.
  int num_valid() const;
  /// True when at least one corner is present.
  bool detected() const { return num_valid() > 0; }
};

struct DetectOptions {
  float quad_decimate = 2.0f;  ///< AprilTag quad_decimate (speed; corners are refined at full resolution)
  float quad_sigma = 0.0f;     ///< AprilTag quad_sigma, px (0.8 helps noisy images)
  double decode_sharpening = 0.25;  ///< AprilTag decode_sharpening
  int max_hamming = 1;              ///< bit errors corrected and accepted per tag (0..2)
  double min_decision_margin = 20;  ///< tags decoded with less are ambiguous: rejected
  double border_margin_px =
      3;                 ///< tags with a corner closer than this to the image border (partial) are rejected
  bool subpixel = true;  ///< refine corners with straight-edge fits (in pixels)
  bool probe_other_families = true;  ///< when no board tag is found, look for other families (for the note)
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// Detects `board` in an 8-bit grey or BGR/BGRA image (converted to grey).
/// `name` is stored as BoardObservation::image. Never throws for an image
/// without tags: the result has no valid corners and a note saying so.
/// Rejected with a note: ids not on the board (another board, or another
/// family's ids), an id seen twice (both copies), decision margin below
/// min_decision_margin (ambiguous), a corner within border_margin_px of the
/// image border (partial), a degenerate quad. std::invalid_argument for an
/// empty image or another pixel type (e.g. 16-bit).
BoardObservation detect_board(const cv::Mat& image, const Board& board, const DetectOptions& options = {},
                              const std::string& name = {});

/// Reads an image file (any format OpenCV reads, converted to 8-bit grey) and
/// detects the board. Throws InputError naming the file when it cannot be read.
BoardObservation detect_board_file(const std::filesystem::path& image, const Board& board,
                                   const DetectOptions& options = {});

/// Image files named by `inputs`: files as given, folders expanded to their
/// image files (png jpg jpeg bmp tif tiff pgm ppm, not recursive), sorted by
/// name. Throws InputError for a path that does not exist or a folder without images.
std::vector<std::filesystem::path> list_images(const std::vector<std::filesystem::path>& inputs);

/// Detects the board in every file, in parallel (TBB), results in the order of
/// `images`. `progress(done, total)` is called after each image (from worker
/// threads, serialised by a mutex; may be empty). An unreadable image throws
/// InputError naming it (after the others finish).
std::vector<BoardObservation> detect_boards(const std::vector<std::filesystem::path>& images,
                                            const Board& board, const DetectOptions& options = {},
                                            const std::function<void(int done, int total)>& progress = {});

/// mrcal's corners.vnl text: header `# filename x y weight`, then per image
/// with corners exactly grid_width*grid_height rows `filename x y weight` in
/// row-major board order (`filename - - -` for a missing corner) and one row
/// `filename - - -` for an image without any corner. The last column is a
/// weight (mrcal-calibrate-cameras --corners-cache-has-weights): pass that
/// option when calibrating with mrcal's tool. Filenames with whitespace are
/// refused (std::invalid_argument; vnl has no quoting).
std::string corners_vnl(const std::vector<BoardObservation>& observations, const Board& board);

/// Writes corners_vnl(...) atomically; InputError naming the path on failure.
void write_corners_vnl(const std::vector<BoardObservation>& observations, const Board& board,
                       const std::filesystem::path& path);

/// One tag of any id found in an image (for part poses from tags on a fixture).
struct DetectedTag {
  int id = -1;
  std::array<Eigen::Vector2d, 4>
      corners;  ///< mrcal pixels, AprilTag order (bottom-left, bottom-right, top-right, top-left)
  std::array<double, 4> weight{};  ///< as BoardObservation weights (>= 0.05)
  double decision_margin = 0;
};

/// Every tag of `family` in an 8-bit grey or BGR image, after the same
/// rejections as detect_board (duplicate ids, ambiguous, partial, degenerate;
/// each with a note in `notes` if given). Corners refined by straight-edge
/// fits: through `lens` when given (undistorted coordinates), else in pixels
/// (options.subpixel false: AprilTag's corners). Sorted by id. InputError for
/// an unknown family (element "family").
std::vector<DetectedTag> detect_tags(const cv::Mat& image, const std::string& family,
                                     const DetectOptions& options = {}, const CameraModel* lens = nullptr,
                                     std::vector<std::string>* notes = nullptr);

struct RefineOptions {
  double edge_margin = 0.12;  ///< fraction of each edge left out at both ends (near the corners)
  double max_window_px =
      3.0;             ///< half-length of the intensity profile across an edge, px (also <= half a bit cell)
  int iterations = 3;  ///< resample the edges around the updated corners this often
  double min_contrast = 10;  ///< grey levels between the dark and bright ends of a profile
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// Refines every tag whose four corners are present in `observation`: edge
/// points across each black-square edge, a straight line per edge, corners at
/// the line intersections. With `lens` (the camera that took `image`, e.g.
/// from a first calibration) the lines are fitted in undistorted normalized
/// coordinates and the corners projected back, which removes the outward bias
/// plain AprilTag corners have under distortion; with nullptr they are fitted
/// in pixels. Weights are recomputed (see the header comment); a tag whose
/// edges cannot be fitted (too little contrast, too small, unprojection failed)
/// keeps its corners and gets a note. The image must be the 8-bit grey (or
/// BGR) image the observation came from (std::invalid_argument if its size differs).
BoardObservation refine_corners(const cv::Mat& image, const BoardObservation& observation, const Board& board,
                                const CameraModel* lens, const RefineOptions& options = {});

}  // namespace clearfit
