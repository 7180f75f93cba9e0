#pragma once
// Choosing the views worth keeping from a video of a board (or of the tags on a
// part's fixture): sharp, distinct, enough corners, at most a cap.
//
// Sharpness is measured as the width of the edges in the region the corners
// span: for a step edge blurred by a Gaussian of standard deviation s, the
// profile across the edge is C * Phi(n / s), its first derivative C * g(n) and
// its second C * g'(n); sum g^2 / sum g'^2 = 2 s^2, so
//   width = sqrt(sum |grad I|^2 / (2 sum I_nn^2))
// (I_nn: the second derivative along the gradient) is s, whatever the edge's
// contrast, length or orientation and however many edges the region holds. The
// sums are taken per edge orientation (8 bins of 22.5 deg over the edge
// normals): motion blur widens the edges whose normal lies along the motion and
// leaves the others, so the worst bin catches it. Gaussian blur adds to the
// width in quadrature: width^2 grows by s^2.
#include <clearfit/camera/detect.hpp>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace clearfit {

/// Edge widths in a region of an image (see the header comment).
struct EdgeBlur {
  double width_px = 0;       ///< the worst edge orientation's width (includes the measuring filter's own, ~1.2 px)
  double best_width_px = 0;  ///< the sharpest orientation's width
  double worst_normal_deg = 0;  ///< direction of the worst edges' normals (a motion blur's direction), [0, 180)
  int edge_pixels = 0;          ///< pixels that entered the sums (0: nothing measured)
  bool measured() const { return edge_pixels > 0; }
};

/// Edge widths in the union of the convex hulls of `regions` (pixels, mrcal
/// convention: (0,0) is the centre of the top-left pixel), grown by `margin_px`
/// so the edges on a hull's boundary count whole. `grey` is 8-bit, one channel.
/// The image is smoothed with a Gaussian of 1 px first (noise), pixels whose
/// gradient is under a tenth of the region's 99th percentile are left out (flat
/// paper and noise), and orientations holding under 5 % of the gradient energy
/// are ignored. A region with no edges gives edge_pixels 0.
EdgeBlur measure_edge_blur(const cv::Mat& grey, const std::vector<std::vector<Eigen::Vector2d>>& regions,
                           double margin_px = 4);

/// The knobs of picking views from a video (one home: the commands bind these).
struct ViewSelectionOptions {
  int max_views = 40;  ///< at most this many views are kept from one video
  /// A frame whose edge width exceeds this times the video's sharpest frame's is blurred.
  double max_blur_ratio = 1.5;
  /// A frame whose corners moved on average by less than this fraction of the
  /// image diagonal from a kept view's (corners seen in both) is a duplicate view.
  double min_corner_shift = 0.03;
  /// A frame with fewer than this fraction of the corners (and fewer than 4) has too few corners.
  double min_corner_fraction = 0.25;
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// What was measured of one frame: its corners in a fixed layout (the same
/// number and order in every frame; weight < 0: missing, as BoardObservation)
/// and its edge blur (in the corners' region; without corners, of the whole frame).
struct ViewCandidate {
  std::vector<Eigen::Vector3d> corners;
  EdgeBlur blur;
};

enum class ViewVerdict { used, no_board, too_few_corners, blurred, duplicate_view, over_cap };
/// "used", "no_board", "too_few_corners", "blurred", "duplicate_view", "over_cap".
const char* to_string(ViewVerdict v);

struct ViewSelection {
  std::vector<ViewVerdict> verdicts;  ///< one per candidate, in their order
  double sharpest_width_px = 0;       ///< the video's best edge width (over frames with enough corners)
  double blur_limit_px = 0;           ///< frames above this edge width are blurred
  double min_shift_px = 0;            ///< mean corner shift below this: duplicate view
  int count(ViewVerdict v) const;
  /// Indices of the used candidates, increasing.
  std::vector<int> used() const;
};

/// Picks the views: frames without corners have no board (unless their blur,
/// measured over the whole frame, is over the limit below: a board blurred
/// enough is not found, and the frame is counted blurred); frames with fewer
/// than max(4, min_corner_fraction * corners) corners have too few; frames whose
/// edges are wider than max_blur_ratio times the sharpest such frame's are
/// blurred. Of the rest, the sharpest is kept first, then (with `distinct`)
/// farthest-point sampling: repeatedly the frame whose corners are farthest
/// (mean shift over the corners both see; no 4 common corners: infinitely far)
/// from every kept view, while that distance is at least min_corner_shift of
/// the image diagonal and fewer than max_views are kept; what is left is a
/// duplicate view (near a kept one) or over the cap. Without `distinct` (views
/// from one still camera, e.g. for a part's pose) the sharpest max_views are
/// kept and the rest are over the cap. `width`, `height`: the frames' size.
ViewSelection select_views(const std::vector<ViewCandidate>& candidates, int width, int height,
                           const ViewSelectionOptions& options, bool distinct = true);

}  // namespace clearfit
