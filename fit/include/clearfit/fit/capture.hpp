#pragma once
// Captures: a "not worn" (baseline) and a "worn" video or image folder, read
// once. Each frame's green channel is linearised from sRGB and added, inside
// the region of the image that can see the skin, into partial sums of a few
// frames ("chunks"), so averaging windows are chosen after the read without
// decoding anything twice. Memory is bounded: the sums before the last frames, or
// outside windows known beforehand, are released as the read goes; a caller that
// learns its windows only at the end caps the sums (max_sums_mb) and, beyond the
// cap, reads again keeping its windows only. Per frame the read also measures motion (a
// similarity from a grid of high-passed log-red patches against a reference
// frame: registration.hpp), the mean green of an 8×8
// grid of blocks (for splitting one video into its two phases; from every other row),
// and saturated / dark pixels.
//
// Motion compensation: each frame is accumulated at an integer pixel shift
// within 0.75 px of its measured motion at the roi's centre (free: an index offset; kept from
// frame to frame while it fits, so jitter around a position is not split), so drift of any size up
// to the refusal limit is undone; the remaining sub-pixel shifts are averaged
// per window and applied once, when the window's average is resampled onto the
// chart (no per-frame resampling). The blur left by sub-pixel jitter inside a
// window is reported, and so are rotation and scale, which are measured but not
// undone: at the roi's corners they add their displacement (rotation_scale_px_max) as blur.
#include <clearfit/fit/frame_reader.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <opencv2/core.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace clearfit {

/// A window of frames [first, first + count) of a capture, chunk-aligned.
struct FrameWindow {
  int first = 0, count = 0;
};

struct CaptureReadOptions {
  cv::Rect roi;                   ///< pixels that can see the skin; empty: the whole image
  int chunk_frames = 5;           ///< frames per stored partial sum
  bool register_motion = true;    ///< measure and compensate motion
  bool colour = true;             ///< also sum linear blue at half resolution (photometric.hpp), for the glare mask
  bool red = false;               ///< also sum linear red (full resolution, photometric.hpp), for registering the phases
  RegistrationOptions registration;  ///< how motion is measured (registration.hpp)
  cv::Mat seen;                   ///< CV_8U, roi size: the pixels that see the skin, where registration patches go; empty: all
  double max_motion_px = 10.0;    ///< motion beyond this anywhere in the roi (against the reference) is refused
  /// A view that changes geometry within the capture (one video whose not-worn phase was filmed
  /// with the part held off the skin or absent, baseline_map.hpp): a frame beyond max_motion_px
  /// is measured against the earlier references, else it becomes a new reference, up to this many;
  /// a frame's motion is then against its own reference (CaptureSums::reference says which; the
  /// caller checks that each phase's window keeps one, and places the windows).
  /// 1: one reference, motion beyond the limit is refused.
  int max_references = 1;
  int expected_width = 0, expected_height = 0;  ///< the camera's imager; 0: not checked
  std::string role;               ///< "baseline", "worn" or "capture", for messages
  /// Bounded memory: keep the chunk sums of the last this many frames only (older ones are
  /// released as the read goes; windows must lie in the kept frames). 0: keep every chunk.
  int keep_last_frames = 0;
  /// Bounded memory when the windows are known only after the read (one video holding both
  /// phases): beyond this many MB of chunk sums none is kept any longer (CaptureSums::sums_dropped;
  /// the caller reads the capture again for its windows). 0: no limit.
  double max_sums_mb = 0;
  /// When not empty: only the chunks overlapping these windows keep their sums.
  std::vector<FrameWindow> keep_windows;
  /// Called after each frame (frames done, frames expected or 0 if unknown).
  std::function<void(int, int)> progress;
  /// Called with each frame as decoded and the integer shift it was accumulated at (aligned
  /// pixel (x, y) of the roi is the frame's roi.tl() + (x, y) + shift), e.g. for time series.
  /// Videos are converted only where the read looks (the roi moved by up to max_motion_px, and the
  /// registration's patches with their filters' support): the frame is black beyond them (and a few px).
  std::function<void(const cv::Mat&, cv::Point)> on_frame;
};

/// The registration reference: the first baseline frame's patches. Shared by
/// both captures so that both are aligned to the same frame.
struct MotionReference {
  std::shared_ptr<MotionRegistration> registration;
  bool empty() const { return !registration || !registration->has_reference(); }
};

/// One capture read once (see the file comment).
struct CaptureSums {
  CaptureInfo info;
  cv::Rect roi;
  int chunk_frames = 0;
  std::vector<cv::Mat> chunk_sum;      ///< CV_32F (roi size) sums of linear green, aligned to the reference
  std::vector<int> chunk_count;        ///< frames in each chunk
  int released_chunks = 0;             ///< chunks [0, released_chunks) had their sums released (keep_last_frames)
  bool sums_dropped = false;           ///< the sums outgrew max_sums_mb and were released: read again with keep_windows
  std::vector<cv::Mat> chunk_blue;     ///< CV_32F (half_grid of the roi) sums of linear blue, aligned (empty without `colour`)
  std::vector<cv::Mat> chunk_red;      ///< CV_32F (roi size) sums of linear red, aligned (empty without `red`)
  std::vector<Vec2> shift_px;          ///< per frame: content displacement against the reference at the roi's centre, px
  std::vector<Similarity> motion;      ///< per frame: the whole measured motion (rotation and scale too; identity unregistered)
  std::vector<int> patches_used;       ///< per frame: registration patches kept by the robust fit (0 unregistered)
  std::vector<cv::Point> applied_shift;  ///< per frame: integer shift undone while accumulating
  std::vector<int> reference;          ///< per frame: the registration reference it was measured against (max_references)
  std::vector<std::array<float, 64>> blocks;  ///< per frame: mean linear green of 8×8 blocks of the roi
  std::vector<float> saturated_fraction;      ///< per frame: roi pixels whose green is 255
  std::vector<float> mean_code;               ///< per frame: mean 8-bit green code over the roi
  cv::Mat last_frame;                  ///< the last frame read (BGR8, full image, converted whole), for pictures
  double read_ms = 0, work_ms = 0;     ///< time waiting for decoded frames / accumulating
};

/// Reads a whole capture (decoding on one thread while accumulating on the
/// others). `reference`: when empty it is set from this capture's first frame.
/// Throws InputError: frame size differs from the expected imager, motion
/// beyond the limit (naming the frame and the size), no frames.
CaptureSums read_capture(const std::filesystem::path& source, const CaptureReadOptions& options,
                         MotionReference& reference);

/// The average of a window: linear green, aligned to the reference frame up
/// to `residual_shift_px` (the mean sub-pixel motion still to be applied when
/// resampling: the reference image at pixel p is `mean` at p + residual −
/// roi.tl()).
struct PhaseAverage {
  FrameWindow window;
  cv::Rect roi;
  cv::Mat mean;          ///< CV_32F, roi size, linear green in [0, 1]
  cv::Mat variance;      ///< CV_32F: variance of `mean` (from the spread of the chunk means; 0 if < 3 chunks)
  Vec2 residual_shift_px = Vec2::Zero();
  double motion_px_max = 0;      ///< largest measured displacement in the window, px
  double jitter_px_rms = 0;      ///< rms of the sub-pixel shifts around their mean (blur left), px
  double rotation_deg_max = 0;   ///< largest measured rotation against the reference, degrees
  double scale_change_max = 0;   ///< largest |scale − 1|
  double rotation_scale_px_max = 0;  ///< largest displacement at the roi's corners from rotation and scale (not undone), px
  double saturated_fraction = 0; ///< mean over the window
  double mean_code = 0;          ///< mean 8-bit green code over the roi
  cv::Mat blue_half;             ///< CV_32F (half_grid of the roi): mean linear blue, gain-normalised; empty without colour
  cv::Mat red;                   ///< CV_32F (roi size): mean linear red, gain-normalised; empty without CaptureReadOptions::red
  /// Per-chunk gains (photometric.hpp) divided out of `mean`, `variance`, `blue_half` and `red`:
  /// their extremes and the typical uncertainty of one chunk's gain.
  double gain_min = 1, gain_max = 1, gain_sigma = 0;
};

/// Averages `window` (rounded to whole chunks: start and end down to a chunk boundary; InputError when fewer
/// than `min_frames` remain, naming the capture and the counts).
/// Each chunk is divided by its gain (exposure, white balance, flicker; photometric.hpp) unless
/// `normalise_gains` is false.
PhaseAverage average_window(const CaptureSums& sums, FrameWindow window, int min_frames, bool normalise_gains = true);

/// The study's protocol in one video: baseline, then press. Finds the step in
/// the per-frame block statistics (two-segment least squares), the end of the
/// press's transient (the statistics within 10 % of their final value), and
/// returns the last `window` frames before the step (minus a margin) and the
/// last `window` frames of the settled press (before the part's removal, when the capture
/// goes on after it: a second step back toward the baseline).
struct PhaseSplit {
  int press_frame = 0;          ///< first frame of the press
  int settled_frame = 0;        ///< first frame within 10 % of the final state
  /// First frame after the part's removal (a second step back toward the baseline; the worn
  /// window ends before it), or -1 when the capture ends worn.
  int release_frame = -1;
  FrameWindow baseline, worn;
  double step_sigmas = 0;       ///< size of the step in units of the frame-to-frame noise
};
/// Throws InputError when there is no significant step (a missing phase) or
/// too few frames on either side.
PhaseSplit split_phases(const CaptureSums& sums, int window_frames);

/// The last `window_frames` frames of a capture (whole chunks).
FrameWindow last_frames(const CaptureSums& sums, int window_frames);

}  // namespace clearfit
