#pragma once
// Videos as inputs of detect, calibrate and pose: every frame is read once and
// measured (corners found, edge blur), the views worth keeping are picked
// (camera/view_selection.hpp), and the video is read again for their pixels.
// What was read, used and dropped (per reason) is printed and reported.
#include <clearfit/camera/tag_pose.hpp>
#include <clearfit/camera/view_selection.hpp>
#include <clearfit/fit/frame_reader.hpp>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace clearfit::cli {

/// Command-line inputs split into image files (folders expanded, as
/// list_images) and videos (files that are not images: .mp4 .mov .mkv ...).
struct ViewInputs {
  std::vector<std::filesystem::path> images, videos;
};
ViewInputs split_view_inputs(const std::vector<std::string>& inputs);

/// The frames kept from one video, with what was dropped and why.
struct VideoViews {
  std::filesystem::path source;
  CaptureInfo info;
  int frames_read = 0;
  ViewSelection selection;
  ViewSelectionOptions options;
  std::vector<int> frames;         ///< indices of the used frames (0-based, decoding order)
  std::vector<std::string> names;  ///< "<video>#<index>": how reports and corners files name them
  std::vector<cv::Mat> images;     ///< their pixels, 8-bit grey
  std::vector<ViewCandidate> candidates;  ///< what was measured of every frame
  /// {"source", "codec", "frames_read", "used", "dropped": {reason: count}, ...} for the command's report.
  nlohmann::json json() const;
  /// One line for people: frames read, used, dropped per reason.
  std::string summary() const;
};

/// What a command finds in one 8-bit grey frame (called from several threads at once).
using MeasureFrame = std::function<ViewCandidate(const cv::Mat& grey)>;

/// The candidate of a frame whose corners are `corners` (layout as
/// ViewCandidate): the edge blur is measured in the hull of all valid corners
/// (group 0: one board) or in each group of `group` consecutive corners with
/// all of them valid (group 4: one quad per tag); with no corners, in the whole frame.
ViewCandidate frame_candidate(const cv::Mat& grey, std::vector<Eigen::Vector3d> corners, int group = 0);

/// Reads `video`, measures every frame, picks the views (select_views with
/// `distinct`) and reads their pixels. Progress on stderr. `thing` names what
/// is looked for in messages ("board", "tags"). Throws InputError (exit 2)
/// for a video that cannot be read, holds no frame, or has no frame worth keeping
/// (the message says why the frames were dropped and what to do).
VideoViews read_video_views(const std::filesystem::path& video, const MeasureFrame& measure, const ViewSelectionOptions& options,
                            bool distinct, const std::string& thing);

/// A board's views in a video (detect_board on every frame, distinct views).
VideoViews read_board_video(const std::filesystem::path& video, const Board& board, const DetectOptions& detect,
                            const ViewSelectionOptions& options);

/// The frames of a still camera's video that show the tags of `layout`
/// (detect_tags on every frame; the sharpest, not necessarily distinct).
VideoViews read_tag_video(const std::filesystem::path& video, const TagLayout& layout, const DetectOptions& detect,
                          const ViewSelectionOptions& options);

/// A board's views in image files and videos: the image files' first (in their
/// order, detected in parallel), then each video's kept frames.
struct BoardViews {
  std::vector<BoardObservation> views;
  std::size_t files = 0;                 ///< views[0, files) come from image files, the rest from videos
  std::vector<cv::Mat> frames;           ///< the pixels of views[files, ...) (8-bit grey)
  nlohmann::json videos = nlohmann::json::array();  ///< VideoViews::json() of each video
  std::vector<std::string> summaries;    ///< VideoViews::summary() of each video
  /// The 8-bit grey pixels of views[k] (image files are read again); InputError if unreadable.
  cv::Mat image(std::size_t k) const;
};
BoardViews detect_board_views(const std::vector<std::string>& inputs, const Board& board, const DetectOptions& detect,
                              const ViewSelectionOptions& options, const std::function<void(int done, int total)>& progress);

/// --max-views, --max-blur-ratio, --min-corner-shift bound to `options` (defaults as ViewSelectionOptions).
void add_video_options(CLI::App& sub, ViewSelectionOptions& options, bool distinct = true);

/// 8-bit grey of a BGR frame (8- or 16-bit).
cv::Mat grey8(const cv::Mat& bgr);

}  // namespace clearfit::cli
