// Frame-to-reference motion on high-passed log red, from a grid of patches,
// combined by a robust similarity fit (see registration.hpp).
#include <clearfit/fit/glare.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/fit/srgb.hpp>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace clearfit {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// ln of the linear value of each 8-bit code (code 0 read as half a code).
const std::array<float, 256>& log_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    const float* lin = srgb::to_linear_table8();
    for (int i = 0; i < 256; ++i) t[i] = std::log(i == 0 ? 0.5f * lin[1] : lin[i]);
    return t;
  }();
  return table;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Robust fit of a similarity to patch centres `q` (relative to the similarity's centre) and their
/// translations `d`: IRLS with Tukey's biweight, started from the median translation.
void fit_similarity(const std::vector<Vec2>& q, const std::vector<Vec2>& d, const RegistrationOptions& o,
                    Similarity& s, std::vector<std::uint8_t>& inlier) {
  const std::size_t n = q.size();
  std::vector<double> xs, ys;
  for (const Vec2& v : d) xs.push_back(v.x()), ys.push_back(v.y());
  s.t = Vec2(median(xs), median(ys));
  s.a = s.b = 0;
  std::vector<double> w(n, 1.0);
  const bool similarity = n >= 3;
  for (int it = 0; it < 20; ++it) {
    std::vector<double> r(n);
    for (std::size_t i = 0; i < n; ++i) r[i] = (d[i] - s.displacement(s.centre + q[i])).norm();
    // Robust σ of a 2-D residual: its median norm is σ·√(2 ln 2) for Gaussian errors.
    const double sigma = std::max(median(r) / std::sqrt(2 * std::log(2.0)), o.min_sigma_px);
    const double cut = o.tukey_c * sigma;
    for (std::size_t i = 0; i < n; ++i) w[i] = r[i] < cut ? std::pow(1 - (r[i] / cut) * (r[i] / cut), 2) : 0.0;
    Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    double wsum = 0;
    Vec2 wmean = Vec2::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      if (w[i] <= 0) continue;
      const Eigen::Vector4d ex(1, 0, q[i].x(), -q[i].y()), ey(0, 1, q[i].y(), q[i].x());
      A += w[i] * (ex * ex.transpose() + ey * ey.transpose());
      rhs += w[i] * (ex * d[i].x() + ey * d[i].y());
      wsum += w[i], wmean += w[i] * d[i];
    }
    if (wsum <= 0) break;
    Similarity next = s;
    int kept = 0;
    for (double wi : w) kept += wi > 0;
    if (similarity && kept >= 3) {
      const Eigen::Vector4d x = A.ldlt().solve(rhs);
      if (x.allFinite()) next.t = x.head<2>(), next.a = x[2], next.b = x[3];
    } else {
      next.t = wmean / wsum, next.a = next.b = 0;
    }
    const bool converged = (next.t - s.t).norm() < 1e-5 && std::abs(next.a - s.a) + std::abs(next.b - s.b) < 1e-8;
    s = next;
    if (converged && it > 0) break;
  }
  inlier.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) inlier[i] = w[i] > 0;
}

}  // namespace

void RegistrationOptions::validate() const {
  auto rule = [](bool ok, const std::string& field, const std::string& what) {
    if (!ok) throw std::invalid_argument("RegistrationOptions." + field + ": " + what);
  };
  rule(grid >= 1 && grid <= 8, "grid", "must be 1..8");
  rule(patch_size >= 32, "patch_size", "must be >= 32 px");
  rule(std::isfinite(green_ratio) && green_ratio >= 0 && green_ratio < 1, "green_ratio", "must be in [0, 1)");
  rule(std::isfinite(smooth_sigma_px) && smooth_sigma_px >= 0 && smooth_sigma_px <= 4, "smooth_sigma_px", "must be in [0, 4]");
  rule(std::isfinite(highpass_sigma_px) && highpass_sigma_px >= 0.5 && highpass_sigma_px <= 32, "highpass_sigma_px", "must be in [0.5, 32]");
  rule(downsample == 1 || downsample == 2, "downsample", "must be 1 or 2");
  rule(iterations >= 1 && iterations <= 200, "iterations", "must be 1..200");
  rule(max_glare_fraction >= 0 && max_glare_fraction <= 1, "max_glare_fraction", "must be in [0, 1]");
  rule(std::isfinite(tukey_c) && tukey_c > 1, "tukey_c", "must be > 1");
  rule(std::isfinite(min_sigma_px) && min_sigma_px > 0, "min_sigma_px", "must be > 0");
}

double Similarity::angle_rad() const { return std::atan2(b, 1 + a); }
double Similarity::scale() const { return std::hypot(1 + a, b); }
double Similarity::max_displacement(const cv::Rect& r) const {
  double m = 0;
  for (const Vec2 c : {Vec2(r.x, r.y), Vec2(r.br().x, r.y), Vec2(r.x, r.br().y), Vec2(r.br().x, r.br().y)})
    m = std::max(m, displacement(c).norm());
  return m;
}

MotionRegistration::MotionRegistration(cv::Size image, const cv::Rect& roi, const RegistrationOptions& options, const cv::Mat& seen)
    : image_(image), roi_(roi & cv::Rect(0, 0, image.width, image.height)), options_(options) {
  options_.validate();
  if (roi_.area() == 0) throw std::invalid_argument("MotionRegistration: the roi lies outside the image");
  const int g = options_.grid;
  // Patch edge: even, at most the option, small enough for the grid to fit across the roi and the image.
  // Patches overlap in a small roi rather than shrink below the option (measured: 35 px patches
  // at half resolution read 2–5× more noise than 64 px ones on the test scene).
  int p = std::min({options_.patch_size, roi_.width, roi_.height, image.width, image.height});
  p = std::max(16, p & ~1);
  if (p > image.width || p > image.height) throw std::invalid_argument("MotionRegistration: the image is smaller than 16 px");
  if (!seen.empty() && (seen.type() != CV_8U || seen.size() != roi.size()))
    throw std::invalid_argument("MotionRegistration: the seen mask must be CV_8U of the roi's size");
  auto seen_fraction = [&](const cv::Rect& r) {
    if (seen.empty()) return 1.0;
    const cv::Rect in = (r & roi) - roi.tl();
    return in.area() == 0 ? 0.0 : cv::countNonZero(seen(in)) / static_cast<double>(r.area());
  };
  auto patch_at = [&](double cx, double cy) {
    const int x = std::clamp(static_cast<int>(std::lround(cx)) - p / 2, 0, image.width - p) & ~1;
    const int y = std::clamp(static_cast<int>(std::lround(cy)) - p / 2, 0, image.height - p) & ~1;
    return cv::Rect(x, y, p, p);
  };
  for (int j = 0; j < g; ++j)
    for (int i = 0; i < g; ++i) {
      // The cell's centre, or the place in the cell (a 5 × 5 lattice) that sees the most skin.
      cv::Rect best = patch_at(roi_.x + roi_.width * (i + 0.5) / g, roi_.y + roi_.height * (j + 0.5) / g);
      double best_seen = seen_fraction(best);
      for (int b = 0; b < 5 && best_seen < 1; ++b)
        for (int a = 0; a < 5; ++a) {
          const cv::Rect r = patch_at(roi_.x + roi_.width * (i + (a + 0.5) / 5) / g, roi_.y + roi_.height * (j + (b + 0.5) / 5) / g);
          const double f = seen_fraction(r);
          if (f > best_seen + 1e-9) best = r, best_seen = f;
        }
      if (best_seen >= 0.75) rects_.push_back(best);
    }
  if (rects_.empty()) rects_.push_back(patch_at(roi_.x + 0.5 * roi_.width, roi_.y + 0.5 * roi_.height));  // little skin: one patch
  border_half_ = static_cast<int>(std::ceil(3 * options_.highpass_sigma_px)) + 4;
}

cv::Mat MotionRegistration::filtered(const cv::Mat& bgr, const cv::Rect& rect, cv::Point& origin_half) const {
  const int b = options_.downsample * border_half_;
  cv::Rect region(rect.x - b, rect.y - b, rect.width + 2 * b, rect.height + 2 * b);
  region &= cv::Rect(0, 0, bgr.cols, bgr.rows);
  region.x += region.x & 1, region.y += region.y & 1;  // even origin: half-resolution pixels line up
  region.width = std::max(2, (std::min(region.width, bgr.cols - region.x)) & ~1);
  region.height = std::max(2, (std::min(region.height, bgr.rows - region.y)) & ~1);
  const auto& lut = log_table();
  const float rho = static_cast<float>(options_.green_ratio);
  cv::Mat full(region.size(), CV_32F);
  for (int y = 0; y < region.height; ++y) {
    const auto* src = bgr.ptr<cv::Vec3b>(region.y + y) + region.x;
    auto* dst = full.ptr<float>(y);
    for (int x = 0; x < region.width; ++x) dst[x] = lut[src[x][2]] - rho * lut[src[x][1]];
  }
  cv::Mat half, low;
  if (options_.downsample == 2) cv::pyrDown(full, half);
  else half = full;
  if (options_.smooth_sigma_px > 0) cv::GaussianBlur(half, half, cv::Size(), options_.smooth_sigma_px, 0, cv::BORDER_REPLICATE);
  cv::GaussianBlur(half, low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
  origin_half = region.tl() / options_.downsample;
  return half - low;
}

void MotionRegistration::set_reference(const cv::Mat& bgr) {
  reference_.assign(rects_.size(), Patch{});
  tbb::parallel_for(std::size_t(0), rects_.size(), [&](std::size_t k) {
    const cv::Rect& r = rects_[k];
    Patch& p = reference_[k];
    if (glare_fraction(bgr, r) > options_.max_glare_fraction) return;
    cv::Point o;
    const cv::Mat f = filtered(bgr, r, o);
    cv::Mat fx, fy;
    cv::Scharr(f, fx, CV_32F, 1, 0, 1.0 / 32, 0, cv::BORDER_REPLICATE);
    cv::Scharr(f, fy, CV_32F, 0, 1, 1.0 / 32, 0, cv::BORDER_REPLICATE);
    const int ds = options_.downsample;
    const cv::Rect in(r.x / ds - o.x, r.y / ds - o.y, r.width / ds, r.height / ds);
    if ((in & cv::Rect(0, 0, f.cols, f.rows)) != in) return;
    p.t = f(in).clone(), p.tx = fx(in).clone(), p.ty = fy(in).clone();
    p.h[0] = p.tx.dot(p.tx), p.h[1] = p.tx.dot(p.ty), p.h[2] = p.ty.dot(p.ty);
    const double det = p.h[0] * p.h[2] - p.h[1] * p.h[1];
    p.usable = std::isfinite(det) && det > 1e-12 * (p.h[0] + p.h[2]) * (p.h[0] + p.h[2]);
  });
}

RegistrationResult MotionRegistration::measure(const cv::Mat& bgr, const Similarity& start_in) const {
  RegistrationResult res;
  const std::size_t n = rects_.size();
  res.patch_shift.assign(n, Vec2::Constant(kNaN));
  res.glare.assign(n, 0);
  res.inlier.assign(n, 0);
  Similarity start = start_in;
  start.centre = Vec2(roi_.x + 0.5 * roi_.width, roi_.y + 0.5 * roi_.height);
  if (!(start.t.allFinite() && std::isfinite(start.a) && std::isfinite(start.b))) start.t.setZero(), start.a = start.b = 0;
  res.motion.centre = start.centre;
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
    const Patch& ref = reference_[k];
    if (!ref.usable) return;
    const cv::Rect& r = rects_[k];
    const Vec2 centre(r.x + 0.5 * r.width, r.y + 0.5 * r.height);
    const Vec2 d0 = start.displacement(centre);
    // Read where the patch is expected (an even offset keeps the half-resolution grid).
    const int ds = options_.downsample;
    const cv::Point off(ds * static_cast<int>(std::lround(d0.x() / ds)), ds * static_cast<int>(std::lround(d0.y() / ds)));
    const cv::Rect moved = r + off;
    if (glare_fraction(bgr, moved) > options_.max_glare_fraction) {
      res.glare[k] = 1;
      return;
    }
    cv::Point o;
    const cv::Mat f = filtered(bgr, moved, o);
    // Enhanced correlation (ECC, translation) of the reference patch into the region read,
    // started where the patch is expected: zero-mean and normalised, so what is left of a
    // gain or an offset after the log and the high-pass does not matter.
    const Vec2 p0 = d0 / ds;  // displacement at the registered resolution
    cv::Mat warp = (cv::Mat_<float>(2, 3) << 1, 0, static_cast<float>(r.x / ds + p0.x() - o.x), 0, 1,
                    static_cast<float>(r.y / ds + p0.y() - o.y));
    try {
      cv::findTransformECC(ref.t, f, warp, cv::MOTION_TRANSLATION,
                           cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, options_.iterations, 1e-3), cv::noArray(), 1);
    } catch (const cv::Exception&) {
      return;  // did not converge: left out
    }
    const Vec2 p(warp.at<float>(0, 2) - (r.x / ds - o.x), warp.at<float>(1, 2) - (r.y / ds - o.y));
    if (p.allFinite() && (p - p0).norm() < border_half_) res.patch_shift[k] = ds * p;
  });
  std::vector<Vec2> q, d;
  std::vector<std::size_t> index;
  for (std::size_t k = 0; k < n; ++k)
    if (res.patch_shift[k].allFinite()) {
      q.push_back(Vec2(rects_[k].x + 0.5 * rects_[k].width, rects_[k].y + 0.5 * rects_[k].height) - res.motion.centre);
      d.push_back(res.patch_shift[k]);
      index.push_back(k);
    }
  res.patches = static_cast<int>(q.size());
  if (q.empty()) {
    res.motion.t = Vec2::Constant(kNaN);
    return res;
  }
  std::vector<std::uint8_t> inlier;
  fit_similarity(q, d, options_, res.motion, inlier);
  for (std::size_t i = 0; i < index.size(); ++i) res.inlier[index[i]] = inlier[i], res.patches_used += inlier[i];
  res.found = res.motion.t.allFinite();
  return res;
}

}  // namespace clearfit
