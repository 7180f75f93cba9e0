// Calibration sessions, the image side (session_presses.hpp): the indenter
// found in the video, the clocks aligned, each press's signal field under it.
#include <clearfit/error.hpp>
#include <clearfit/fit/frame_reader.hpp>
#include <clearfit/fit/session_presses.hpp>
#include <clearfit/fit/srgb.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace clearfit {
namespace {

struct Video {
  std::vector<cv::Mat> green;  // CV_8U per frame
  double fps = 0;
  int width = 0, height = 0;
};

Video read_green(const std::filesystem::path& path, double fps_override) {
  FrameReader reader(path);
  Video v;
  cv::Mat bgr, g;
  while (reader.read(bgr)) {
    cv::extractChannel(bgr, g, 1);
    v.green.push_back(g.clone());
  }
  v.fps = fps_override > 0 ? fps_override : reader.info().fps;
  v.width = reader.info().width;
  v.height = reader.info().height;
  if (!(v.fps > 0))
    throw InputError(path.string(), "frame rate", "is unknown (a folder of frames)", "give it with --fps");
  if (v.green.size() < 20) throw InputError(path.string(), "", "holds " + std::to_string(v.green.size()) + " frames; a session needs many more");
  return v;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Mean linear green of the pixels where mask != 0, per frame.
std::vector<double> masked_trace(const Video& v, const cv::Mat& mask) {
  const float* lin = srgb::to_linear_table8();
  std::vector<int> idx;
  for (int i = 0; i < mask.rows * mask.cols; ++i)
    if (mask.data[i]) idx.push_back(i);
  std::vector<double> out(v.green.size(), NAN);
  if (idx.empty()) return out;
  for (std::size_t f = 0; f < v.green.size(); ++f) {
    double s = 0;
    for (int i : idx) s += lin[v.green[f].data[i]];
    out[f] = s / double(idx.size());
  }
  return out;
}

/// y(t) = ln(G/G̃) − ln(G_ref/G̃_ref) of two traces.
std::vector<double> relative_signal(const std::vector<double>& area, const std::vector<double>& ref) {
  const double ma = median(area), mr = median(ref);
  std::vector<double> y(area.size());
  for (std::size_t i = 0; i < y.size(); ++i) y[i] = std::log(area[i] / ma) - std::log(ref[i] / mr);
  return y;
}

/// The block whose relative green varies most: the coarse indenter centre (px).
Eigen::Vector2d find_indenter_blocks(const Video& v, int block) {
  const int bw = v.width / block, bh = v.height / block, nb = bw * bh;
  const float* lin = srgb::to_linear_table8();
  std::vector<std::vector<double>> traces(nb, std::vector<double>(v.green.size()));
  for (std::size_t f = 0; f < v.green.size(); ++f) {
    std::vector<double> sum(nb, 0.0);
    for (int y = 0; y < bh * block; ++y) {
      const unsigned char* row = v.green[f].ptr<unsigned char>(y);
      for (int x = 0; x < bw * block; ++x) sum[(y / block) * bw + x / block] += lin[row[x]];
    }
    for (int b = 0; b < nb; ++b) traces[b][f] = std::log(std::max(sum[b], 1e-9));
  }
  std::vector<double> common(v.green.size());
  for (std::size_t f = 0; f < v.green.size(); ++f) {
    std::vector<double> col(nb);
    for (int b = 0; b < nb; ++b) col[b] = traces[b][f];
    common[f] = median(col);
  }
  std::vector<double> score(nb);
  for (int b = 0; b < nb; ++b) {
    double s = 0, ss = 0;
    for (std::size_t f = 0; f < common.size(); ++f) {
      const double d = traces[b][f] - common[f];
      s += d, ss += d * d;
    }
    const double n = double(common.size());
    score[b] = ss / n - (s / n) * (s / n);
  }
  const double top = *std::max_element(score.begin(), score.end());
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  double w = 0;
  for (int b = 0; b < nb; ++b)
    if (score[b] > 0.5 * top) {
      c += score[b] * Eigen::Vector2d((b % bw + 0.5) * block - 0.5, (b / bw + 0.5) * block - 0.5);
      w += score[b];
    }
  return c / w;
}

/// Frame index range [first, last] of video times [a, b]; empty (first > last) when outside.
std::pair<int, int> frames_between(double a, double b, double fps, int frames) {
  return {std::max(0, static_cast<int>(std::ceil(a * fps))), std::min(frames - 1, static_cast<int>(std::floor(b * fps)))};
}

/// Mean linear green image over frames [first, last], and the fraction of `mask` pixels clipped (0 or 255).
cv::Mat mean_image(const Video& v, std::pair<int, int> range, const cv::Mat& mask, double& clipped) {
  const float* lin = srgb::to_linear_table8();
  cv::Mat sum = cv::Mat::zeros(v.height, v.width, CV_64F);
  long bad = 0, seen = 0;
  for (int f = range.first; f <= range.second; ++f) {
    const unsigned char* g = v.green[f].data;
    auto* s = sum.ptr<double>();
    for (int i = 0; i < v.width * v.height; ++i) {
      s[i] += lin[g[i]];
      if (mask.data[i]) ++seen, bad += (g[i] == 0 || g[i] == 255);
    }
  }
  clipped = seen ? double(bad) / double(seen) : 0;
  return sum / std::max(1, range.second - range.first + 1);
}


/// Line of the force log's sample nearest gauge time t.
int log_line_at(const ForceLog& log, double t) {
  const auto it = std::lower_bound(log.time_s.begin(), log.time_s.end(), t);
  return log.line[std::min<std::size_t>(static_cast<std::size_t>(it - log.time_s.begin()), log.line.size() - 1)];
}

/// Per press: y = ln(hold/rest) per pixel (CV_32F), frames outside the recording refused, clipping refused.
std::vector<cv::Mat> press_images(SessionAnalysis& out, const Video& v, const ForceLog& log,
                                  const std::vector<ForcePress>& presses, const cv::Mat& disc) {
  std::vector<cv::Mat> images;
  const double video_end = double(v.green.size() - 1) / v.fps;
  for (std::size_t k = 0; k < presses.size(); ++k) {
    const ForcePress& p = presses[k];
    SessionPress sp;
    sp.force = p;
    {  // the force against this press's own rest (the gauge's rest reading drifts over a session)
      std::vector<double> rest_force;
      for (std::size_t i = 0; i < log.time_s.size(); ++i)
        if (log.time_s[i] >= p.rest_start_s && log.time_s[i] <= p.rest_end_s) rest_force.push_back(log.force_n[i]);
      if (!rest_force.empty()) sp.force.force_n = p.force_n - median(rest_force);
    }
    sp.log_line = log_line_at(log, p.start_s);
    sp.hold_start_s = out.clock.to_video(p.hold_start_s), sp.hold_end_s = out.clock.to_video(p.hold_end_s);
    sp.rest_start_s = out.clock.to_video(p.rest_start_s), sp.rest_end_s = out.clock.to_video(p.rest_end_s);
    if (sp.rest_start_s < 0 || sp.hold_end_s > video_end)
      throw InputError(out.force_log.string(), "line " + std::to_string(sp.log_line),
                       "press " + std::to_string(k + 1) + " (gauge " + std::to_string(p.start_s) + " s, video " +
                           std::to_string(out.clock.to_video(p.start_s)) + " s) lies outside the recording (0 to " +
                           std::to_string(video_end) + " s of " + out.video.string() + ")",
                       "the recording is shorter than the force log: record the whole session, or cut the log to the recording");
    const auto hold = frames_between(sp.hold_start_s, sp.hold_end_s, v.fps, out.frames);
    const auto rest = frames_between(sp.rest_start_s, sp.rest_end_s, v.fps, out.frames);
    sp.hold_frames = hold.second - hold.first + 1, sp.rest_frames = rest.second - rest.first + 1;
    if (sp.hold_frames < 1 || sp.rest_frames < 1)
      throw InputError(out.video.string(), "press " + std::to_string(k + 1), "its hold (video " + std::to_string(sp.hold_start_s) + "-" + std::to_string(sp.hold_end_s) + " s) or rest (" + std::to_string(sp.rest_start_s) + "-" + std::to_string(sp.rest_end_s) + " s) holds no frame", "record at a higher frame rate");
    double clipped_hold = 0, clipped_rest = 0;
    const cv::Mat h = mean_image(v, hold, disc, clipped_hold), r = mean_image(v, rest, disc, clipped_rest);
    if (std::max(clipped_hold, clipped_rest) > 0.01)
      throw InputError(out.video.string(), "press " + std::to_string(k + 1) + ", frames " + std::to_string(rest.first) + "-" +
                       std::to_string(hold.second), std::to_string(100 * std::max(clipped_hold, clipped_rest)).substr(0, 5) +
                       " % of the indenter area's pixels are at 0 or 255 (saturated or over-exposed)",
                       "lower the exposure or the light and record again");
    cv::Mat y;
    cv::log(cv::max(h, 1e-6) / cv::max(r, 1e-6), y);
    y.convertTo(y, CV_32F);
    images.push_back(y);
    out.presses.push_back(sp);
    if (sp.hold_frames < 5) out.warnings.push_back("press " + std::to_string(k + 1) + ": only " + std::to_string(sp.hold_frames) + " settled frames");
  }
  return images;
}

/// The centroid (skin mm) of the blanching within a + 1 mm of c, three times.
Eigen::Vector2d refine_centre(const cv::Mat& blanching, const cv::Mat& sx, const cv::Mat& sy, Eigen::Vector2d c, double a) {
  for (int it = 0; it < 4; ++it) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    double w = 0;
    for (int i = 0; i < blanching.rows * blanching.cols; ++i) {
      const Eigen::Vector2d p(sx.at<double>(i), sy.at<double>(i));
      const double b = blanching.at<float>(i);
      if ((p - c).norm() < a + 1 && b > 0) sum += b * p, w += b;
    }
    if (w > 0) c = sum / w;
  }
  return c;
}

}  // namespace

void SessionOptions::validate() const {
  if (!(indenter_radius_mm > 0 && indenter_radius_mm < 50))
    throw InputError("", "--indenter-radius-mm", "expected the indenter's radius in mm (> 0)");
  optics.validate();
  if (!(fps >= 0)) throw InputError("", "--fps", "must be > 0");
  if (!(ring_mm > 0.01 && ring_mm <= indenter_radius_mm)) throw InputError("", "--ring-mm", "from 0.01 mm to the indenter radius");
  segmentation.validate();
  alignment.validate();
}

SessionAnalysis analyse_session(const std::filesystem::path& video_path, const std::filesystem::path& log_path,
                                const CameraModel& camera, const SessionOptions& o) {
  o.validate();
  SessionAnalysis out;
  out.video = video_path, out.force_log = log_path;
  const ForceLog log = read_force_log(log_path);
  out.tare_n = log.tare_n;
  out.notes = log.notes;
  const std::vector<ForcePress> presses = find_presses(log, o.segmentation);
  if (presses.size() < 4)
    throw InputError(log_path.string(), "line " + std::to_string(log.line.back()),
                     "holds " + std::to_string(presses.size()) + " presses; the calibration has 3 parameters and needs at least 4",
                     "record 12-16 presses at forces spread over the range");
  const Video v = read_green(video_path, o.fps);
  out.fps = v.fps, out.frames = static_cast<int>(v.green.size()), out.width = v.width, out.height = v.height;
  if (v.width != camera.width || v.height != camera.height)
    throw InputError(video_path.string(), "frame 0", "is " + std::to_string(v.width) + " x " + std::to_string(v.height) +
                     " px; the camera model is " + std::to_string(camera.width) + " x " + std::to_string(camera.height),
                     "give the camera model the video was recorded with");
  // Every pixel's skin point (mm).
  cv::Mat skin_x(v.height, v.width, CV_64F), skin_y(v.height, v.width, CV_64F);
  for (int y = 0; y < v.height; ++y)
    for (int x = 0; x < v.width; ++x) {
      const Eigen::Vector2d p = o.optics.skin_point(camera.unproject(Vec2(x, y)));
      skin_x.at<double>(y, x) = p.x(), skin_y.at<double>(y, x) = p.y();
    }
  auto skin_at = [&](const Eigen::Vector2d& px) { return o.optics.skin_point(camera.unproject(Vec2(px.x(), px.y()))); };
  const double a = o.indenter_radius_mm;
  auto masks = [&](const Eigen::Vector2d& c, cv::Mat& disc, cv::Mat& ref, cv::Mat& radius) {
    disc = cv::Mat::zeros(v.height, v.width, CV_8U), ref = disc.clone(), radius.create(v.height, v.width, CV_64F);
    for (int i = 0; i < v.width * v.height; ++i) {
      const double r = std::hypot(skin_x.at<double>(i) - c.x(), skin_y.at<double>(i) - c.y());
      radius.at<double>(i) = r;
      disc.data[i] = r < a;
      ref.data[i] = r > a + 2 && r < a + 4;
    }
    if (cv::countNonZero(disc) < 5 || cv::countNonZero(ref) < 20)
      throw InputError(video_path.string(), "indenter at (" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ") mm",
                       "its disc or the reference ring 2-4 mm beyond its rim falls outside the image",
                       "frame the indenter with 4 mm of skin around it, or check --centre-px and --distance-mm");
  };
  out.centre_found = !o.centre_px;
  out.centre_px = o.centre_px ? *o.centre_px : find_indenter_blocks(v, o.block_px);
  out.centre_mm = skin_at(out.centre_px);
  cv::Mat disc, ref, radius;
  masks(out.centre_mm, disc, ref, radius);
  out.time_s.resize(v.green.size());
  for (std::size_t f = 0; f < v.green.size(); ++f) out.time_s[f] = double(f) / v.fps;
  out.trace = relative_signal(masked_trace(v, disc), masked_trace(v, ref));
  out.clock = align_clocks(log, presses, out.time_s, out.trace, o.alignment);
  std::vector<cv::Mat> y = press_images(out, v, log, presses, disc);
  out.blanching = cv::Mat::zeros(v.height, v.width, CV_32F);
  for (const cv::Mat& m : y) out.blanching += m;
  if (out.centre_found) {
    out.centre_mm = refine_centre(out.blanching, skin_x, skin_y, out.centre_mm, a);
    masks(out.centre_mm, disc, ref, radius);
    cv::Point at;
    cv::minMaxLoc(radius, nullptr, nullptr, &at, nullptr);
    out.centre_px = Eigen::Vector2d(at.x, at.y);
    out.trace = relative_signal(masked_trace(v, disc), masked_trace(v, ref));
  }
  out.mm_per_px = (skin_at(out.centre_px + Eigen::Vector2d(1, 0)) - skin_at(out.centre_px)).norm();
  for (double e = 0; e < a + o.profile_margin_mm + 1e-9; e += o.ring_mm) out.ring_edges_mm.push_back(e);
  const std::size_t rings = out.ring_edges_mm.size() - 1;
  for (std::size_t k = 0; k < y.size(); ++k) {
    const double y_ref = cv::mean(y[k], ref)[0];
    std::vector<double> sum(rings, 0.0), count(rings, 0.0);
    double disc_sum = 0, disc_n = 0;
    for (int i = 0; i < v.width * v.height; ++i) {
      const double r = radius.at<double>(i), val = y[k].at<float>(i) - y_ref;
      if (r < a) disc_sum += val, disc_n += 1;
      const auto ring = static_cast<std::size_t>(r / o.ring_mm);
      if (ring < rings) sum[ring] += val, count[ring] += 1;
    }
    SessionPress& sp = out.presses[k];
    sp.signal = disc_sum / disc_n;
    for (std::size_t j = 0; j < rings; ++j) sp.ring_signal.push_back(count[j] > 0 ? sum[j] / count[j] : NAN);
  }
  for (std::size_t i = 0; i < log.time_s.size(); ++i) {
    out.force_time_s.push_back(out.clock.to_video(log.time_s[i]));
    out.force_n.push_back(log.force_n[i]);
  }
  if (out.mm_per_px > o.ring_mm) out.warnings.push_back("a pixel spans " + std::to_string(out.mm_per_px) + " mm on the skin, more than a ring (" + std::to_string(o.ring_mm) + " mm)");
  if (out.clock.offset_sigma_s > 0.05) out.warnings.push_back("the clock offset is uncertain: sigma " + std::to_string(out.clock.offset_sigma_s) + " s");
  return out;
}

}  // namespace clearfit
