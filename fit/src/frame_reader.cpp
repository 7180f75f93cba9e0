#include <algorithm>
#include <cctype>
#include <clearfit/error.hpp>
#include <clearfit/fit/frame_reader.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

namespace clearfit {
namespace {

bool is_image_file(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp";
}

}  // namespace

struct FrameReader::Impl {
  CaptureInfo info;
  cv::VideoCapture video;
  std::vector<std::filesystem::path> files;
  int next = 0;
  std::string last_name;
};

FrameReader::FrameReader(const std::filesystem::path& source) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.info.source = source;
  if (!std::filesystem::exists(source))
    throw InputError(source.string(), "", "capture not found", "give a video file or a folder of images");
  if (std::filesystem::is_directory(source)) {
    for (const auto& e : std::filesystem::directory_iterator(source))
      if (e.is_regular_file() && is_image_file(e.path())) m.files.push_back(e.path());
    std::sort(m.files.begin(), m.files.end());
    if (m.files.empty())
      throw InputError(source.string(), "", "the folder holds no images (.png .jpg .tif .bmp)",
                       "give a folder of frames or a video file");
    m.info.frames = static_cast<int>(m.files.size());
    const cv::Mat first = cv::imread(m.files.front().string(), cv::IMREAD_UNCHANGED);
    if (first.empty()) throw InputError(m.files.front().string(), "", "cannot be read as an image");
    m.info.width = first.cols;
    m.info.height = first.rows;
  } else {
    m.info.is_video = true;
    if (!m.video.open(source.string(), cv::CAP_FFMPEG) || !m.video.isOpened())
      throw InputError(source.string(), "", "cannot be opened as a video",
                       "give a video FFmpeg reads (e.g. .mp4, .mkv, .avi) or a folder of images");
    m.info.fps = m.video.get(cv::CAP_PROP_FPS);
    m.info.frames = static_cast<int>(m.video.get(cv::CAP_PROP_FRAME_COUNT));
    m.info.width = static_cast<int>(m.video.get(cv::CAP_PROP_FRAME_WIDTH));
    m.info.height = static_cast<int>(m.video.get(cv::CAP_PROP_FRAME_HEIGHT));
    if (!(m.info.fps > 0 && m.info.fps < 10000)) m.info.fps = 0;
  }
}

FrameReader::~FrameReader() = default;

const CaptureInfo& FrameReader::info() const { return impl_->info; }

std::string FrameReader::frame_name() const { return impl_->last_name; }

bool FrameReader::read(cv::Mat& bgr) {
  Impl& m = *impl_;
  cv::Mat frame;
  if (m.info.is_video) {
    if (!m.video.read(frame) || frame.empty()) return false;
    m.last_name = "frame " + std::to_string(m.next);
  } else {
    if (m.next >= static_cast<int>(m.files.size())) return false;
    const auto& file = m.files[m.next];
    frame = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    m.last_name = file.filename().string();
    if (frame.empty()) throw InputError(file.string(), "", "cannot be read as an image");
    if (frame.depth() != CV_8U)
      throw InputError(file.string(), "", "is not an 8-bit image", "captures are 8-bit sRGB frames as a camera writes them");
  }
  if (frame.cols != m.info.width || frame.rows != m.info.height)
    throw InputError(m.info.source.string(), m.last_name,
                     "is " + std::to_string(frame.cols) + "x" + std::to_string(frame.rows) + ", the capture's first frame is " +
                         std::to_string(m.info.width) + "x" + std::to_string(m.info.height),
                     "all frames of a capture must have one size");
  if (frame.channels() == 1)
    cv::cvtColor(frame, bgr, cv::COLOR_GRAY2BGR);
  else if (frame.channels() == 4)
    cv::cvtColor(frame, bgr, cv::COLOR_BGRA2BGR);
  else
    bgr = frame;
  ++m.next;
  return true;
}

}  // namespace clearfit
