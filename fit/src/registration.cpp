// Frame-to-reference motion on high-passed log red, from a grid of patches,
// combined by a robust similarity fit (see registration.hpp).
#include <clearfit/fit/glare.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/fit/srgb.hpp>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
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
  // A turn and scale within the patches' own scatter are noise: at the roi's corners they would
  // double it. The translation alone then (kept patches' weighted mean).
  double wsum = 0, wq = 0, wr = 0;
  Vec2 wmean = Vec2::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    wsum += w[i], wq += w[i] * q[i].squaredNorm(), wmean += w[i] * d[i];
    wr += w[i] * (d[i] - s.displacement(s.centre + q[i])).squaredNorm();
  }
  if (wsum <= 0) return;
  int kept = 0;
  for (double wi : w) kept += wi > 0;
  // Fewer than six patches kept (glare, blanching) leave a turn poorly held at the far corners.
  const double sigma = std::sqrt(wr / (2 * std::max(wsum - 2.0, 1.0)));  // per coordinate
  if (kept < 6 || wq <= 0 || std::hypot(s.a, s.b) < o.turn_significance * sigma / std::sqrt(wq / 2)) s.t = wmean / wsum, s.a = s.b = 0;
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
  rule(reference_frames >= 1 && reference_frames <= 64, "reference_frames", "must be 1..64");
  rule(max_glare_fraction >= 0 && max_glare_fraction <= 1, "max_glare_fraction", "must be in [0, 1]");
  rule(std::isfinite(tukey_c) && tukey_c > 1, "tukey_c", "must be > 1");
  rule(std::isfinite(min_sigma_px) && min_sigma_px > 0, "min_sigma_px", "must be > 0");
  rule(std::isfinite(turn_significance) && turn_significance >= 0, "turn_significance", "must be >= 0");
}

double Similarity::angle_rad() const { return std::atan2(b, 1 + a); }
double Similarity::scale() const { return std::hypot(1 + a, b); }
double Similarity::max_displacement(const cv::Rect& r) const {
  double m = 0;
  for (const Vec2& c : {Vec2(r.x, r.y), Vec2(r.br().x, r.y), Vec2(r.x, r.br().y), Vec2(r.br().x, r.br().y)})
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
  // Patches keep their template's apron and a few pixels of motion inside the image.
  const int edge = options_.downsample * (kApron + 4);
  int p = std::min({options_.patch_size, roi_.width, roi_.height, image.width - 2 * edge, image.height - 2 * edge});
  p = std::max(16, p & ~1);
  if (p + 2 * edge > image.width || p + 2 * edge > image.height)
    throw std::invalid_argument("MotionRegistration: the image is smaller than " + std::to_string(min_image_side(options_)) + " px");
  if (!seen.empty() && (seen.type() != CV_8U || seen.size() != roi.size()))
    throw std::invalid_argument("MotionRegistration: the seen mask must be CV_8U of the roi's size");
  auto seen_fraction = [&](const cv::Rect& r) {
    if (seen.empty()) return 1.0;
    const cv::Rect in = (r & roi) - roi.tl();
    return in.area() == 0 ? 0.0 : cv::countNonZero(seen(in)) / static_cast<double>(r.area());
  };
  auto patch_at = [&](double cx, double cy) {
    const int even = options_.downsample == 2 ? ~1 : ~0;  // whole registration pixels
    const int x = std::clamp(static_cast<int>(std::lround(cx)) - p / 2, edge, image.width - p - edge) & even;
    const int y = std::clamp(static_cast<int>(std::lround(cy)) - p / 2, edge, image.height - p - edge) & even;
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
  border_ = static_cast<int>(std::ceil(3 * std::max(options_.highpass_sigma_px, options_.smooth_sigma_px))) + 4;
  const int ds = options_.downsample;
  if (!seen.empty()) {
    // The skin, eroded: the pixels next to its edge mix in what lies beyond.
    seen_ = cv::Mat::zeros(image, CV_8U);
    cv::erode(seen != 0, seen_(roi_), cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  }
  for (const cv::Rect& r : rects_) {
    Patch p;
    p.area = cv::Rect(r.x / ds, r.y / ds, r.width / ds, r.height / ds);
    patches_.push_back(p);
  }
  skin_blur_.resize(patches_.size());
}

const MotionRegistration::SkinBlur& MotionRegistration::skin_blur(const cv::Rect& region, cv::Point shift, const cv::Rect& crop,
                                                                 SkinBlur& cache) const {
  if (cache.region == region && cache.shift == shift && cache.crop == crop && !cache.skin.empty()) return cache;
  // The skin in this frame: the seen mask moved with the frame (pixels off the image: none).
  SkinBlur fresh;  // new buffers: Regions handed out earlier keep theirs
  fresh.region = region, fresh.shift = shift, fresh.crop = crop;
  fresh.skin = cv::Mat::zeros(region.size(), CV_32F);
  const cv::Rect from = (region - shift) & cv::Rect(0, 0, seen_.cols, seen_.rows);
  if (from.area() > 0) seen_(from).convertTo(fresh.skin(from + shift - region.tl()), CV_32F, 1.0 / 255);
  cv::Mat mask = fresh.skin, mask_low;
  smooth(mask);
  // Only the crop is blurred; its support is read from the whole mask (as blurring all of it and cropping).
  cv::GaussianBlur(mask(crop), mask_low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
  fresh.mask_div = cv::max(mask(crop), 1e-3f);
  fresh.low_div = cv::max(mask_low, 1e-3f);
  fresh.on_skin = mask(crop) > 0.99f;
  cache = std::move(fresh);
  return cache;
}

void MotionRegistration::smooth(cv::Mat& m) const {
  if (options_.downsample == 2) cv::pyrDown(m, m);
  if (options_.smooth_sigma_px > 0) cv::GaussianBlur(m, m, cv::Size(), options_.smooth_sigma_px, 0, cv::BORDER_REPLICATE);
}

MotionRegistration::Region MotionRegistration::filtered(const cv::Mat& bgr, const cv::Rect& area_in, cv::Point shift,
                                                        SkinBlur& cache) const {
  Region out;
  const int ds = options_.downsample;
  const cv::Rect image_reg(0, 0, bgr.cols / ds, bgr.rows / ds);
  const cv::Rect area = area_in & image_reg;
  if (area.area() == 0) return out;
  // Full-resolution region: the area plus the filters' support (clipped to the image; even for pyrDown).
  cv::Rect region(ds * (area.x - border_), ds * (area.y - border_), ds * (area.width + 2 * border_), ds * (area.height + 2 * border_));
  region &= cv::Rect(0, 0, image_reg.width * ds, image_reg.height * ds);
  const auto& lut = log_table();
  const float rho = static_cast<float>(options_.green_ratio);
  cv::Mat full(region.size(), CV_32F);
  for (int y = 0; y < region.height; ++y) {
    const auto* src = bgr.ptr<cv::Vec3b>(region.y + y) + region.x;
    auto* dst = full.ptr<float>(y);
    for (int x = 0; x < region.width; ++x) dst[x] = lut[src[x][2]] - rho * lut[src[x][1]];
  }
  const cv::Rect crop = area - region.tl() / ds;  // the area in the (smoothed) region
  out.origin = area.tl();
  // The high-pass is read over the crop only; the Gaussian's support comes from the whole region
  // (OpenCV reads a submatrix's surroundings from its parent), so the crop is as if all were blurred.
  cv::Mat low;
  if (seen_.empty()) {
    smooth(full);
    cv::GaussianBlur(full(crop), low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
    out.f = full(crop) - low;
    return out;
  }
  // Normalised convolution: the skin's own smoothing, so what lies beyond its edge does not leak in.
  // The skin's terms change only when the region or the frame's integer shift does (cached per patch).
  const SkinBlur& skin = skin_blur(region, shift, crop, cache);
  cv::Mat reg = full.mul(skin.skin);
  smooth(reg);
  cv::GaussianBlur(reg(crop), low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
  out.f = reg(crop) / skin.mask_div - low / skin.low_div;
  out.skin = skin.on_skin;
  return out;
}

cv::Rect MotionRegistration::support(double motion_px) const {
  // read(): the template with its apron where the expected motion puts it, the search margin, then
  // the filters' border. A motion that moves the roi's corners by at most motion_px moves a patch's
  // corners (at most half a patch diagonal beyond the roi, a patch being no larger than the roi) by
  // at most twice as much; three times, with a few pixels, to spare.
  const int ds = options_.downsample;
  const int reach = ds * (kApron + kSearchMargin + 1 + border_ + 2) + static_cast<int>(std::ceil(3 * motion_px));
  cv::Rect all;
  for (const cv::Rect& r : rects_) {
    const cv::Rect grown(r.x - reach, r.y - reach, r.width + 2 * reach, r.height + 2 * reach);
    all = all.area() == 0 ? grown : (all | grown);
  }
  return all & cv::Rect(0, 0, image_.width, image_.height);
}

MotionRegistration::Regions MotionRegistration::read(const cv::Mat& bgr, const Similarity& expected) const {
  if (bgr.type() != CV_8UC3 || bgr.size() != image_)
    throw std::invalid_argument("MotionRegistration: frames must be 8-bit BGR of the registration's image size");
  Regions regions(patches_.size());
  const int ds = options_.downsample;
  tbb::parallel_for(std::size_t(0), patches_.size(), [&](std::size_t k) {
    const Patch& p = patches_[k];
    Region& g = regions[k];
    // The template's corners (with its apron) where the expected motion puts them, and a margin
    // for the correction, the interpolation and a second pass.
    const cv::Rect a(p.area.x - kApron, p.area.y - kApron, p.area.width + 2 * kApron, p.area.height + 2 * kApron);
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    for (const Vec2& c : {Vec2(a.x, a.y), Vec2(a.br().x, a.y), Vec2(a.x, a.br().y), Vec2(a.br().x, a.br().y)}) {
      const Vec2 m = c + expected.displacement(ds * c) / ds;
      x0 = std::min(x0, m.x()), y0 = std::min(y0, m.y()), x1 = std::max(x1, m.x()), y1 = std::max(y1, m.y());
    }
    if (!std::isfinite(x0 + y0 + x1 + y1)) return;
    const cv::Rect box(static_cast<int>(std::floor(x0)) - kSearchMargin, static_cast<int>(std::floor(y0)) - kSearchMargin,
                       static_cast<int>(std::ceil(x1 - x0)) + 2 * kSearchMargin + 1, static_cast<int>(std::ceil(y1 - y0)) + 2 * kSearchMargin + 1);
    const Vec2 centre(p.area.x + 0.5 * p.area.width, p.area.y + 0.5 * p.area.height), shift = expected.displacement(ds * centre) / ds;
    const cv::Point moved(static_cast<int>(std::lround(shift.x())), static_cast<int>(std::lround(shift.y())));
    const cv::Rect full_res(ds * (p.area.x + moved.x), ds * (p.area.y + moved.y), ds * p.area.width, ds * p.area.height);
    if (glare_fraction(bgr, full_res) > options_.max_glare_fraction) {
      g.glare = true;
      return;
    }
    g = filtered(bgr, box, cv::Point(ds * moved.x, ds * moved.y), skin_blur_[k]);
  });
  return regions;
}

namespace {

/// Catmull–Rom weights of the four taps around a fractional position f in [0, 1).
inline void cubic_weights(float f, float w[4]) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = 0.5f * (-f3 + 2 * f2 - f);
  w[1] = 0.5f * (3 * f3 - 5 * f2 + 2);
  w[2] = 0.5f * (-3 * f3 + 4 * f2 + f);
  w[3] = 0.5f * (f3 - f2);
}

/// `src` sampled by bicubic (Catmull–Rom) interpolation at (bx + dx, by + dy), exactly: OpenCV's
/// remap and warpAffine round positions to 1/32 px, which a registration to a hundredth of a
/// pixel cannot afford. `uniform`: the positions are a grid moved by one offset (no turn or
/// scale), sampled as one separable filter. Returns false when a position leaves `src` (its taps included).
bool sample_cubic(const cv::Mat& src, const cv::Mat& bx, const cv::Mat& by, double dx, double dy, bool uniform, cv::Mat& out) {
  if (uniform) {
    const double x = bx.at<float>(0, 0) + dx, y = by.at<float>(0, 0) + dy;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    if (x0 < 1 || y0 < 1 || x0 + bx.cols + 2 > src.cols || y0 + bx.rows + 2 > src.rows) return false;
    float wx[4], wy[4];
    cubic_weights(static_cast<float>(x - x0), wx);
    cubic_weights(static_cast<float>(y - y0), wy);
    cv::Mat filtered;
    cv::sepFilter2D(src(cv::Rect(x0 - 1, y0 - 1, bx.cols + 3, bx.rows + 3)), filtered, CV_32F, cv::Mat(1, 4, CV_32F, wx),
                    cv::Mat(4, 1, CV_32F, wy), cv::Point(0, 0), 0, cv::BORDER_REPLICATE);
    out = filtered(cv::Rect(0, 0, bx.cols, bx.rows));
    return true;
  }
  out.create(bx.size(), CV_32F);
  for (int j = 0; j < bx.rows; ++j) {
    const float *px = bx.ptr<float>(j), *py = by.ptr<float>(j);
    float* o = out.ptr<float>(j);
    for (int i = 0; i < bx.cols; ++i) {
      const double x = px[i] + dx, y = py[i] + dy;
      const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
      if (x0 < 1 || y0 < 1 || x0 + 2 >= src.cols || y0 + 2 >= src.rows) return false;
      float wx[4], wy[4];
      cubic_weights(static_cast<float>(x - x0), wx);
      cubic_weights(static_cast<float>(y - y0), wy);
      float v = 0;
      for (int b = 0; b < 4; ++b) {
        const float* row = src.ptr<float>(y0 - 1 + b) + (x0 - 1);
        v += wy[b] * (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
      }
      o[i] = v;
    }
  }
  return true;
}

/// The translation (registration px) that moves `region` onto a template: Gauss–Newton on
/// the zero-mean, gain-normalised difference, the region sampled at `base` + the translation
/// (sample_cubic, with a pixel's apron for its gradients). The Jacobian is the mean of the
/// template's and the sample's gradients (efficient second-order minimisation): symmetric in the
/// two, and steps not shortened by the template's noise alone.
/// Returns false when the region runs out or the correlation is lost.
struct TemplateFit {
  const cv::Mat &t, &tx, &ty, &weight;
  double tt;
  bool run(const cv::Mat& region, const cv::Mat& base_x, const cv::Mat& base_y, const Eigen::Matrix2d& linear, bool uniform,
           int iterations, Vec2& delta, double& gain) const {
    cv::Mat big, gx, gy;
    const cv::Rect in(1, 1, t.cols, t.rows);
    for (int it = 0; it < iterations; ++it) {
      if (!sample_cubic(region, base_x, base_y, delta.x(), delta.y(), uniform, big)) return false;
      cv::Mat w = big(in);
      w -= cv::mean(w, weight)[0];
      gain = w.dot(t) / tt;
      if (!(gain > 0)) return false;
      const cv::Mat e = w - gain * t;
      cv::Scharr(big, gx, CV_32F, 1, 0, 1.0 / 32);
      cv::Scharr(big, gy, CV_32F, 0, 1, 1.0 / 32);
      // Efficient second-order minimisation: the mean of the template's and the sample's gradients.
      cv::Mat jx = 0.5 * (tx + gx(in) / gain), jy = 0.5 * (ty + gy(in) / gain);
      jx.setTo(0, weight == 0), jy.setTo(0, weight == 0);
      const double hxy = jx.dot(jy);
      const Eigen::Matrix2d h = (Eigen::Matrix2d() << jx.dot(jx), hxy, hxy, jy.dot(jy)).finished();
      Vec2 step = h.ldlt().solve(Vec2(jx.dot(e), jy.dot(e))) / gain;
      if (!step.allFinite()) return false;
      if (step.norm() > 1) step /= step.norm();
      delta -= linear * step;
      if (step.norm() < 1e-3) return true;
    }
    return true;
  }
};

}  // namespace

RegistrationResult MotionRegistration::solve(const Regions& regions, const Similarity& start_in, std::vector<cv::Mat>* warped) const {
  RegistrationResult res;
  const std::size_t n = patches_.size();
  const int ds = options_.downsample;
  // The start, about the roi's centre.
  Similarity start = start_in;
  start.centre = Vec2(roi_.x + 0.5 * roi_.width, roi_.y + 0.5 * roi_.height);
  start.t = start_in.displacement(start.centre);
  if (!(start.t.allFinite() && std::isfinite(start.a) && std::isfinite(start.b))) start.t.setZero(), start.a = start.b = 0;
  res.motion = start;
  res.glare.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) res.glare[k] = regions[k].glare;
  std::vector<Vec2> delta(n, Vec2::Zero());
  std::vector<double> gain(n, 1.0);
  std::vector<std::uint8_t> ok(n, 0), inlier;
  auto centre_of = [&](std::size_t k) {  // the template's centre, full-resolution px
    const cv::Rect& a = patches_[k].area;
    return Vec2(ds * (a.x + 0.5 * (a.width - 1)), ds * (a.y + 0.5 * (a.height - 1)));
  };
  // Sampling positions of the template (plus `apron`) in the region under motion `s`.
  auto base_maps = [&](std::size_t k, const Similarity& s, int apron, cv::Mat& bx, cv::Mat& by) {
    const cv::Rect& a = patches_[k].area;
    bx.create(a.height + 2 * apron, a.width + 2 * apron, CV_32F), by.create(bx.size(), CV_32F);
    const cv::Point o = regions[k].origin;
    for (int j = 0; j < bx.rows; ++j)
      for (int i = 0; i < bx.cols; ++i) {
        const Vec2 x(a.x - apron + i, a.y - apron + j);
        const Vec2 m = x + s.displacement(ds * x) / ds;
        bx.at<float>(j, i) = static_cast<float>(m.x() - o.x), by.at<float>(j, i) = static_cast<float>(m.y() - o.y);
      }
  };
  // No turn or scale worth a hundredth of a pixel at the patch's corners: its samples are one grid moved.
  auto uniform = [&](std::size_t k, const Similarity& m) {
    return (std::abs(m.a) + std::abs(m.b)) * ds * 0.5 * (patches_[k].area.width + patches_[k].area.height) < 0.01;
  };
  Similarity s = start;
  for (int pass = 0; pass < 4; ++pass) {
    const Eigen::Matrix2d linear = (Eigen::Matrix2d() << 1 + s.a, -s.b, s.b, 1 + s.a).finished();
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
      const Patch& p = patches_[k];
      ok[k] = 0;
      if (!p.usable || regions[k].f.empty()) return;
      cv::Mat bx, by;
      base_maps(k, s, 1, bx, by);
      const TemplateFit f{p.t, p.tx, p.ty, p.weight, p.t.dot(p.t)};
      Vec2 d = Vec2::Zero();
      if (f.run(regions[k].f, bx, by, linear, uniform(k, s), options_.iterations, d, gain[k]) && d.norm() < 4) delta[k] = d, ok[k] = 1;
    });
    std::vector<Vec2> q, d;
    std::vector<std::size_t> index;
    for (std::size_t k = 0; k < n; ++k)
      if (ok[k]) {
        const Vec2 c = centre_of(k);
        q.push_back(c - s.centre);
        d.push_back(s.displacement(c) + ds * delta[k]);
        index.push_back(k);
      }
    res.patches = static_cast<int>(q.size());
    res.patch_shift.assign(n, Vec2::Constant(kNaN));
    for (std::size_t i = 0; i < index.size(); ++i) res.patch_shift[index[i]] = d[i];
    if (q.empty()) {
      res.motion.t = Vec2::Constant(kNaN);
      res.inlier.assign(n, 0);
      return res;
    }
    Similarity next;
    next.centre = s.centre;
    fit_similarity(q, d, options_, next, inlier);
    res.inlier.assign(n, 0);
    res.patches_used = 0;
    for (std::size_t i = 0; i < index.size(); ++i) res.inlier[index[i]] = inlier[i], res.patches_used += inlier[i];
    // The turn and scale changed the patches' own sampling by more than a hundredth of a pixel: again.
    double change = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 half(0.5 * ds * patches_[k].area.width, 0.5 * ds * patches_[k].area.height);
      change = std::max(change, (std::abs(next.a - s.a) + std::abs(next.b - s.b)) * half.norm());
    }
    s = next;
    res.motion = s;
    if (change < 0.01) break;
  }
  res.found = res.motion.t.allFinite();
  if (warped && res.found) {
    warped->assign(n, cv::Mat());
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
      if (!res.inlier[k] || !(gain[k] > 0)) return;
      cv::Mat bx, by, w;
      base_maps(k, s, kApron, bx, by);
      // The patch's own residual translation (its noise) is left in: the average is moved by the whole motion.
      if (!sample_cubic(regions[k].f, bx, by, 0, 0, uniform(k, s), w)) return;
      (*warped)[k] = (w - cv::mean(w)[0]) / gain[k];
    });
  }
  return res;
}

void MotionRegistration::accumulate(const std::vector<cv::Mat>& warped) {
  tbb::parallel_for(std::size_t(0), patches_.size(), [&](std::size_t k) {
    Patch& p = patches_[k];
    if (warped[k].empty()) return;
    if (p.sum.empty()) p.sum = warped[k].clone();
    else p.sum += warped[k];
    ++p.count;
    const cv::Mat avg = p.sum / p.count;
    cv::Mat gx, gy;
    cv::Scharr(avg, gx, CV_32F, 1, 0, 1.0 / 32, 0, cv::BORDER_REPLICATE);
    cv::Scharr(avg, gy, CV_32F, 0, 1, 1.0 / 32, 0, cv::BORDER_REPLICATE);
    const cv::Rect in(kApron, kApron, p.area.width, p.area.height);
    const cv::Mat off = p.weight == 0;
    p.t = avg(in) - cv::mean(avg(in), p.weight)[0];
    p.tx = gx(in).clone(), p.ty = gy(in).clone();
    p.t.setTo(0, off), p.tx.setTo(0, off), p.ty.setTo(0, off);
    p.h[0] = p.tx.dot(p.tx), p.h[1] = p.tx.dot(p.ty), p.h[2] = p.ty.dot(p.ty);
    const double det = p.h[0] * p.h[2] - p.h[1] * p.h[1];
    p.usable = std::isfinite(det) && det > 1e-12 * (p.h[0] + p.h[2]) * (p.h[0] + p.h[2]) && p.t.dot(p.t) > 0;
  });
}

void MotionRegistration::set_reference(const cv::Mat& bgr) {
  for (Patch& p : patches_) {
    Patch fresh;
    fresh.area = p.area;
    p = fresh;
  }
  kept_.clear(), kept_motion_.clear(), kept_call_.clear();
  calls_ = 0;
  frames_averaged_ = 0;
  open_ = true;
  const Similarity none{Vec2(roi_.x + 0.5 * roi_.width, roi_.y + 0.5 * roi_.height)};
  Regions regions = read(bgr, none);
  std::vector<cv::Mat> warped(patches_.size());
  for (std::size_t k = 0; k < patches_.size(); ++k) {
    if (regions[k].glare || regions[k].f.empty()) continue;
    const cv::Rect a = patches_[k].area, r(a.x - kApron - regions[k].origin.x, a.y - kApron - regions[k].origin.y,
                                           a.width + 2 * kApron, a.height + 2 * kApron);
    if ((r & cv::Rect(0, 0, regions[k].f.cols, regions[k].f.rows)) != r) continue;
    // The template's pixels: on the skin, away from its edge by the gradients' reach.
    Patch& p = patches_[k];
    const cv::Rect in(r.x + kApron, r.y + kApron, a.width, a.height);
    if (regions[k].skin.empty()) p.weight = cv::Mat(a.size(), CV_8U, cv::Scalar(255));
    else cv::erode(regions[k].skin(in), p.weight, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * kApron + 3, 2 * kApron + 3)));
    if (cv::countNonZero(p.weight) < a.area() / 4) continue;  // mostly off the skin
    warped[k] = regions[k].f(r) - cv::mean(regions[k].f(r))[0];
  }
  accumulate(warped);
  frames_averaged_ = 1;
  kept_.push_back(std::move(regions));
  kept_motion_.push_back(none);
  kept_call_.push_back(calls_++);
}

RegistrationResult MotionRegistration::add_to_reference(const cv::Mat& bgr, const Similarity& start) {
  if (!has_reference()) {
    set_reference(bgr);
    RegistrationResult r;
    r.motion = kept_motion_.front();
    r.found = true;
    r.patches = r.patches_used = 0;
    for (const Patch& p : patches_) r.patches += p.usable;
    r.patches_used = r.patches;
    r.patch_shift.assign(patches_.size(), Vec2::Zero());
    r.inlier.assign(patches_.size(), 1);
    r.glare.assign(patches_.size(), 0);
    return r;
  }
  if (!reference_open()) return measure(bgr, start);
  Regions regions = read(bgr, start);
  std::vector<cv::Mat> warped;
  RegistrationResult r = solve(regions, start, &warped);
  if (r.found) {
    accumulate(warped);
    ++frames_averaged_;
    kept_.push_back(std::move(regions));
    kept_motion_.push_back(r.motion);
    kept_call_.push_back(calls_);
  }
  ++calls_;
  return r;
}

std::vector<std::pair<int, RegistrationResult>> MotionRegistration::close_reference() {
  std::vector<std::pair<int, RegistrationResult>> out;
  open_ = false;
  for (std::size_t i = 0; i < kept_.size(); ++i) out.emplace_back(kept_call_[i], solve(kept_[i], kept_motion_[i], nullptr));
  kept_.clear(), kept_motion_.clear(), kept_call_.clear();
  return out;
}

RegistrationResult MotionRegistration::measure(const cv::Mat& bgr, const Similarity& start) const {
  return solve(read(bgr, start), start, nullptr);
}

}  // namespace clearfit
