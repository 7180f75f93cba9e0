#include <algorithm>
#include <cctype>
#include <clearfit/error.hpp>
#include <clearfit/fit/frame_reader.hpp>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/display.h>
#include <libavutil/imgutils.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

namespace clearfit {
namespace {

std::string lower_extension(const std::filesystem::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

bool is_image_file(const std::filesystem::path& p) {
  const std::string ext = lower_extension(p);
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp";
}

std::string av_message(int err) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(err, buf, sizeof buf);
  return buf;
}

/// The full-range twin of FFmpeg's deprecated "J" formats (yuvj420p is yuv420p in full range).
AVPixelFormat unjpeg(AVPixelFormat f, bool& full_range) {
  switch (f) {
    case AV_PIX_FMT_YUVJ420P: full_range = true; return AV_PIX_FMT_YUV420P;
    case AV_PIX_FMT_YUVJ422P: full_range = true; return AV_PIX_FMT_YUV422P;
    case AV_PIX_FMT_YUVJ444P: full_range = true; return AV_PIX_FMT_YUV444P;
    case AV_PIX_FMT_YUVJ440P: full_range = true; return AV_PIX_FMT_YUV440P;
    default: return f;
  }
}

/// Clockwise degrees (0, 90, 180, 270) that turn the coded frames upright, from the display matrix.
int stream_rotation(const AVStream* st) {
  const std::uint8_t* m = av_stream_get_side_data(st, AV_PKT_DATA_DISPLAYMATRIX, nullptr);
  if (m == nullptr) return 0;
  const double ccw = av_display_rotation_get(reinterpret_cast<const std::int32_t*>(m));  // counter-clockwise
  if (!std::isfinite(ccw)) return 0;
  const int cw = static_cast<int>(std::lround(-ccw / 90.0)) * 90;
  return ((cw % 360) + 360) % 360;
}

}  // namespace

/// A video decoded by FFmpeg on several threads, converted with the stream's colour matrix and range.
struct VideoDecoder {
  /// A conversion to BGR of one size and source format, with the stream's matrix and range.
  struct Converter {
    SwsContext* sws = nullptr;
    int w = 0, h = 0;
    AVPixelFormat fmt = AV_PIX_FMT_NONE;
    Converter() = default;
    Converter(const Converter&) = delete;
    Converter& operator=(const Converter&) = delete;
    ~Converter() { sws_freeContext(sws); }
  };
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* frame = nullptr;
  AVFrame* last = nullptr;  ///< the frame last converted, kept for whole_last()
  Converter part, whole;    ///< the region's conversion and the whole frame's
  int stream = -1;
  bool draining = false, finished = false;
  bool sixteen = false;
  cv::Rect region;          ///< coded pixels to convert (empty: all)

  ~VideoDecoder() {
    av_frame_free(&last);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&codec);
    avformat_close_input(&format);
  }

  void open(const std::filesystem::path& source, CaptureInfo& info) {
    const std::string src = source.string();
    auto fail = [&](const std::string& what) {
      throw InputError(src, "", "cannot be opened as a video (" + what + ")",
                       "give a video FFmpeg reads (e.g. .mp4, .mov, .mkv, .avi) or a folder of images");
    };
    av_log_set_level(AV_LOG_ERROR);
    if (int e = avformat_open_input(&format, src.c_str(), nullptr, nullptr); e < 0) fail(av_message(e));
    if (int e = avformat_find_stream_info(format, nullptr); e < 0) fail(av_message(e));
    const AVCodec* dec = nullptr;
    stream = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &dec, 0);
    if (stream < 0 || dec == nullptr) fail("no video stream FFmpeg can decode");
    AVStream* st = format->streams[stream];
    codec = avcodec_alloc_context3(dec);
    if (codec == nullptr || avcodec_parameters_to_context(codec, st->codecpar) < 0) fail("codec parameters");
    codec->thread_count = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
    codec->thread_type = FF_THREAD_FRAME | FF_THREAD_SLICE;
    if (int e = avcodec_open2(codec, dec, nullptr); e < 0) fail(av_message(e));
    packet = av_packet_alloc();
    frame = av_frame_alloc();
    last = av_frame_alloc();
    info.is_video = true;
    const AVRational fr = av_guess_frame_rate(format, st, nullptr);
    info.fps = fr.num > 0 && fr.den > 0 ? av_q2d(fr) : 0;
    if (!(info.fps > 0 && info.fps < 10000)) info.fps = 0;
    info.frames = static_cast<int>(st->nb_frames);
    if (info.frames <= 0 && info.fps > 0 && format->duration > 0)
      info.frames = static_cast<int>(std::lround(format->duration / double(AV_TIME_BASE) * info.fps));
    const AVCodecDescriptor* desc = avcodec_descriptor_get(codec->codec_id);
    info.codec = desc != nullptr ? desc->name : dec->name;
    info.lossy = desc != nullptr && (desc->props & AV_CODEC_PROP_LOSSY) != 0;
    info.rotation_deg = stream_rotation(st);
    const bool quarter = info.rotation_deg == 90 || info.rotation_deg == 270;
    info.width = quarter ? codec->height : codec->width;
    info.height = quarter ? codec->width : codec->height;
    const AVPixFmtDescriptor* pd = av_pix_fmt_desc_get(codec->pix_fmt);
    info.pixel_format = pd != nullptr ? pd->name : "unknown";
    info.bit_depth = pd != nullptr ? pd->comp[0].depth : 8;
    sixteen = info.bit_depth > 8;
    describe_colour(codec->colorspace, codec->color_range, codec->pix_fmt, codec->height, info);
  }

  /// The matrix and range the frames are converted with (what the stream declares; untagged: by size).
  static int describe_colour(AVColorSpace space, AVColorRange range, AVPixelFormat fmt, int coded_height, CaptureInfo& info) {
    const AVPixFmtDescriptor* pd = av_pix_fmt_desc_get(fmt);
    const bool rgb = pd != nullptr && (pd->flags & AV_PIX_FMT_FLAG_RGB) != 0;
    bool full = range == AVCOL_RANGE_JPEG;
    unjpeg(fmt, full);
    info.limited_range = !rgb && !full;
    int cs = SWS_CS_ITU601;
    switch (space) {
      case AVCOL_SPC_BT709: cs = SWS_CS_ITU709; break;
      case AVCOL_SPC_BT470BG:
      case AVCOL_SPC_SMPTE170M: cs = SWS_CS_ITU601; break;
      case AVCOL_SPC_BT2020_NCL:
      case AVCOL_SPC_BT2020_CL: cs = SWS_CS_BT2020; break;
      case AVCOL_SPC_SMPTE240M: cs = SWS_CS_SMPTE240M; break;
      case AVCOL_SPC_FCC: cs = SWS_CS_FCC; break;
      default: cs = coded_height >= 720 ? SWS_CS_ITU709 : SWS_CS_ITU601;  // what players assume for untagged video
    }
    info.colour_matrix = rgb ? "rgb" : cs == SWS_CS_ITU709 ? "bt709" : cs == SWS_CS_BT2020 ? "bt2020" : cs == SWS_CS_SMPTE240M ? "smpte240m" : cs == SWS_CS_FCC ? "fcc" : "bt601";
    return cs;
  }

  /// Decodes the next frame into `frame`; false at the end of the stream.
  bool decode(const std::string& src) {
    for (;;) {
      const int r = avcodec_receive_frame(codec, frame);
      if (r == 0) return true;
      if (r == AVERROR_EOF) return false;
      if (r != AVERROR(EAGAIN)) throw InputError(src, "", "cannot be decoded: " + av_message(r), "check the video file");
      if (draining) return false;
      const int e = av_read_frame(format, packet);
      if (e == AVERROR_EOF || e < 0) {
        draining = true;
        avcodec_send_packet(codec, nullptr);
        continue;
      }
      if (packet->stream_index == stream) {
        const int s = avcodec_send_packet(codec, packet);
        if (s < 0 && s != AVERROR(EAGAIN) && s != AVERROR_INVALIDDATA)
          throw InputError(src, "", "cannot be decoded: " + av_message(s), "check the video file");
      }
      av_packet_unref(packet);
    }
  }

  /// The coded pixels converted for `region`: grown by a margin for the chroma filters' taps and
  /// aligned to the chroma subsampling, so that inside `region` the values are the whole frame's,
  /// bit for bit (frame_reader_test). The whole frame for rotated streams and formats whose planes
  /// cannot be offset (palettes, bit streams).
  cv::Rect converted_rect(const AVFrame& f) const {
    const cv::Rect all(0, 0, f.width, f.height);
    const AVPixFmtDescriptor* pd = av_pix_fmt_desc_get(static_cast<AVPixelFormat>(f.format));
    if (region.area() == 0 || pd == nullptr || (pd->flags & (AV_PIX_FMT_FLAG_PAL | AV_PIX_FMT_FLAG_BITSTREAM | AV_PIX_FMT_FLAG_HWACCEL)) != 0)
      return all;
    constexpr int kChromaMargin = 8;  // taps of swscale's chroma interpolation, with room to spare
    const int ax = 1 << pd->log2_chroma_w, ay = 1 << pd->log2_chroma_h;
    cv::Rect r(region.x - kChromaMargin, region.y - kChromaMargin, region.width + 2 * kChromaMargin, region.height + 2 * kChromaMargin);
    r &= all;
    const int x0 = r.x / ax * ax, y0 = r.y / ay * ay;
    const int x1 = std::min(f.width, (r.br().x + ax - 1) / ax * ax), y1 = std::min(f.height, (r.br().y + ay - 1) / ay * ay);
    return {x0, y0, x1 - x0, y1 - y0};
  }

  /// Converts `rect` of `f` (coded pixels, aligned by converted_rect) into `dst` (rect's size, BGR).
  void convert(const std::string& src, CaptureInfo& info, const AVFrame& f, const cv::Rect& rect, Converter& c, cv::Mat dst) {
    auto fmt = static_cast<AVPixelFormat>(f.format);
    if (c.sws == nullptr || rect.width != c.w || rect.height != c.h || fmt != c.fmt) {
      sws_freeContext(c.sws);
      bool full = f.color_range == AVCOL_RANGE_JPEG;
      const AVPixelFormat src_fmt = unjpeg(fmt, full);
      const int cs = describe_colour(f.colorspace, full ? AVCOL_RANGE_JPEG : f.color_range, fmt, f.height, info);
      c.sws = sws_getContext(rect.width, rect.height, src_fmt, rect.width, rect.height, sixteen ? AV_PIX_FMT_BGR48 : AV_PIX_FMT_BGR24,
                             SWS_BILINEAR | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT | SWS_FULL_CHR_H_INP, nullptr, nullptr, nullptr);
      if (c.sws == nullptr) throw InputError(src, "", "has a pixel format clearfit cannot convert (" + info.pixel_format + ")");
      // Source matrix and range as declared; destination full-range RGB.
      sws_setColorspaceDetails(c.sws, sws_getCoefficients(cs), info.limited_range ? 0 : 1, sws_getCoefficients(SWS_CS_DEFAULT), 1, 0,
                               1 << 16, 1 << 16);
      c.w = rect.width, c.h = rect.height, c.fmt = fmt;
    }
    // The planes offset to the rect's corner (as FFmpeg's crop filter does).
    const AVPixFmtDescriptor* pd = av_pix_fmt_desc_get(fmt);
    int max_step[4] = {};
    av_image_fill_max_pixsteps(max_step, nullptr, pd);
    const std::uint8_t* planes[4] = {};
    for (int i = 0; i < 4; ++i) {
      if (f.data[i] == nullptr) continue;
      const bool chroma = i == 1 || i == 2;
      const int hs = chroma ? pd->log2_chroma_w : 0, vs = chroma ? pd->log2_chroma_h : 0;
      planes[i] = f.data[i] + static_cast<std::ptrdiff_t>(rect.y >> vs) * f.linesize[i] + ((rect.x * max_step[i]) >> hs);
    }
    std::uint8_t* dst_planes[4] = {dst.data, nullptr, nullptr, nullptr};
    int dst_stride[4] = {static_cast<int>(dst.step[0]), 0, 0, 0};
    sws_scale(c.sws, planes, f.linesize, 0, rect.height, dst_planes, dst_stride);
  }

  bool read(const std::string& src, CaptureInfo& info, cv::Mat& out) {
    if (finished) return false;
    if (!decode(src)) return finished = true, false;
    const int w = frame->width, h = frame->height;
    // Upright frames are converted straight into `out` (its buffer reused when it has the size and type).
    const int type = sixteen ? CV_16UC3 : CV_8UC3;
    cv::Mat coded;
    if (info.rotation_deg == 0) out.create(h, w, type), coded = out;
    else coded.create(h, w, type);
    const cv::Rect rect = info.rotation_deg == 0 ? converted_rect(*frame) : cv::Rect(0, 0, w, h);
    convert(src, info, *frame, rect, rect.size() == coded.size() ? whole : part, coded(rect));
    if (rect.size() != coded.size()) {  // black around the region (a recycled buffer held another frame)
      coded.rowRange(0, rect.y).setTo(0), coded.rowRange(rect.br().y, h).setTo(0);
      coded(cv::Rect(0, rect.y, rect.x, rect.height)).setTo(0), coded(cv::Rect(rect.br().x, rect.y, w - rect.br().x, rect.height)).setTo(0);
    }
    av_frame_unref(last);
    av_frame_move_ref(last, frame);
    turn_upright(info, coded, out);
    return true;
  }

  /// The frame last read, whole (an empty Mat before the first).
  cv::Mat whole_last(const std::string& src, CaptureInfo& info) {
    if (last->data[0] == nullptr) return {};
    cv::Mat coded(last->height, last->width, sixteen ? CV_16UC3 : CV_8UC3), out;
    convert(src, info, *last, cv::Rect(0, 0, last->width, last->height), whole, coded);
    turn_upright(info, coded, out);
    return out;
  }

  static void turn_upright(const CaptureInfo& info, const cv::Mat& coded, cv::Mat& out) {
    switch (info.rotation_deg) {
      case 90: cv::rotate(coded, out, cv::ROTATE_90_CLOCKWISE); break;
      case 180: cv::rotate(coded, out, cv::ROTATE_180); break;
      case 270: cv::rotate(coded, out, cv::ROTATE_90_COUNTERCLOCKWISE); break;
      default: out = coded; break;
    }
  }
};

struct FrameReader::Impl {
  CaptureInfo info;
  std::unique_ptr<VideoDecoder> video;
  std::vector<std::filesystem::path> files;
  int next = 0;
  int depth = CV_8U;
  std::string last_name;
  cv::Mat last_image;  ///< image folders: the frame last read
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
    m.depth = first.depth();
    if (m.depth != CV_8U && m.depth != CV_16U)
      throw InputError(m.files.front().string(), "", "is neither an 8-bit nor a 16-bit image",
                       "captures are 8- or 16-bit sRGB frames as a camera or raw converter writes them");
    m.info.bit_depth = m.depth == CV_16U ? 16 : 8;
    const std::string ext = lower_extension(m.files.front());
    m.info.codec = ext == ".jpg" || ext == ".jpeg" ? "jpeg" : ext == ".tif" || ext == ".tiff" ? "tiff" : ext.substr(1);
    m.info.lossy = m.info.codec == "jpeg";
    m.info.colour_matrix = "rgb";
  } else {
    m.video = std::make_unique<VideoDecoder>();
    m.video->open(source, m.info);
    m.depth = m.info.bit_depth > 8 ? CV_16U : CV_8U;
  }
}

FrameReader::~FrameReader() = default;

const CaptureInfo& FrameReader::info() const { return impl_->info; }

void FrameReader::set_region(const cv::Rect& region) {
  if (impl_->video) impl_->video->region = region & cv::Rect(0, 0, impl_->info.width, impl_->info.height);
}

cv::Mat FrameReader::whole_last_frame() {
  Impl& m = *impl_;
  cv::Mat frame = m.video ? m.video->whole_last(m.info.source.string(), m.info) : m.last_image;
  cv::Mat bgr;
  if (frame.empty() || frame.channels() == 3) return frame;
  cv::cvtColor(frame, bgr, frame.channels() == 1 ? cv::COLOR_GRAY2BGR : cv::COLOR_BGRA2BGR);
  return bgr;
}

std::string FrameReader::frame_name() const { return impl_->last_name; }

bool FrameReader::read(cv::Mat& bgr) {
  Impl& m = *impl_;
  cv::Mat frame;
  if (m.video) {
    if (bgr.u != nullptr && bgr.u->refcount == 1) frame = bgr;  // nothing else sees bgr's buffer: decoded into it when it fits
    if (!m.video->read(m.info.source.string(), m.info, frame)) return false;
    m.last_name = "frame " + std::to_string(m.next);
  } else {
    if (m.next >= static_cast<int>(m.files.size())) return false;
    const auto& file = m.files[m.next];
    frame = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    m.last_name = file.filename().string();
    if (frame.empty()) throw InputError(file.string(), "", "cannot be read as an image");
    m.last_image = frame;
    if (frame.depth() != m.depth)
      throw InputError(file.string(), "", std::string("is ") + (frame.depth() == CV_8U ? "8" : frame.depth() == CV_16U ? "16" : "neither 8 nor 16") +
                                              "-bit, the capture's first frame is " + std::to_string(m.info.bit_depth) + "-bit",
                       "all frames of a capture must have one bit depth");
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
