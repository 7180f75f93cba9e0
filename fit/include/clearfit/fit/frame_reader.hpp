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
  int width = 0, height = 0;   ///< as displayed (after the rotation)
  // Videos: what the stream says and how it was decoded.
  std::string codec;           ///< e.g. "h264", "hevc", "ffv1"; "png"/"tiff"/... for image folders
  bool lossy = false;          ///< the codec compresses lossily (H.264, HEVC, MJPEG, JPEG frames...): its noise does not average away
  std::string pixel_format;    ///< e.g. "yuv420p", "yuv420p10le", "bgr24"
  std::string colour_matrix;   ///< "bt709", "bt601", "bt2020" or "rgb" (what the YUV was converted with)
  bool limited_range = false;  ///< the YUV codes span 16–235 (TV range), expanded to full range when decoded
  int rotation_deg = 0;        ///< clockwise rotation applied to the coded frames so they show upright (0, 90, 180, 270)
  int bit_depth = 8;           ///< bits per sample of the source; frames above 8 bits are read as 16-bit
};

/// Reads a capture as BGR frames: a video file (any format FFmpeg reads, decoded
/// on several threads) or a folder of images (PNG, JPEG, TIFF, BMP, sorted by
/// file name). Videos are converted with the colour matrix (BT.601/709/2020) and
/// range (limited/full) their stream declares (untagged: BT.709 from 720 lines
/// up, else BT.601; limited range unless the format is a full-range one), and
/// turned upright by their rotation metadata. Frames are CV_8UC3, or CV_16UC3
/// when the source has more than 8 bits (16-bit PNG/TIFF, 10-bit video).
/// Throws InputError for a missing source, an unreadable video, a folder
/// without images, a frame that cannot be read or differs in size or depth
/// from the first, or a frame that is neither 8- nor 16-bit.
class FrameReader {
 public:
  explicit FrameReader(const std::filesystem::path& source);
  ~FrameReader();
  FrameReader(const FrameReader&) = delete;
  FrameReader& operator=(const FrameReader&) = delete;
  const CaptureInfo& info() const;
  /// The next frame (BGR, 8- or 16-bit as info().bit_depth says; grey frames are expanded); false at the end.
  /// A video frame is decoded into `bgr`'s buffer when it has the size and type and nothing else refers to
  /// it (no page faults for a fresh buffer per frame); otherwise `bgr` gets a new one.
  bool read(cv::Mat& bgr);
  /// Videos (upright ones): frames read after this are converted to BGR only inside `region` (image
  /// pixels, clipped to the image), with the same values there as a whole frame's; pixels more than
  /// 10 px from the region are black (those nearer hold what the chroma filters' margin converted). Saves the colour conversion of pixels nobody reads. Empty: whole frames (the
  /// default). Rotated videos and image folders are always read whole.
  void set_region(const cv::Rect& region);
  /// The frame last read, whole whatever the region (BGR as read() gives it; empty before the first
  /// read). For pictures: one frame converted whole again.
  cv::Mat whole_last_frame();
  /// Name of the frame last read (file name, or "frame N").
  std::string frame_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clearfit
