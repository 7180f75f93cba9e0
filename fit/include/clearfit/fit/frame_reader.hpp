#pragma once
// Frames of a capture, one at a time: a video file or a folder of images.
#include <opencv2/core.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace clearfit {

struct CaptureInfo {
  std::filesystem::path source;
  bool is_video = false;
  int frames = 0;      ///< frames read (after read_capture), else as reported by the container / folder
  double fps = 0;      ///< 0 when unknown (image folders)
  int width = 0, height = 0;
};

/// Reads a capture as 8-bit BGR frames: a video file (any format OpenCV's
/// FFmpeg back end reads) or a folder of images (PNG, JPEG, TIFF, BMP, sorted
/// by file name). Throws InputError for a missing source, an unreadable video,
/// a folder without images, a frame that cannot be read or differs in size
/// from the first, or a frame that is not 8-bit.
class FrameReader {
 public:
  explicit FrameReader(const std::filesystem::path& source);
  ~FrameReader();
  FrameReader(const FrameReader&) = delete;
  FrameReader& operator=(const FrameReader&) = delete;
  const CaptureInfo& info() const;
  /// The next frame (8-bit BGR; grey frames are expanded); false at the end.
  bool read(cv::Mat& bgr);
  /// Name of the frame last read (file name, or "frame N").
  std::string frame_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clearfit
