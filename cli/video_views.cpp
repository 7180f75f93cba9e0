// Videos as inputs of detect, calibrate and pose (video_views.hpp).
#include <clearfit/cli/video_views.hpp>

#include <clearfit/camera/detect.hpp>
#include <clearfit/error.hpp>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <unistd.h>

namespace clearfit::cli {
namespace fs = std::filesystem;

namespace {

bool is_image_path(const fs::path& p) {
  static const std::set<std::string> exts{".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"};
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return exts.count(ext) > 0;
}

/// Why no frame of the video was kept, and what to do.
[[noreturn]] void nothing_kept(const VideoViews& v, const std::string& thing) {
  const int n = v.frames_read;
  const std::string src = v.source.string();
  if (v.selection.count(ViewVerdict::no_board) == n)
    throw InputError(src, "", "no " + thing + " found in any of its " + std::to_string(n) + " frames",
                     "film the " + thing + " in full view and in focus; check the board or layout file against the printed tags (family, ids)");
  throw InputError(src, "",
                   "no frame shows enough of the " + thing + ": " + std::to_string(v.selection.count(ViewVerdict::too_few_corners)) + " of " +
                       std::to_string(n) + " frames have too few corners, " + std::to_string(v.selection.count(ViewVerdict::no_board)) +
                       " none",
                   "film the whole " + thing + " (lower --min-corner-fraction to keep partial views)");
}

}  // namespace

ViewInputs split_view_inputs(const std::vector<std::string>& inputs) {
  ViewInputs out;
  std::vector<fs::path> images;
  for (const auto& in : inputs) {
    const fs::path p(in);
    if (fs::is_regular_file(p) && !is_image_path(p)) out.videos.push_back(p);
    else images.push_back(p);
  }
  if (!images.empty()) out.images = list_images(images);
  return out;
}

cv::Mat grey8(const cv::Mat& bgr) {
  cv::Mat eight = bgr;
  if (bgr.depth() == CV_16U) bgr.convertTo(eight, CV_8U, 1.0 / 257);
  cv::Mat grey;
  if (eight.channels() == 1) grey = eight;
  else cv::cvtColor(eight, grey, eight.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return grey;
}

ViewCandidate frame_candidate(const cv::Mat& grey, std::vector<Eigen::Vector3d> corners, int group) {
  ViewCandidate c;
  c.corners = std::move(corners);
  std::vector<std::vector<Eigen::Vector2d>> regions;
  if (group <= 0) {
    regions.emplace_back();
    for (const auto& p : c.corners)
      if (p.z() >= 0) regions.back().push_back(p.head<2>());
  } else {
    for (std::size_t k = 0; k + group <= c.corners.size(); k += group) {
      std::vector<Eigen::Vector2d> quad;
      for (int i = 0; i < group; ++i)
        if (c.corners[k + i].z() >= 0) quad.push_back(c.corners[k + i].head<2>());
      if (static_cast<int>(quad.size()) == group) regions.push_back(quad);
    }
  }
  if (regions.empty() || regions.front().size() < 3) {
    // Nothing found: the whole frame's blur tells a blurred board from none (select_views).
    const double w = grey.cols - 1, h = grey.rows - 1;
    regions = {{{0, 0}, {w, 0}, {w, h}, {0, h}}};
  }
  c.blur = measure_edge_blur(grey, regions);
  return c;
}

VideoViews read_video_views(const fs::path& video, const MeasureFrame& measure, const ViewSelectionOptions& options, bool distinct,
                            const std::string& thing) {
  options.validate();
  VideoViews v;
  v.source = video;
  v.options = options;
  FrameReader reader(video);
  v.info = reader.info();
  const std::size_t batch_size = 2 * static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  std::vector<ViewCandidate> candidates;
  std::vector<cv::Mat> batch;
  int with_thing = 0;
  auto last = std::chrono::steady_clock::now();
  const bool tty = ::isatty(2) != 0;
  const std::string total = v.info.frames > 0 ? " / ~" + std::to_string(v.info.frames) : "";
  auto flush = [&](bool end) {
    std::vector<ViewCandidate> out(batch.size());
    tbb::parallel_for(std::size_t(0), batch.size(), [&](std::size_t i) { out[i] = measure(batch[i]); });
    for (auto& c : out) {
      with_thing += std::any_of(c.corners.begin(), c.corners.end(), [](const Eigen::Vector3d& p) { return p.z() >= 0; });
      candidates.push_back(std::move(c));
    }
    batch.clear();
    const auto now = std::chrono::steady_clock::now();
    if (end || now - last > std::chrono::seconds(1)) {
      std::cerr << (tty ? "\r" : "") << video.string() << ": frame " << candidates.size() << total << ", " << thing << " in "
                << with_thing << (end || !tty ? "\n" : "") << std::flush;
      last = now;
    }
  };
  cv::Mat bgr;
  while (reader.read(bgr)) {
    batch.push_back(grey8(bgr));
    if (batch.size() == batch_size) flush(false);
  }
  flush(true);
  v.frames_read = static_cast<int>(candidates.size());
  if (v.frames_read == 0) throw InputError(video.string(), "", "holds no frames", "give a video with the " + thing + " in view");
  v.selection = select_views(candidates, v.info.width, v.info.height, options, distinct);
  for (auto& c : candidates) c.corners.clear();  // the widths stay for the report
  v.candidates = std::move(candidates);
  const std::vector<int> used = v.selection.used();
  if (used.empty()) nothing_kept(v, thing);
  // The kept frames' pixels: the video read again (keeping every frame would not fit in memory).
  FrameReader again(video);
  std::size_t u = 0;
  for (int index = 0; u < used.size() && again.read(bgr); ++index) {
    if (index != used[u]) continue;
    v.frames.push_back(index);
    v.names.push_back(video.string() + "#" + std::to_string(index));
    v.images.push_back(grey8(bgr));
    ++u;
  }
  if (u < used.size())
    throw InputError(video.string(), "", "gave fewer frames when read a second time (" + std::to_string(u) + " of " + std::to_string(used.size()) + ")",
                     "convert the video to a format that decodes the same every time, or extract its frames to a folder");
  return v;
}

VideoViews read_board_video(const fs::path& video, const Board& board, const DetectOptions& detect, const ViewSelectionOptions& options) {
  DetectOptions quick = detect;
  quick.probe_other_families = false;  // per frame; a video without the board says so once
  return read_video_views(
      video, [&](const cv::Mat& grey) { return frame_candidate(grey, detect_board(grey, board, quick).corners); }, options, true, "board");
}

VideoViews read_tag_video(const fs::path& video, const TagLayout& layout, const DetectOptions& detect, const ViewSelectionOptions& options) {
  DetectOptions quick = detect;
  quick.probe_other_families = false;
  auto measure = [&](const cv::Mat& grey) {
    // One slot of 4 corners per tag of the layout, in its order.
    std::vector<Eigen::Vector3d> corners(4 * layout.tags.size(), Eigen::Vector3d(-1, -1, -1));
    for (const DetectedTag& t : detect_tags(grey, layout.family, quick)) {
      for (std::size_t k = 0; k < layout.tags.size(); ++k)
        if (layout.tags[k].id == t.id)
          for (int c = 0; c < 4; ++c) corners[4 * k + c] = Eigen::Vector3d(t.corners[c].x(), t.corners[c].y(), t.weight[c]);
    }
    return frame_candidate(grey, std::move(corners), 4);
  };
  return read_video_views(video, measure, options, false, "tags");
}

BoardViews detect_board_views(const std::vector<std::string>& inputs, const Board& board, const DetectOptions& detect,
                              const ViewSelectionOptions& options, const std::function<void(int, int)>& progress) {
  const ViewInputs in = split_view_inputs(inputs);
  BoardViews b;
  if (!in.images.empty()) {
    std::cerr << "detecting the board in " << in.images.size() << " images\n";
    b.views = detect_boards(in.images, board, detect, progress);
  }
  b.files = b.views.size();
  for (const auto& video : in.videos) {
    const VideoViews v = read_board_video(video, board, detect, options);
    std::cerr << v.summary() << "\n";
    for (std::size_t k = 0; k < v.images.size(); ++k) {
      b.views.push_back(detect_board(v.images[k], board, detect, v.names[k]));
      b.frames.push_back(v.images[k]);
    }
    b.videos.push_back(v.json());
    b.summaries.push_back(v.summary());
  }
  return b;
}

cv::Mat BoardViews::image(std::size_t k) const {
  if (k >= files) return frames.at(k - files);
  const cv::Mat img = cv::imread(views.at(k).image, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError(views[k].image, "", "cannot be read as an image");
  return img;
}

std::string VideoViews::summary() const {
  const ViewSelection& s = selection;
  std::ostringstream o;
  o.precision(3);
  o << source.string() << ": " << frames_read << " frames read, " << s.count(ViewVerdict::used) << " used; dropped "
    << s.count(ViewVerdict::blurred) << " blurred (edges wider than " << s.blur_limit_px << " px, the sharpest " << s.sharpest_width_px
    << " px), " << s.count(ViewVerdict::duplicate_view) << " duplicate views (corners moved < " << s.min_shift_px << " px), "
    << s.count(ViewVerdict::no_board) << " with no board or tags found, " << s.count(ViewVerdict::too_few_corners)
    << " with too few corners, " << s.count(ViewVerdict::over_cap) << " over the cap of " << options.max_views;
  return o.str();
}

nlohmann::json VideoViews::json() const {
  const ViewSelection& s = selection;
  nlohmann::json dropped;
  for (ViewVerdict r : {ViewVerdict::blurred, ViewVerdict::duplicate_view, ViewVerdict::no_board, ViewVerdict::too_few_corners, ViewVerdict::over_cap})
    dropped[to_string(r)] = s.count(r);
  nlohmann::json per_frame = nlohmann::json::array();
  for (std::size_t k = 0; k < candidates.size() && k < s.verdicts.size(); ++k) {
    const EdgeBlur& b = candidates[k].blur;
    per_frame.push_back({{"verdict", to_string(s.verdicts[k])},
                         {"edge_width_px", b.measured() ? nlohmann::json(b.width_px) : nlohmann::json(nullptr)},
                         {"best_edge_width_px", b.measured() ? nlohmann::json(b.best_width_px) : nlohmann::json(nullptr)}});
  }
  return {{"source", source.string()},
          {"codec", info.codec},
          {"lossy", info.lossy},
          {"size", {info.width, info.height}},
          {"fps", info.fps > 0 ? nlohmann::json(info.fps) : nlohmann::json(nullptr)},
          {"frames_read", frames_read},
          {"used", s.count(ViewVerdict::used)},
          {"dropped", dropped},
          {"frames_used", frames},
          {"sharpest_edge_width_px", s.sharpest_width_px},
          {"blur_limit_px", s.blur_limit_px},
          {"min_corner_shift_px", s.min_shift_px},
          {"frames", per_frame},
          {"options",
           {{"max_views", options.max_views},
            {"max_blur_ratio", options.max_blur_ratio},
            {"min_corner_shift", options.min_corner_shift},
            {"min_corner_fraction", options.min_corner_fraction}}}};
}

void add_video_options(CLI::App& sub, ViewSelectionOptions& o, bool distinct) {
  sub.add_option("--max-views", o.max_views, "Videos: keep at most this many frames of each video")->capture_default_str()->check(CLI::Range(1, 100000));
  sub.add_option("--max-blur-ratio", o.max_blur_ratio,
                 "Videos: drop frames whose edges are wider than this times the video's sharpest frame's (blur, motion blur)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 100.0));
  if (distinct)
    sub.add_option("--min-corner-shift", o.min_corner_shift,
                   "Videos: drop frames whose corners moved less than this fraction of the image diagonal from a kept frame's (duplicate views)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 0.99));
  sub.add_option("--min-corner-fraction", o.min_corner_fraction, "Videos: drop frames showing fewer than this fraction of the corners")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
}

}  // namespace clearfit::cli
