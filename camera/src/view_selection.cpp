// Edge widths of a board region and the choice of views from a video
// (view_selection.hpp).
#include <clearfit/camera/view_selection.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace clearfit {
namespace {

constexpr int kBins = 8;  // edge-normal orientations, 22.5 deg each

/// The region's mask: the convex hulls of `regions`, grown by margin_px.
cv::Mat region_mask(cv::Size size, const std::vector<std::vector<Eigen::Vector2d>>& regions, double margin_px) {
  cv::Mat mask = cv::Mat::zeros(size, CV_8U);
  for (const auto& r : regions) {
    std::vector<cv::Point2f> pts;
    for (const auto& p : r)
      if (std::isfinite(p.x()) && std::isfinite(p.y())) pts.emplace_back(float(p.x()), float(p.y()));
    if (pts.size() < 3) continue;
    std::vector<cv::Point2f> hull;
    cv::convexHull(pts, hull);
    std::vector<cv::Point> ip;
    for (const auto& h : hull) ip.emplace_back(int(std::lround(h.x)), int(std::lround(h.y)));
    cv::fillConvexPoly(mask, ip, 255);
  }
  const int m = static_cast<int>(std::ceil(std::max(0.0, margin_px)));
  if (m > 0) cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * m + 1, 2 * m + 1}));
  return mask;
}

double mean_shift(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double sum = 0;
  int n = 0;
  for (std::size_t k = 0; k < a.size() && k < b.size(); ++k)
    if (a[k].z() >= 0 && b[k].z() >= 0) {
      sum += (a[k].head<2>() - b[k].head<2>()).norm();
      ++n;
    }
  return n < 4 ? std::numeric_limits<double>::infinity() : sum / n;
}

int valid_corners(const ViewCandidate& c) {
  return static_cast<int>(std::count_if(c.corners.begin(), c.corners.end(), [](const Eigen::Vector3d& p) { return p.z() >= 0; }));
}

}  // namespace

EdgeBlur measure_edge_blur(const cv::Mat& grey, const std::vector<std::vector<Eigen::Vector2d>>& regions, double margin_px) {
  if (grey.empty() || grey.type() != CV_8UC1) throw std::invalid_argument("measure_edge_blur: needs an 8-bit one-channel image");
  const cv::Mat full_mask = region_mask(grey.size(), regions, margin_px);
  cv::Rect box = cv::boundingRect(full_mask);
  if (box.area() == 0) return {};
  const int pad = 5;  // the filters' support
  box = cv::Rect(box.x - pad, box.y - pad, box.width + 2 * pad, box.height + 2 * pad) & cv::Rect(0, 0, grey.cols, grey.rows);
  cv::Mat f, gx, gy, gxx, gxy, gyy;
  grey(box).convertTo(f, CV_32F);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 1.0);
  cv::Sobel(f, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(f, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  cv::Sobel(f, gxx, CV_32F, 2, 0, 3, 1.0 / 4);
  cv::Sobel(f, gyy, CV_32F, 0, 2, 3, 1.0 / 4);
  cv::Sobel(f, gxy, CV_32F, 1, 1, 3, 1.0 / 4);
  const cv::Mat mask = full_mask(box);
  std::vector<float> mags;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (mask.at<std::uint8_t>(y, x)) mags.push_back(std::hypot(gx.at<float>(y, x), gy.at<float>(y, x)));
  if (mags.empty()) return {};
  auto p99 = mags.begin() + static_cast<std::ptrdiff_t>(0.99 * double(mags.size() - 1));
  std::nth_element(mags.begin(), p99, mags.end());
  const double threshold = 0.1 * *p99;
  if (!(threshold > 0)) return {};
  std::array<double, kBins> e1{}, e2{};
  int used = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      if (!mask.at<std::uint8_t>(y, x)) continue;
      const double dx = gx.at<float>(y, x), dy = gy.at<float>(y, x), g2 = dx * dx + dy * dy;
      if (g2 < threshold * threshold) continue;
      const double inn = (dx * dx * gxx.at<float>(y, x) + 2 * dx * dy * gxy.at<float>(y, x) + dy * dy * gyy.at<float>(y, x)) / g2;
      double angle = std::atan2(dy, dx);
      if (angle < 0) angle += M_PI;
      const int bin = std::min(kBins - 1, static_cast<int>(angle / (M_PI / kBins)));
      e1[bin] += g2;
      e2[bin] += inn * inn;
      ++used;
    }
  const double total = std::accumulate(e1.begin(), e1.end(), 0.0);
  EdgeBlur out;
  out.best_width_px = std::numeric_limits<double>::infinity();
  for (int b = 0; b < kBins; ++b) {
    if (e1[b] < 0.05 * total || !(e2[b] > 0)) continue;
    const double w = std::sqrt(e1[b] / (2 * e2[b]));
    if (w > out.width_px) out.width_px = w, out.worst_normal_deg = (b + 0.5) * 180.0 / kBins;
    out.best_width_px = std::min(out.best_width_px, w);
  }
  if (!(out.width_px > 0)) return {};
  out.edge_pixels = used;
  return out;
}

void ViewSelectionOptions::validate() const {
  auto fail = [](const std::string& field, double v, const std::string& rule) {
    throw std::invalid_argument(field + " = " + std::to_string(v) + ": " + rule);
  };
  if (max_views < 1) fail("max_views", max_views, "must be at least 1");
  if (!(std::isfinite(max_blur_ratio) && max_blur_ratio >= 1)) fail("max_blur_ratio", max_blur_ratio, "must be at least 1");
  if (!(std::isfinite(min_corner_shift) && min_corner_shift >= 0 && min_corner_shift < 1))
    fail("min_corner_shift", min_corner_shift, "must be a fraction of the image diagonal in [0, 1)");
  if (!(std::isfinite(min_corner_fraction) && min_corner_fraction >= 0 && min_corner_fraction <= 1))
    fail("min_corner_fraction", min_corner_fraction, "must be in [0, 1]");
}

const char* to_string(ViewVerdict v) {
  switch (v) {
    case ViewVerdict::used: return "used";
    case ViewVerdict::no_board: return "no_board";
    case ViewVerdict::too_few_corners: return "too_few_corners";
    case ViewVerdict::blurred: return "blurred";
    case ViewVerdict::duplicate_view: return "duplicate_view";
    case ViewVerdict::over_cap: return "over_cap";
  }
  return "?";
}

int ViewSelection::count(ViewVerdict v) const { return static_cast<int>(std::count(verdicts.begin(), verdicts.end(), v)); }

std::vector<int> ViewSelection::used() const {
  std::vector<int> out;
  for (std::size_t k = 0; k < verdicts.size(); ++k)
    if (verdicts[k] == ViewVerdict::used) out.push_back(static_cast<int>(k));
  return out;
}

ViewSelection select_views(const std::vector<ViewCandidate>& candidates, int width, int height, const ViewSelectionOptions& options,
                           bool distinct) {
  options.validate();
  ViewSelection s;
  s.verdicts.assign(candidates.size(), ViewVerdict::over_cap);
  s.min_shift_px = options.min_corner_shift * std::hypot(double(width), double(height));
  // Corners first, then the video's sharpest frame among those with enough corners.
  std::vector<int> sharp;
  s.sharpest_width_px = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const ViewCandidate& c = candidates[k];
    const int n = valid_corners(c);
    if (n == 0) s.verdicts[k] = ViewVerdict::no_board;  // or blurred: decided below
    else if (n < std::max(4.0, options.min_corner_fraction * double(c.corners.size()))) s.verdicts[k] = ViewVerdict::too_few_corners;
    else if (!c.blur.measured()) s.verdicts[k] = ViewVerdict::blurred;  // no edge survived: nothing sharp in it
    else {
      sharp.push_back(static_cast<int>(k));
      s.sharpest_width_px = std::min(s.sharpest_width_px, c.blur.width_px);
    }
  }
  if (sharp.empty()) {
    s.sharpest_width_px = s.blur_limit_px = 0;
    return s;
  }
  s.blur_limit_px = options.max_blur_ratio * s.sharpest_width_px;
  // A board blurred enough is not found at all: a frame without corners whose edges are too wide is blurred.
  for (std::size_t k = 0; k < candidates.size(); ++k)
    if (s.verdicts[k] == ViewVerdict::no_board && candidates[k].blur.measured() && candidates[k].blur.width_px > s.blur_limit_px)
      s.verdicts[k] = ViewVerdict::blurred;
  std::erase_if(sharp, [&](int k) {
    const bool blurred = candidates[k].blur.width_px > s.blur_limit_px;
    if (blurred) s.verdicts[k] = ViewVerdict::blurred;
    return blurred;
  });
  std::stable_sort(sharp.begin(), sharp.end(), [&](int a, int b) { return candidates[a].blur.width_px < candidates[b].blur.width_px; });
  if (!distinct) {
    for (std::size_t i = 0; i < sharp.size() && i < static_cast<std::size_t>(options.max_views); ++i) s.verdicts[sharp[i]] = ViewVerdict::used;
    return s;
  }
  // Farthest-point sampling from the sharpest frame.
  std::vector<double> nearest(sharp.size(), std::numeric_limits<double>::infinity());
  std::size_t pick = 0;
  for (int kept = 0;;) {
    const int k = sharp[pick];
    s.verdicts[k] = ViewVerdict::used;
    nearest[pick] = -1;  // taken
    if (++kept >= options.max_views) break;
    double best = -1;
    for (std::size_t i = 0; i < sharp.size(); ++i) {
      if (nearest[i] < 0) continue;
      nearest[i] = std::min(nearest[i], mean_shift(candidates[sharp[i]].corners, candidates[k].corners));
      if (nearest[i] > best) best = nearest[i], pick = i;
    }
    if (best < s.min_shift_px) break;  // also when none is left (best -1)
    // Of the frames showing nearly that view, the sharpest (`sharp` is sorted by width).
    for (std::size_t i = 0; i < pick; ++i)
      if (nearest[i] >= 0 && mean_shift(candidates[sharp[i]].corners, candidates[sharp[pick]].corners) < 0.5 * s.min_shift_px) {
        pick = i;
        break;
      }
  }
  for (std::size_t i = 0; i < sharp.size(); ++i)
    if (nearest[i] >= 0) {
      // Not kept: near a kept view, or distinct but over the cap. Distances to views kept after the
      // last update are not in nearest[i] yet: bring them up to date.
      double d = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < sharp.size(); ++j)
        if (nearest[j] < 0) d = std::min(d, mean_shift(candidates[sharp[i]].corners, candidates[sharp[j]].corners));
      s.verdicts[sharp[i]] = d < s.min_shift_px ? ViewVerdict::duplicate_view : ViewVerdict::over_cap;
    }
  return s;
}

}  // namespace clearfit
