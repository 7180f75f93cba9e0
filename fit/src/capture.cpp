#include <algorithm>
#include <chrono>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/fit/capture.hpp>
#include <clearfit/fit/photometric.hpp>
#include <clearfit/fit/srgb.hpp>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <limits>
#include <optional>
#include <sstream>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>
#include <thread>
#include <type_traits>

namespace clearfit {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

std::string fmt(double v, int digits = 2) { return fixed_digits(v, digits); }

}  // namespace

namespace {

/// Decodes frames on a thread of its own into a short queue.
class FrameQueue {
 public:
  explicit FrameQueue(FrameReader& reader) : reader_(reader), thread_([this] { run(); }) {}
  ~FrameQueue() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  /// Next frame and its name; false at the end. Rethrows a decoding error.
  bool pop(cv::Mat& frame, std::string& name) {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return !queue_.empty() || done_; });
    if (queue_.empty()) {
      if (error_) std::rethrow_exception(error_);
      return false;
    }
    frame = std::move(queue_.front().first);
    name = std::move(queue_.front().second);
    queue_.pop_front();
    cv_.notify_all();
    return true;
  }
  /// Gives a frame's buffer back for a later frame to be decoded into (when nothing else refers to it).
  void recycle(cv::Mat&& frame) {
    if (frame.u == nullptr || frame.u->refcount != 1) return;
    std::lock_guard lock(mutex_);
    if (spare_.size() < 2) spare_.push_back(std::move(frame));
  }

 private:
  void run() {
    try {
      for (;;) {
        cv::Mat frame;
        {
          std::lock_guard lock(mutex_);
          if (!spare_.empty()) frame = std::move(spare_.back()), spare_.pop_back();
        }
        if (!reader_.read(frame)) break;
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [&] { return queue_.size() < 4 || stop_; });
        if (stop_) break;
        queue_.emplace_back(std::move(frame), reader_.frame_name());  // each read fills its own Mat: no copy
        cv_.notify_all();
      }
    } catch (...) {
      std::lock_guard lock(mutex_);
      error_ = std::current_exception();
    }
    std::lock_guard lock(mutex_);
    done_ = true;
    cv_.notify_all();
  }

  FrameReader& reader_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::pair<cv::Mat, std::string>> queue_;
  std::vector<cv::Mat> spare_;  ///< buffers given back by the consumer
  bool done_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

/// The registration references of one read: the shared first one and, with
/// CaptureReadOptions::max_references > 1, those taken where the view changed beyond the
/// motion limit (a phase filmed through another geometry in the same video). A frame's motion
/// is against its own reference (the motion across a change of geometry cannot be told from
/// the change); the caller places each phase's window (capture.hpp).
class References {
 public:
  References(MotionRegistration* first, const CaptureReadOptions& o, cv::Size image, const cv::Rect& roi)
      : o_(o), image_(image), roi_(roi) {
    if (first) refs_.push_back(first), last_.emplace_back();
  }
  MotionRegistration* current() const { return refs_.empty() ? nullptr : refs_[cur_]; }
  int index() const { return cur_; }
  /// Records the frame's motion against the current reference.
  void measured(const Similarity& m) {
    if (!refs_.empty() && m.t.allFinite()) last_[cur_] = m;
  }
  /// A frame beyond the motion limit against the current reference: the other references are
  /// tried (the view back to an earlier geometry), each from the motion last measured against it,
  /// then the frame becomes a new one. False when neither fits (the caller refuses the motion).
  bool change(const cv::Mat& frame, const Similarity& previous, Similarity& motion, int& patches_used) {
    if (refs_.empty() || o_.max_references <= 1) return false;
    for (int i = 0; i < static_cast<int>(refs_.size()); ++i) {
      if (i == cur_) continue;
      const RegistrationResult r = refs_[i]->measure(frame, last_[i]);
      if (r.found && r.motion.t.allFinite() && r.motion.max_displacement(roi_) <= o_.max_motion_px) {
        cur_ = i, motion = r.motion, patches_used = r.patches_used;
        return true;
      }
    }
    if (static_cast<int>(refs_.size()) >= o_.max_references) return false;
    owned_.push_back(std::make_unique<MotionRegistration>(image_, roi_, o_.registration,
                                                          o_.seen.size() == roi_.size() ? o_.seen : cv::Mat()));
    owned_.back()->set_reference(frame);
    owned_.back()->close_reference();  // a view's own reference is its first frame (the averaged one is the shared first)
    refs_.push_back(owned_.back().get());
    cur_ = static_cast<int>(refs_.size()) - 1;
    motion = Similarity{};
    motion.centre = previous.centre;
    last_.push_back(motion);
    patches_used = static_cast<int>(refs_[cur_]->patches().size());
    return true;
  }

 private:
  const CaptureReadOptions& o_;
  cv::Size image_;
  cv::Rect roi_;
  std::vector<MotionRegistration*> refs_;
  std::vector<std::unique_ptr<MotionRegistration>> owned_;
  std::vector<Similarity> last_;  ///< per reference: the motion last measured against it
  int cur_ = 0;
};

/// The frames' linear green summed into a chunk's accumulator at their integer shifts, and the
/// statistics read on the way (from every other row: the means over an 8×8 grid of blocks of the
/// roi, the saturated pixels and the mean green code).
class GreenSums {
 public:
  GreenSums(const cv::Rect& roi, cv::Size image)
      : roi_(roi), image_(image), row_block_sum_(static_cast<std::size_t>(roi.height) * 8), row_saturated_(roi.height),
        row_code_(roi.height) {}
  /// Adds (sign +1) or removes (-1) the frame's linear green at integer shift d to `acc`; with
  /// `stats`, also the per-row block sums, saturated pixels and green codes. `deep`: the frame's
  /// 16-bit original (deep_frame), else empty.
  void accumulate(const cv::Mat& frame, const cv::Mat& deep, cv::Mat& acc, cv::Point d, float sign, bool stats) {
    if (deep.empty())
      sum_rows<cv::Vec3b>(frame, lut8_, acc, d, sign, stats);
    else
      sum_rows<cv::Vec3w>(deep, srgb::to_linear_table16(), acc, d, sign, stats);
  }
  /// Appends the statistics of the frame last accumulated with `stats` to `sums`.
  void append_statistics(CaptureSums& sums) const {
    std::array<float, 64> blocks{};
    std::array<int, 64> block_pixels{};
    long long stat_saturated = 0, stat_code = 0;
    for (int y = 0; y < roi_.height; y += 2) {  // the rows that carry statistics
      stat_saturated += row_saturated_[y];
      stat_code += row_code_[y];
      for (int b = 0; b < 8; ++b) {
        const int k = (y * 8 / roi_.height) * 8 + b;
        blocks[k] += static_cast<float>(row_block_sum_[static_cast<std::size_t>(y) * 8 + b]);
        // pixels in column block b of a row: x with x*8/w == b
        block_pixels[k] += (roi_.width * (b + 1) + 7) / 8 - (roi_.width * b + 7) / 8;
      }
    }
    const double stat_pixels = static_cast<double>((roi_.height + 1) / 2) * roi_.width;
    for (int k = 0; k < 64; ++k) blocks[k] = block_pixels[k] > 0 ? blocks[k] / block_pixels[k] : 0.f;
    sums.blocks.push_back(blocks);
    sums.saturated_fraction.push_back(static_cast<float>(stat_saturated / stat_pixels));
    sums.mean_code.push_back(static_cast<float>(stat_code / stat_pixels));
  }

 private:
  // Pixel type Px: 8-bit codes through the 256-entry table, 16-bit through the 65536-entry one;
  // the statistics count codes at full scale as saturated and the mean code in 8-bit units.
  template <class Px>
  void sum_rows(const cv::Mat& img, const float* table, cv::Mat& acc, cv::Point d, float sign, bool stats) {
    const cv::Rect roi = roi_;
    const int width = image_.width, height = image_.height;
    constexpr int code_max = sizeof(typename Px::value_type) == 1 ? 255 : 65535, code_shift = code_max == 255 ? 0 : 8;
    tbb::parallel_for(tbb::blocked_range<int>(0, roi.height, 16), [&](const tbb::blocked_range<int>& rows) {
      for (int y = rows.begin(); y < rows.end(); ++y) {
        // Aligned pixel (x, y) of the roi reads the frame at (x, y) + d (clamped at the image edge).
        const int sy = std::clamp(roi.y + y + d.y, 0, height - 1);
        const auto* src = img.ptr<Px>(sy);
        float* dst = acc.ptr<float>(y);
        const int lo_all = std::clamp(-(roi.x + d.x), 0, roi.width);
        const int hi_all = std::clamp(width - (roi.x + d.x), lo_all, roi.width);
        if (!stats || (y & 1) != 0) {  // statistics come from every other row; the sum from all
          const float first = sign * table[src[0][1]], last = sign * table[src[width - 1][1]];
          const Px* row = src + roi.x + d.x;
          for (int x = 0; x < lo_all; ++x) dst[x] += first;
          for (int x = lo_all; x < hi_all; ++x) dst[x] += sign * table[row[x][1]];
          for (int x = hi_all; x < roi.width; ++x) dst[x] += last;
          continue;
        }
        double block[8] = {};
        int saturated = 0;
        long long code = 0;
        // Eight column blocks; inside each, pixels whose source lies in the image need no clamp.
        for (int b = 0; b < 8; ++b) {
          const int x0 = (roi.width * b + 7) / 8, x1 = (roi.width * (b + 1) + 7) / 8;  // x * 8 / width == b
          const int lo = std::clamp(-(roi.x + d.x), x0, x1), hi = std::clamp(width - (roi.x + d.x), lo, x1);
          float sum = 0.f;
          auto add = [&](int x, int sx) {
            const int g = src[sx][1];
            const float v = table[g];
            dst[x] += sign * v;
            sum += v;
            saturated += g == code_max;
            code += g >> code_shift;
          };
          for (int x = x0; x < lo; ++x) add(x, 0);
          for (int x = lo; x < hi; ++x) add(x, roi.x + d.x + x);
          for (int x = hi; x < x1; ++x) add(x, width - 1);
          block[b] = sum;
        }
        std::copy(block, block + 8, row_block_sum_.begin() + static_cast<std::ptrdiff_t>(y) * 8);
        row_saturated_[y] = saturated;
        row_code_[y] = code;
      }
    });
  }

  cv::Rect roi_;
  cv::Size image_;
  const float* lut8_ = srgb::to_linear_table8();
  std::vector<double> row_block_sum_;
  std::vector<int> row_saturated_;
  std::vector<long long> row_code_;
};

/// A 16-bit frame (16-bit PNG/TIFF, 10-bit video) is kept as `deep` for the green sums and
/// replaced by its 8-bit rounding for everything else; an 8-bit frame gives an empty Mat.
cv::Mat deep_frame(cv::Mat& frame) {
  if (frame.depth() != CV_16U) return {};
  cv::Mat deep = frame;
  deep.convertTo(frame, CV_8U, 1.0 / 257.0);
  return deep;
}

/// Closes the registration's reference and puts the motions of the frames averaged into it,
/// measured again against the whole average, in their place (the first frames of `sums`; their
/// integer shifts stay as accumulated, the sub-pixel rest follows the new motion).
void revise_reference_frames(MotionRegistration& registration, CaptureSums& sums) {
  for (const auto& [frame, r] : registration.close_reference()) {
    if (!r.found || frame < 0 || static_cast<std::size_t>(frame) >= sums.motion.size()) continue;
    sums.motion[frame] = r.motion;
    sums.shift_px[frame] = r.motion.t;
    sums.patches_used[frame] = r.patches_used;
  }
}

/// Bounded memory: releases the sums of the chunks before chunk `open` (the one being summed;
/// the number of chunks once the read has ended) that are not to be kept
/// (CaptureReadOptions::keep_last_frames, keep_windows, max_sums_mb); `n`: frames read.
void release_chunks(CaptureSums& sums, const CaptureReadOptions& o, int n, int open) {
  const int c = o.chunk_frames;
  auto release = [&](int k) {
    sums.chunk_sum[k].release();
    if (o.colour) sums.chunk_blue[k].release();
    if (o.red) sums.chunk_red[k].release();
  };
  for (const int drop = o.keep_last_frames > 0 ? std::min(open, (n - o.keep_last_frames) / c) : 0; sums.released_chunks < drop;
       ++sums.released_chunks)
    release(sums.released_chunks);
  auto in_windows = [&](int k) {
    return std::any_of(o.keep_windows.begin(), o.keep_windows.end(),
                       [&](const FrameWindow& w) { return k * c < w.first + w.count && (k + 1) * c > w.first; });
  };
  if (open > 0 && !o.keep_windows.empty() && !in_windows(open - 1)) release(open - 1);
  if (o.max_sums_mb > 0 && !sums.sums_dropped) {
    double bytes = 0;
    for (int k = 0; k < std::min(open + 1, static_cast<int>(sums.chunk_sum.size())); ++k)
      bytes += static_cast<double>(sums.chunk_sum[k].total() * sums.chunk_sum[k].elemSize()) +
               (o.colour ? static_cast<double>(sums.chunk_blue[k].total() * sums.chunk_blue[k].elemSize()) : 0.0) +
               (o.red ? static_cast<double>(sums.chunk_red[k].total() * sums.chunk_red[k].elemSize()) : 0.0);
    if (bytes > o.max_sums_mb * 1048576.0) {
      sums.sums_dropped = true;
      for (int k = 0; k < open; ++k) release(k);
    }
  }
  if (sums.sums_dropped && open > 0) release(open - 1);
}

/// The sums of a capture before its first frame: its description, checked against the camera's
/// imager, and the roi inside its image.
CaptureSums empty_sums(const CaptureInfo& info, const std::filesystem::path& source, const CaptureReadOptions& options) {
  CaptureSums sums;
  sums.info = info;
  if (options.expected_width > 0 && (info.width != options.expected_width || info.height != options.expected_height))
    throw InputError(source.string(), "frame size",
                     std::to_string(info.width) + "x" + std::to_string(info.height) + " does not match the camera's imager " +
                         std::to_string(options.expected_width) + "x" + std::to_string(options.expected_height),
                     "use the captures filmed with the calibrated camera at its full resolution");
  const cv::Rect image(0, 0, info.width, info.height);
  sums.roi = options.roi.area() > 0 ? (options.roi & image) : image;
  if (sums.roi.area() == 0) throw std::invalid_argument("read_capture: the roi lies outside the image");
  sums.chunk_frames = options.chunk_frames;
  return sums;
}

/// The shared first registration reference (made on the first read, checked on the others), or
/// nullptr without motion registration.
MotionRegistration* first_registration(const CaptureReadOptions& options, MotionReference& reference, cv::Size image,
                                       const cv::Rect& roi) {
  // Registration: a grid of patches over the roi, against the first baseline frame (registration.hpp).
  if (options.register_motion) {
    if (!reference.registration)
      reference.registration = std::make_shared<MotionRegistration>(image, roi, options.registration,
                                                                   options.seen.size() == roi.size() ? options.seen : cv::Mat());
    else if (reference.registration->roi() != roi || reference.registration->image() != image)
      throw std::invalid_argument("read_capture: the motion reference was taken with another roi or image size");
  }
  return options.register_motion ? reference.registration.get() : nullptr;
}

/// The pixels a read converts (FrameReader::set_region): the roi where every integer shift up to the
/// motion limit puts it (the sums, the statistics, on_frame), and the registration's support.
cv::Rect read_region(const cv::Rect& roi, const MotionRegistration* registration, double max_motion_px, cv::Size image) {
  const int reach = static_cast<int>(std::ceil(max_motion_px)) + 2;
  cv::Rect region(roi.x - reach, roi.y - reach, roi.width + 2 * reach, roi.height + 2 * reach);
  if (registration) region |= registration->support(max_motion_px);
  return region & cv::Rect(0, 0, image.width, image.height);
}

}  // namespace

CaptureSums read_capture(const std::filesystem::path& source, const CaptureReadOptions& options,
                         MotionReference& reference) {
  if (options.chunk_frames < 1) throw std::invalid_argument("read_capture: chunk_frames must be >= 1");
  options.registration.validate();
  FrameReader reader(source);
  CaptureSums sums = empty_sums(reader.info(), source, options);
  const CaptureInfo& info = sums.info;
  const std::string role = options.role.empty() ? "capture" : options.role;
  const cv::Rect roi = sums.roi;
  const int min_side = MotionRegistration::min_image_side(options.registration);
  if (options.register_motion && std::min(info.width, info.height) < min_side)
    throw InputError(source, "frame size",
                     std::to_string(info.width) + "x" + std::to_string(info.height) + " is too small to measure motion in (at least " +
                         std::to_string(min_side) + " px on each side)",
                     "film the captures with a camera of at least " + std::to_string(min_side) + " x " + std::to_string(min_side) + " px");
  MotionRegistration* const first_reference = first_registration(options, reference, cv::Size(info.width, info.height), roi);
  References refs(first_reference, options, cv::Size(info.width, info.height), roi);
  const Vec2 roi_centre(roi.x + 0.5 * roi.width, roi.y + 0.5 * roi.height);
  reader.set_region(read_region(roi, first_reference, options.max_motion_px, cv::Size(info.width, info.height)));
  std::optional<FrameQueue> frames(std::in_place, reader);
  FrameQueue& queue = *frames;
  cv::Mat frame;
  std::string name;
  int n = 0;
  GreenSums green(roi, cv::Size(info.width, info.height));
  for (;;) {
    const auto t_wait = Clock::now();
    if (!queue.pop(frame, name)) break;
    sums.read_ms += ms_since(t_wait);
    const auto t_work = Clock::now();
    const cv::Mat deep = deep_frame(frame);  // 16-bit frames: the green sums read every bit, the rest 8 bits
    // Motion: content displacement of this frame against the reference, measured (on a task
    // of its own) while the frame is accumulated at the previous frame's integer shift;
    // in the rare frame whose integer shift changes, the frame is moved afterwards.
    const cv::Point d_prev = sums.applied_shift.empty() ? cv::Point(0, 0) : sums.applied_shift.back();
    Similarity motion;
    motion.centre = roi_centre;
    int patches_used = 0;
    tbb::task_group registration;
    MotionRegistration* const registration_of = refs.current();
    // The first frames (registration.hpp: reference_frames) are averaged into the reference as they come.
    const bool building = registration_of && registration_of->reference_open();
    if (registration_of) {
      // Started from the previous frame's motion.
      const Similarity start = sums.motion.empty() ? motion : sums.motion.back();
      registration.run([&motion, &patches_used, registration_of, &frame, start, building] {
        const RegistrationResult r = building ? registration_of->add_to_reference(frame, start) : registration_of->measure(frame, start);
        // Every patch left out for glare, or skin without texture: the frame cannot say how it moved; it keeps
        // the previous frame's motion (the glare check refuses a capture that is mostly glare, and a skin
        // without texture leaves nothing to place the phases by either).
        const bool all_glare = !r.found && !r.glare.empty() &&
                               std::all_of(r.glare.begin(), r.glare.end(), [](std::uint8_t g) { return g != 0; });
        motion = all_glare || (!r.found && r.no_texture) ? start : r.motion;
        patches_used = r.patches_used;
      });
    }
    const int chunk = n / options.chunk_frames;
    if (chunk >= static_cast<int>(sums.chunk_sum.size())) {
      sums.chunk_sum.emplace_back(cv::Mat::zeros(roi.size(), CV_32F));
      if (options.colour) sums.chunk_blue.emplace_back(cv::Mat::zeros(half_grid(roi.size()), CV_32F));
      if (options.red) sums.chunk_red.emplace_back(cv::Mat::zeros(roi.size(), CV_32F));
      sums.chunk_count.push_back(0);
      release_chunks(sums, options, n, chunk);
    }
    cv::Mat& acc = sums.chunk_sum[chunk];
    auto accumulate = [&](cv::Point d, float sign, bool stats) { green.accumulate(frame, deep, acc, d, sign, stats); };
    accumulate(d_prev, 1.f, true);
    registration.wait();
    auto moved_by = [&roi](const Similarity& m) {
      return m.t.allFinite() ? m.max_displacement(roi) : std::numeric_limits<double>::quiet_NaN();
    };
    double moved = moved_by(motion);
    if ((!std::isfinite(moved) || moved > options.max_motion_px) && !sums.motion.empty() &&
        refs.change(frame, sums.motion.back(), motion, patches_used))
      moved = moved_by(motion);
    refs.measured(motion);
    const Vec2 shift = motion.t;
    if (!std::isfinite(moved) || moved > options.max_motion_px)
      throw InputError(source.string(), name,
                       "moved " + (std::isfinite(moved) ? fmt(moved, 1) + " px" : std::string("beyond recognition")) +
                           " against the first baseline frame, more than the " + fmt(options.max_motion_px, 1) +
                           " px clearfit compensates",
                       "hold the part and the skin still while filming (a fixture helps), or raise "
                       "captures.max_motion_px if the motion is a steady drift");
    // Integer part undone while accumulating, with hysteresis: frames jittering around one
    // position keep one integer shift, so the sub-pixel residuals stay as tight as the jitter.
    cv::Point d = d_prev;
    if (std::abs(shift.x() - d.x) > 0.75) d.x = static_cast<int>(std::lround(shift.x()));
    if (std::abs(shift.y() - d.y) > 0.75) d.y = static_cast<int>(std::lround(shift.y()));
    if (d != d_prev) {
      accumulate(d_prev, -1.f, false);
      accumulate(d, 1.f, false);
    }
    if (options.colour) accumulate_half_blue(frame, roi, d, sums.chunk_blue[chunk]);
    if (options.red) accumulate_red(frame, roi, d, sums.chunk_red[chunk]);
    ++sums.chunk_count[chunk];
    if (options.on_frame) options.on_frame(frame, d);
    green.append_statistics(sums);
    sums.shift_px.push_back(shift);
    sums.motion.push_back(motion);
    sums.patches_used.push_back(patches_used);
    sums.applied_shift.push_back(d);
    sums.reference.push_back(refs.index());
    if (building && registration_of == first_reference && !registration_of->reference_open()) revise_reference_frames(*registration_of, sums);
    sums.work_ms += ms_since(t_work);
    ++n;
    if (options.progress) options.progress(n, info.frames);
    queue.recycle(std::move(frame));  // its buffer decodes a later one
  }
  frames.reset();  // the decoding thread ends: the reader's last frame is `last`, converted whole for pictures
  sums.last_frame = reader.whole_last_frame();
  deep_frame(sums.last_frame);
  if (n == 0) throw InputError(source.string(), "", "holds no frames", "check the " + role + " capture");
  release_chunks(sums, options, n, static_cast<int>(sums.chunk_sum.size()));  // the last chunk too
  // A capture shorter than the reference's frames: the reference is what it holds.
  if (first_reference && first_reference->has_reference() && first_reference->reference_open())
    revise_reference_frames(*first_reference, sums);
  sums.info.frames = n;
  return sums;
}

FrameWindow last_frames(const CaptureSums& sums, int window_frames) {
  const int n = sums.info.frames;
  return {std::max(0, n - window_frames), std::min(window_frames, n)};
}

PhaseAverage average_window(const CaptureSums& sums, FrameWindow window, int min_frames, bool normalise_gains) {
  const int c = sums.chunk_frames;
  const int n = static_cast<int>(sums.shift_px.size());
  // Whole chunks: the start rounds down to its chunk (at most chunk_frames - 1 frames earlier),
  // the end rounds down too; a final partial chunk counts when the capture ends there.
  int first_chunk = std::max(0, window.first) / c;
  int end_frame = std::min(window.first + window.count, n);
  int end_chunk = end_frame == n ? static_cast<int>(sums.chunk_sum.size()) : end_frame / c;
  PhaseAverage avg;
  avg.roi = sums.roi;
  avg.window.first = first_chunk * c;
  avg.window.count = 0;
  for (int k = first_chunk; k < end_chunk; ++k) avg.window.count += sums.chunk_count[k];
  const std::string role = sums.info.source.filename().string();
  if (avg.window.count < std::max(1, min_frames))
    throw InputError(sums.info.source.string(), "frames " + std::to_string(window.first) + ".." +
                                                    std::to_string(window.first + window.count - 1),
                     "the averaging window holds " + std::to_string(avg.window.count) + " usable frames, fewer than the " +
                         std::to_string(min_frames) + " asked for (the capture has " + std::to_string(n) + " frames)",
                     "film longer, or lower captures.window_frames");
  if (sums.sums_dropped || std::any_of(sums.chunk_sum.begin() + first_chunk, sums.chunk_sum.begin() + std::max(first_chunk, end_chunk),
                                       [](const cv::Mat& m) { return m.empty(); }))
    throw InputError(sums.info.source.string(), "frames " + std::to_string(window.first) + ".." + std::to_string(window.first + window.count - 1),
                     "the averaging window reaches frames whose sums were not kept (bounded memory: " +
                         std::string(sums.sums_dropped ? "the sums outgrew captures.max_mb" : "only the last frames or the windows asked for were kept") +
                         ")",
                     "average the frames kept, or read the capture again keeping this window");
  // Mean of the chunks, each divided by its gain (exposure, white balance, flicker: photometric.hpp).
  const int chunks = end_chunk - first_chunk;
  auto gain_normalised_mean = [&](const std::vector<cv::Mat>& chunk_sums, std::vector<double>& gains) {
    cv::Mat mean = cv::Mat::zeros(chunk_sums[first_chunk].size(), CV_32F);
    for (int k = first_chunk; k < end_chunk; ++k) mean += chunk_sums[k];
    mean /= avg.window.count;
    gains.assign(chunks, 1.0);
    if (!normalise_gains || chunks < 2) return mean;
    const ChunkGains g = estimate_chunk_gains(chunk_sums, sums.chunk_count, first_chunk, end_chunk, mean);
    gains = g.gain;
    if (&chunk_sums == &sums.chunk_sum) avg.gain_min = g.min, avg.gain_max = g.max, avg.gain_sigma = g.sigma;
    mean.setTo(0);
    for (int k = first_chunk; k < end_chunk; ++k) cv::scaleAdd(chunk_sums[k], 1.0 / gains[k - first_chunk], mean, mean);
    mean /= avg.window.count;
    return mean;
  };
  std::vector<double> gains, blue_gains, red_gains;
  avg.mean = gain_normalised_mean(sums.chunk_sum, gains);
  if (!sums.chunk_blue.empty()) avg.blue_half = gain_normalised_mean(sums.chunk_blue, blue_gains);
  if (!sums.chunk_red.empty()) avg.red = gain_normalised_mean(sums.chunk_red, red_gains);
  // Variance of the mean from the spread of the gain-normalised chunk means (equal-size chunks).
  avg.variance = cv::Mat::zeros(sums.roi.size(), CV_32F);
  if (chunks >= 3) {
    cv::Mat diff;
    for (int k = first_chunk; k < end_chunk; ++k) {
      diff = sums.chunk_sum[k] / (sums.chunk_count[k] * gains[k - first_chunk]) - avg.mean;
      avg.variance += diff.mul(diff);
    }
    avg.variance /= static_cast<double>(chunks) * (chunks - 1);
  }
  Vec2 residual = Vec2::Zero();
  double sat = 0, code = 0;
  const int f0 = avg.window.first, f1 = avg.window.first + avg.window.count;
  for (int f = f0; f < f1; ++f) {
    residual += sums.shift_px[f] - Vec2(sums.applied_shift[f].x, sums.applied_shift[f].y);
    Similarity m;  // the whole motion; a translation when only shifts are known
    if (static_cast<std::size_t>(f) < sums.motion.size()) m = sums.motion[f];
    else m.t = sums.shift_px[f];
    avg.motion_px_max = std::max(avg.motion_px_max, m.max_displacement(sums.roi));
    avg.rotation_deg_max = std::max(avg.rotation_deg_max, std::abs(m.angle_rad()) * 180 / std::numbers::pi);
    avg.scale_change_max = std::max(avg.scale_change_max, std::abs(m.scale() - 1));
    Similarity turn = m;
    turn.t.setZero();
    avg.rotation_scale_px_max = std::max(avg.rotation_scale_px_max, turn.max_displacement(sums.roi));
    sat += sums.saturated_fraction[f];
    code += sums.mean_code[f];
  }
  const int m = f1 - f0;
  avg.residual_shift_px = residual / m;
  double jitter = 0;
  for (int f = f0; f < f1; ++f)
    jitter += (sums.shift_px[f] - Vec2(sums.applied_shift[f].x, sums.applied_shift[f].y) - avg.residual_shift_px).squaredNorm();
  avg.jitter_px_rms = std::sqrt(jitter / m);
  avg.saturated_fraction = sat / m;
  avg.mean_code = code / m;
  return avg;
}

PhaseSplit split_phases(const CaptureSums& sums, int window_frames) {
  const int n = static_cast<int>(sums.blocks.size());
  const std::string src = sums.info.source.string();
  if (n < 4)
    throw InputError(src, "", "has " + std::to_string(n) + " frames: too few to hold a baseline and a press",
                     "film the baseline (not worn) and then the press (worn), each longer than the averaging window");
  // Log block means, each scaled by its own frame-to-frame noise (robust: median absolute
  // difference of consecutive frames), so a press on a few blocks stands out of the noise.
  std::vector<Eigen::Matrix<double, 64, 1>> v(n);
  for (int t = 0; t < n; ++t)
    for (int k = 0; k < 64; ++k) v[t][k] = std::log(std::max(sums.blocks[t][k], 1e-6f));
  // Exposure, white balance and flicker change all blocks alike: each frame's median block
  // (the unpressed majority) is taken out, so a gain step is not read as the press.
  for (auto& frame : v) {
    Eigen::Matrix<double, 64, 1> sorted = frame;
    std::nth_element(sorted.data(), sorted.data() + 32, sorted.data() + 64);
    frame.array() -= sorted[32];
  }
  for (int k = 0; k < 64; ++k) {
    std::vector<double> d;
    for (int t = 1; t < n; ++t) d.push_back(std::abs(v[t][k] - v[t - 1][k]));
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    const double sigma = std::max(d[d.size() / 2] / (0.6745 * std::sqrt(2.0)), 1e-7);
    for (int t = 0; t < n; ++t) v[t][k] /= sigma;
  }
  // Two-segment least squares: the split that minimises the within-segment scatter.
  std::vector<Eigen::Matrix<double, 64, 1>> prefix(n + 1, Eigen::Matrix<double, 64, 1>::Zero());
  std::vector<double> prefix_sq(n + 1, 0);
  for (int t = 0; t < n; ++t) {
    prefix[t + 1] = prefix[t] + v[t];
    prefix_sq[t + 1] = prefix_sq[t] + v[t].squaredNorm();
  }
  auto sse = [&](int a, int b) {  // scatter of frames [a, b)
    const auto s = prefix[b] - prefix[a];
    return (prefix_sq[b] - prefix_sq[a]) - s.squaredNorm() / (b - a);
  };
  // Best split of frames [a, b) into two segments (at least 2 frames each): the split and its cost.
  auto best_split = [&](int a, int b) {
    std::pair<int, double> best{-1, std::numeric_limits<double>::infinity()};
    for (int t = a + 2; t <= b - 2; ++t) {
      const double cost = sse(a, t) + sse(t, b);
      if (cost < best.second) best = {t, cost};
    }
    return best;
  };
  auto mean_of = [&](int a, int b) -> Eigen::Matrix<double, 64, 1> { return (prefix[b] - prefix[a]) / (b - a); };
  const int best = best_split(0, n).first;
  // The part may be removed before the capture ends: a second step, back toward the baseline.
  // Binary segmentation: the best further split on either side of the first; it is the removal
  // when the middle segment stands out of the first (8 σ, as the press) and the last one lies
  // back toward the first by 10 % of the press (at least 3 σ; a press's own rise goes the other way).
  int press_cut = best, release_cut = -1;
  double release_gain = 0;
  // The last frame on the worn plateau before `r` (the split may fall inside a slow refill): the
  // plateau is the 90th percentile of the progress along the press over [p, r); frames below it
  // by 10 % (at least 3 σ) at the end are refill.
  auto plateau_end = [&](int p, int r) {
    const Eigen::Matrix<double, 64, 1> ma = mean_of(0, p), d = (mean_of(p, r) - ma).normalized();
    std::vector<double> on;
    for (int t = p; t < r; ++t) on.push_back((v[t] - ma).dot(d));
    std::nth_element(on.begin(), on.begin() + on.size() * 9 / 10, on.end());
    const double plateau = on[on.size() * 9 / 10], margin = std::max(0.1 * plateau, 3.0);
    while (r > p + 4 && (v[r - 1] - ma).dot(d) < plateau - margin) --r;
    return r;
  };
  for (int side = 0; side < 2; ++side) {
    const int a = side == 0 ? 0 : best, b = side == 0 ? best : n;
    const auto [t, cost] = best_split(a, b);
    if (t < 0) continue;
    const int p = side == 0 ? t : best;
    if ((side == 0 ? best : t) - p < 4) continue;
    const int r = plateau_end(p, side == 0 ? best : t);
    const Eigen::Matrix<double, 64, 1> ma = mean_of(0, p), mb = mean_of(p, r), mc = mean_of(r, n);
    const double press_step = (mb - ma).norm(), drop = (mb - mc).dot(mb - ma) / press_step;
    if ((mb - ma).cwiseAbs().maxCoeff() < 8 || drop < std::max(0.1 * press_step, 3.0)) continue;
    const double gain = sse(a, b) - cost;
    if (gain > release_gain) release_gain = gain, press_cut = p, release_cut = r;
  }
  const int worn_end = release_cut < 0 ? n : release_cut;
  const Eigen::Matrix<double, 64, 1> before = mean_of(0, press_cut);
  const int tail = std::max(1, std::min(20, (worn_end - press_cut) / 4));
  const Eigen::Matrix<double, 64, 1> final_state = mean_of(worn_end - tail, worn_end);
  PhaseSplit split;
  split.step_sigmas = (final_state - before).cwiseAbs().maxCoeff();  // in units of each block's noise
  if (split.step_sigmas < 8)
    throw InputError(src, "", "shows no press: the image does not change between a baseline and a worn phase (largest block step " +
                                  fmt(split.step_sigmas, 1) + " sigma of its frame noise, 8 needed)",
                     "give one video holding the baseline then the press, or give captures.baseline and captures.worn");
  // Progress along the step, per frame: 0 at the baseline, `step` when settled; the
  // projection has unit noise (whitened blocks). The press starts at the first frame that
  // has left the baseline by 10 % of the step (at least 3 σ); it has settled within the same.
  // The removal is the first frame that has left the settled state by as much.
  const double step = (final_state - before).norm();
  const Eigen::Matrix<double, 64, 1> dir = (final_state - before) / step;
  auto progress = [&](int t) { return (v[t] - before).dot(dir); };
  const double tol = std::max(0.1 * step, 3.0);
  int press = press_cut;
  while (press > 1 && progress(press - 1) > tol) --press;
  int settled = press_cut;
  while (settled < worn_end - 1 && std::abs(progress(settled) - step) > tol) ++settled;
  int release = release_cut;
  if (release_cut >= 0)
    while (release > settled + 1 && progress(release - 1) < step - tol) --release;
  split.release_frame = release;
  split.press_frame = press;
  split.settled_frame = std::min(settled, worn_end - 1);
  const int margin = std::max(2, sums.chunk_frames);
  const int base_end = press - margin;
  split.baseline = {std::max(0, base_end - window_frames), std::min(window_frames, std::max(0, base_end))};
  const int worn_stop = release < 0 ? n : std::max(split.settled_frame, release - margin);
  split.worn = {std::max(split.settled_frame, worn_stop - window_frames), worn_stop - std::max(split.settled_frame, worn_stop - window_frames)};
  return split;
}

}  // namespace clearfit
