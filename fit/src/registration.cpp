// Frame-to-reference motion on high-passed log red, from a grid of patches,
// combined by a robust similarity fit (see registration.hpp).
#include <clearfit/fit/glare.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/fit/srgb.hpp>

#include "spline_sampler.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
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

/// ln R − ρ·ln G of `bgr` over `r` (CV_32F, r's size).
cv::Mat registered_value(const cv::Mat& bgr, const cv::Rect& r, double green_ratio) {
  const auto& lut = log_table();
  const float rho = static_cast<float>(green_ratio);
  cv::Mat out(r.size(), CV_32F);
  for (int y = 0; y < r.height; ++y) {
    const auto* src = bgr.ptr<cv::Vec3b>(r.y + y) + r.x;
    auto* dst = out.ptr<float>(y);
    for (int x = 0; x < r.width; ++x) dst[x] = lut[src[x][2]] - rho * lut[src[x][1]];
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Robust fit of a similarity to patch centres `q` (relative to the similarity's centre) and their
/// translations `d` with their information (inverse covariance) `info`: IRLS with Tukey's biweight on the
/// residuals' Mahalanobis norms, started from the median translation. `full`: the fit with its turn and
/// scale even where they are not significant (six patches kept or more).
void fit_similarity(const std::vector<Vec2>& q, const std::vector<Vec2>& d, const std::vector<Eigen::Matrix2d>& info,
                    const RegistrationOptions& o, Similarity& s, std::vector<std::uint8_t>& inlier, Similarity& full) {
  const std::size_t n = q.size();
  std::vector<double> xs, ys;
  for (const Vec2& v : d) xs.push_back(v.x()), ys.push_back(v.y());
  s.t = Vec2(median(xs), median(ys));
  s.a = s.b = 0;
  std::vector<double> w(n, 1.0);
  auto rows = [&](std::size_t i) {  // d_i = E_i · (t, a, b)
    return (Eigen::Matrix<double, 2, 4>() << 1, 0, q[i].x(), -q[i].y(), 0, 1, q[i].y(), q[i].x()).finished();
  };
  auto residual = [&](std::size_t i, const Similarity& m) { return Vec2(d[i] - m.displacement(m.centre + q[i])); };
  // Normal equations of the weighted fit: with the turn and scale, and of the translation alone.
  Eigen::Matrix4d A;
  Eigen::Vector4d rhs;
  Eigen::Matrix2d At;
  Vec2 rhs_t;
  auto normal = [&] {
    A.setZero(), rhs.setZero(), At.setZero(), rhs_t.setZero();
    for (std::size_t i = 0; i < n; ++i) {
      if (w[i] <= 0) continue;
      const Eigen::Matrix<double, 2, 4> E = rows(i);
      A += w[i] * E.transpose() * info[i] * E, rhs += w[i] * E.transpose() * info[i] * d[i];
      At += w[i] * info[i], rhs_t += w[i] * info[i] * d[i];
    }
  };
  auto kept = [&] { return static_cast<int>(std::count_if(w.begin(), w.end(), [](double v) { return v > 0; })); };
  for (int it = 0; it < 20; ++it) {
    std::vector<double> r(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2 e = residual(i, s);
      r[i] = std::sqrt(std::max(0.0, e.dot(info[i] * e)));
    }
    // Robust σ of the normalised 2-D residuals: their median is σ·√(2 ln 2) for Gaussian errors; at least 1
    // (the patches' own precision).
    const double sigma = std::max(median(r) / std::sqrt(2 * std::log(2.0)), 1.0);
    const double cut = o.tukey_c * sigma;
    for (std::size_t i = 0; i < n; ++i) w[i] = r[i] < cut ? std::pow(1 - (r[i] / cut) * (r[i] / cut), 2) : 0.0;
    normal();
    if (kept() == 0) break;
    Similarity next = s;
    if (kept() >= 3) {
      const Eigen::Vector4d x = A.ldlt().solve(rhs);
      if (x.allFinite()) next.t = x.head<2>(), next.a = x[2], next.b = x[3];
    } else {
      next.t = At.ldlt().solve(rhs_t), next.a = next.b = 0;
    }
    const bool converged = (next.t - s.t).norm() < 1e-5 && std::abs(next.a - s.a) + std::abs(next.b - s.b) < 1e-8;
    s = next;
    if (converged && it > 0) break;
  }
  inlier.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) inlier[i] = w[i] > 0;
  normal();
  if (kept() == 0) return;
  const Vec2 translation = At.ldlt().solve(rhs_t);
  // Fewer than six patches kept (glare, blanching) leave a turn poorly held at the far corners.
  if (kept() < 6 || !translation.allFinite()) s.t = translation, s.a = s.b = 0;
  full = s;
  if (kept() < 6) return;
  // A turn and scale within their own uncertainty are noise: at the roi's corners they would double
  // it. Their covariance from the patches' information, scaled up by the residuals' excess scatter.
  double chi2 = 0, wsum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 e = residual(i, s);
    chi2 += w[i] * e.dot(info[i] * e), wsum += w[i];
  }
  const double scale = std::max(1.0, chi2 / std::max(2 * wsum - 4, 1.0));
  const Eigen::Matrix2d turn_cov = A.inverse().bottomRightCorner<2, 2>() * scale;
  const double z2min = o.turn_significance * o.turn_significance;
  // The scale (a) and the turn (b) each against its own standard error: a significant turn does not keep a
  // scale that is noise, nor the other way round.
  const bool scale_kept = s.a * s.a >= z2min * turn_cov(0, 0), turn_kept = s.b * s.b >= z2min * turn_cov(1, 1);
  if (!scale_kept && !turn_kept) {
    s.t = translation, s.a = s.b = 0;
  } else if (scale_kept != turn_kept) {
    // The one dropped held at no change (a turn alone: the scale at 1, a = cos θ − 1 for b = sin θ), the rest fitted again.
    const int fixed = scale_kept ? 3 : 2, free = 5 - fixed;
    const double value = scale_kept ? 0.0 : std::sqrt(std::max(0.0, 1 - s.b * s.b)) - 1;
    Eigen::Matrix3d R;
    Eigen::Vector3d r;
    const int idx[3] = {0, 1, free};
    for (int i = 0; i < 3; ++i) {
      r[i] = rhs[idx[i]] - A(idx[i], fixed) * value;
      for (int j = 0; j < 3; ++j) R(i, j) = A(idx[i], idx[j]);
    }
    const Eigen::Vector3d x = R.ldlt().solve(r);
    if (!x.allFinite()) {
      s.t = translation, s.a = s.b = 0;
      return;
    }
    s.t = x.head<2>();
    (scale_kept ? s.a : s.b) = x[2];
    (scale_kept ? s.b : s.a) = value;
  }
}

/// The motion `m` relative to `m0` (both about one centre): the content a frame moved by m0 shows at p is
/// seen by one moved by m at p + the result's displacement(p). Rotations and scales as complex numbers.
Similarity relative(const Similarity& m, const Similarity& m0) {
  const std::complex<double> z(1 + m.a, m.b), z0(1 + m0.a, m0.b), zr = z / z0;
  const std::complex<double> t = std::complex<double>(m.t.x(), m.t.y()) - zr * std::complex<double>(m0.t.x(), m0.t.y());
  Similarity r;
  r.centre = m.centre;
  r.t = Vec2(t.real(), t.imag());
  r.a = zr.real() - 1, r.b = zr.imag();
  return r;
}

/// `m` (CV_32F) without its frequencies above `max_frequency` (cycles/px, radial) and with white noise of
/// variance `noise_var` per pixel suppressed: a Wiener filter, each frequency kept in proportion S / (S + N),
/// S the signal's power (the periodogram, smoothed over neighbouring frequencies, less the noise's N).
/// `noise_var` 0 (not known: a template of one frame): the noise read from the periodogram's corners (both
/// frequencies above 0.35 cycles/px; their median over ln 2, for an unfiltered frame's white noise). Unfiltered,
/// one frame's noise made the gradient of a patch without texture look like texture: its standard error read
/// 0.11–0.13 px where it was 1.5–3.4 px off (textureless skin). Mirrored borders (no step at the edges).
cv::Mat wiener(const cv::Mat& m, double noise_var, double max_frequency, double* texture = nullptr) {
  const int pad = 8;
  const int rows = cv::getOptimalDFTSize(m.rows + 2 * pad), cols = cv::getOptimalDFTSize(m.cols + 2 * pad);
  cv::Mat padded, spectrum;
  cv::copyMakeBorder(m, padded, pad, rows - m.rows - pad, pad, cols - m.cols - pad, cv::BORDER_REFLECT_101);
  cv::dft(padded, spectrum, cv::DFT_COMPLEX_OUTPUT);
  cv::Mat parts[2];
  cv::split(spectrum, parts);
  cv::Mat power = parts[0].mul(parts[0]) + parts[1].mul(parts[1]), wrapped, smoothed;
  auto frequency = [&](int j, int i) {
    return Vec2(std::min(i, cols - i) / static_cast<double>(cols), std::min(j, rows - j) / static_cast<double>(rows));
  };
  double n = noise_var * rows * cols;
  if (!(noise_var > 0)) {
    std::vector<double> corner;
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < cols; ++i)
        if (frequency(j, i).minCoeff() > 0.35) corner.push_back(power.at<float>(j, i));
    n = median(corner) / std::log(2.0);
  }
  // The periodogram smoothed over its neighbours (it wraps around).
  cv::copyMakeBorder(power, wrapped, 3, 3, 3, 3, cv::BORDER_WRAP);
  cv::GaussianBlur(wrapped, smoothed, cv::Size(7, 7), 1.0);
  cv::Mat gain(rows, cols, CV_32F);
  double excess = 0, noise = 0;  // the power above the noise's, and the noise's, over the frequencies kept
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      const bool kept = frequency(j, i).norm() <= max_frequency;
      const double s = std::max(smoothed.at<float>(j + 3, i + 3) - n, 0.0);
      gain.at<float>(j, i) = kept ? static_cast<float>(s / (s + n)) : 0.f;
      if (kept) excess += power.at<float>(j, i) - n, noise += n;
    }
  if (texture) *texture = noise > 0 ? excess / noise : 0.0;
  parts[0] = parts[0].mul(gain), parts[1] = parts[1].mul(gain);
  cv::merge(parts, 2, spectrum);
  cv::Mat out;
  cv::idft(spectrum, out, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  return out(cv::Rect(pad, pad, m.cols, m.rows)).clone();
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
  rule(std::isfinite(max_frequency) && max_frequency >= 0.1 && max_frequency <= 0.71, "max_frequency", "must be in [0.1, 0.71] cycles/px");
  rule(spline_order == 3 || spline_order == 5, "spline_order", "must be 3 or 5");
  rule(reference_frames >= 1 && reference_frames <= 64, "reference_frames", "must be 1..64");
  rule(max_glare_fraction >= 0 && max_glare_fraction <= 1, "max_glare_fraction", "must be in [0, 1]");
  rule(glare_margin_px >= 0 && glare_margin_px <= 16, "glare_margin_px", "must be 0..16");
  rule(std::isfinite(tukey_c) && tukey_c > 1, "tukey_c", "must be > 1");
  rule(std::isfinite(min_sigma_px) && min_sigma_px > 0, "min_sigma_px", "must be > 0");
  rule(std::isfinite(max_sigma_px) && max_sigma_px > min_sigma_px, "max_sigma_px", "must be > min_sigma_px");
  rule(std::isfinite(min_texture) && min_texture >= 0, "min_texture", "must be >= 0");
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
    seen_map_ = cv::Mat::zeros(image, CV_8U);
    cv::erode(seen != 0, seen_map_(roi_), cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
    seen_ = seen_map_.clone();
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
  cache = skin_terms(region, shift, crop, {});
  return cache;
}

MotionRegistration::SkinBlur MotionRegistration::skin_terms(const cv::Rect& region, cv::Point shift, const cv::Rect& crop,
                                                            const cv::Mat& glare) const {
  // The skin in this frame: the seen mask moved with the frame (pixels off the image: none; no mask: all).
  SkinBlur fresh;  // new buffers: Regions handed out earlier keep theirs
  fresh.region = region, fresh.shift = shift, fresh.crop = crop;
  if (seen_.empty()) {
    fresh.skin = cv::Mat(region.size(), CV_32F, cv::Scalar(1));
  } else {
    fresh.skin = cv::Mat::zeros(region.size(), CV_32F);
    const cv::Rect from = (region - shift) & cv::Rect(0, 0, seen_.cols, seen_.rows);
    if (from.area() > 0) seen_(from).convertTo(fresh.skin(from + shift - region.tl()), CV_32F, 1.0 / 255);
  }
  if (!glare.empty()) fresh.skin.setTo(0, glare);
  cv::Mat mask = fresh.skin, mask_low;
  smooth(mask);
  // Only the crop is blurred; its support is read from the whole mask (as blurring all of it and cropping).
  cv::GaussianBlur(mask(crop), mask_low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
  fresh.mask_div = cv::max(mask(crop), 1e-3f);
  fresh.low_div = cv::max(mask_low, 1e-3f);
  fresh.on_skin = mask(crop) > 0.99f;
  fresh.off_skin = mask(crop) <= 0.f;
  return fresh;
}

void MotionRegistration::smooth(cv::Mat& m) const {
  if (options_.downsample == 2) cv::pyrDown(m, m);
  if (options_.smooth_sigma_px > 0) cv::GaussianBlur(m, m, cv::Size(), options_.smooth_sigma_px, 0, cv::BORDER_REPLICATE);
}

MotionRegistration::Region MotionRegistration::filtered(const cv::Mat& bgr, const cv::Rect& area_in, cv::Point shift,
                                                        SkinBlur& cache, const cv::Rect& patch) const {
  Region out;
  const int ds = options_.downsample;
  const cv::Rect image_reg(0, 0, bgr.cols / ds, bgr.rows / ds);
  const cv::Rect area = area_in & image_reg;
  if (area.area() == 0) return out;
  // Full-resolution region: the area plus the filters' support (clipped to the image; even for pyrDown).
  cv::Rect region(ds * (area.x - border_), ds * (area.y - border_), ds * (area.width + 2 * border_), ds * (area.height + 2 * border_));
  region &= cv::Rect(0, 0, image_reg.width * ds, image_reg.height * ds);
  // Glare and its margin, where the fit reads (the area): off the skin in this frame; the patch left out when its
  // template area is mostly that.
  cv::Mat glare;
  const cv::Rect read_area = cv::Rect(ds * area.x, ds * area.y, ds * area.width, ds * area.height) & region;
  const cv::Mat found = glare_pixels(bgr, patch, read_area);
  if (cv::countNonZero(found) > 0) {
    glare = cv::Mat::zeros(region.size(), CV_8U);
    found.copyTo(glare(read_area - region.tl()));
    const int m = ds * options_.glare_margin_px;
    if (m > 0) cv::dilate(glare, glare, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * m + 1, 2 * m + 1)));
    const cv::Rect in = (patch & region) - region.tl();
    if (cv::countNonZero(glare(in)) > options_.max_glare_fraction * patch.area()) {
      out.glare = true;
      return out;
    }
  }
  cv::Mat full = registered_value(bgr, region, options_.green_ratio);
  const cv::Rect crop = area - region.tl() / ds;  // the area in the (smoothed) region
  out.origin = area.tl();
  // The high-pass is read over the crop only; the Gaussian's support comes from the whole region
  // (OpenCV reads a submatrix's surroundings from its parent), so the crop is as if all were blurred.
  cv::Mat low;
  if (seen_.empty() && glare.empty()) {
    smooth(full);
    cv::GaussianBlur(full(crop), low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
    out.f = full(crop) - low;
    return out;
  }
  // Normalised convolution: the skin's own smoothing, so what lies beyond its edge does not leak in.
  // The skin's terms change only when the region or the frame's integer shift does (cached per patch).
  // Glare's terms are the frame's own (not cached).
  SkinBlur own;
  if (!glare.empty()) own = skin_terms(region, shift, crop, glare);
  const SkinBlur& skin = glare.empty() ? skin_blur(region, shift, crop, cache) : own;
  cv::Mat reg = full.mul(skin.skin);
  smooth(reg);
  cv::GaussianBlur(reg(crop), low, cv::Size(), options_.highpass_sigma_px, 0, cv::BORDER_REPLICATE);
  out.f = reg(crop) / skin.mask_div - low / skin.low_div;
  out.f.setTo(0, skin.off_skin);  // off the skin: the high-pass's mean (a step there would ring through the splines)
  out.skin = skin.on_skin;
  if (!glare.empty()) {
    cv::Mat g;
    glare.convertTo(g, CV_32F);
    smooth(g);
    out.glare_mask = g(crop) > 0.f;
  }
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

cv::Point MotionRegistration::whole_shift(std::size_t k, const Similarity& m) const {
  const cv::Rect& a = patches_[k].area;
  const Vec2 centre(a.x + 0.5 * a.width, a.y + 0.5 * a.height), shift = m.displacement(options_.downsample * centre) / options_.downsample;
  return {static_cast<int>(std::lround(shift.x())), static_cast<int>(std::lround(shift.y()))};
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
    const cv::Point moved = whole_shift(k, expected);
    const cv::Rect full_res(ds * (p.area.x + moved.x), ds * (p.area.y + moved.y), ds * p.area.width, ds * p.area.height);
    g = filtered(bgr, box, cv::Point(ds * moved.x, ds * moved.y), skin_blur_[k], full_res);
    if (g.glare || g.f.empty()) return;
    g.coef = g.f.clone();
    SplineSampler(options_.spline_order).coefficients(g.coef);
  });
  return regions;
}

namespace {

/// A template's sums (`s` a MotionRegistration patch or a TemplateFit): h = Σ j·∇t, m = Σ j·jᵀ, Σ t², Σ tf², the
/// pixels that count; whether they hold a fit (a well-conditioned h, some texture).
template <class S>
bool fill_sums(S& s) {
  s.h[0] = s.jx.dot(s.tx), s.h[1] = s.jx.dot(s.ty), s.h[2] = s.jy.dot(s.tx), s.h[3] = s.jy.dot(s.ty);
  s.m[0] = s.jx.dot(s.jx), s.m[1] = s.jx.dot(s.jy), s.m[2] = s.jy.dot(s.jy);
  s.tt = s.t.dot(s.t), s.ff = s.tf.dot(s.tf), s.pixels = cv::countNonZero(s.weight);
  const double det = s.h[0] * s.h[3] - s.h[1] * s.h[2];
  return std::isfinite(det) && det > 1e-12 * (s.h[0] + s.h[3]) * (s.h[0] + s.h[3]) && s.tt > 0 && s.ff > 0;
}

/// The translation (registration px) that moves a region onto a template: Gauss–Newton on the
/// zero-mean, gain-normalised difference, the region's spline (`coef`) sampled at `base` + the
/// translation (SplineSampler), the Jacobian the gradient of the template's noise-filtered spline (jx, jy;
/// `h` its products with the template's own gradient, `m` with itself). Its fixed
/// point is the peak of the cross-correlation: a Jacobian with the sample's gradient in it (efficient
/// second-order minimisation) also descends the sample's own power, which interpolation changes with
/// the fractional shift (measured: noise as strong as the texture pulled patches 0.3–0.5 px towards
/// half-pixel shifts). `linear` maps a step in the template's coordinates to one in the region's.
/// Returns false when the region runs out or the correlation is lost.
struct TemplateFit {
  cv::Mat t, tx, ty, jx, jy, tf;
  cv::Mat weight;  ///< CV_8U: the pixels that count
  double h[4] = {0, 0, 0, 0};
  double m[3] = {0, 0, 0};
  double tt = 0, ff = 0, pixels = 0;
  /// The fit without the pixels `off` (CV_8U, 255: left out): the template and its filtered copy zero-mean
  /// over the rest, the Jacobian 0 on them; its sums are to be made again (fill_sums).
  TemplateFit without(const cv::Mat& off) const {
    TemplateFit r = *this;
    r.weight = weight.clone();
    r.weight.setTo(0, off);
    const cv::Mat out = r.weight == 0;
    auto zero_mean = [&](const cv::Mat& v) {
      cv::Mat z = v - cv::mean(v, r.weight)[0];
      z.setTo(0, out);
      return z;
    };
    r.t = zero_mean(t), r.tf = zero_mean(tf), r.jx = jx.clone(), r.jy = jy.clone();
    r.jx.setTo(0, out), r.jy.setTo(0, out);
    return r;
  }
  /// `cov`: the translation's covariance (registration px²), from the residual's variance.
  bool run(const SplineSampler& spline, const cv::Mat& coef, const cv::Mat& base_x, const cv::Mat& base_y, const Eigen::Matrix2d& linear,
           bool uniform, int iterations, Vec2& delta, double& gain, Eigen::Matrix2d& cov) const {
    cv::Mat w, e;
    const Eigen::Matrix2d hessian = (Eigen::Matrix2d() << h[0], h[1], h[2], h[3]).finished();
    for (int it = 0; it < iterations; ++it) {
      if (!spline.sample(coef, base_x, base_y, delta.x(), delta.y(), uniform, w)) return false;
      w = w - cv::mean(w, weight)[0];
      gain = w.dot(t) / tt;
      if (!(gain > 0)) return false;
      e = w - gain * t;
      // The step is scaled by the frame's contrast against the filtered template, not by `gain`: against a
      // noisy template (one frame, on dark skin) `gain` is biased low by the template's noise (in Σ t²), and
      // steps too long by as much do not converge. The Wiener filter's output predicts the texture without that
      // bias (Σ tf·T ≈ Σ tf²). Measured: dark skin held still read 0.09–0.11 px, 0.06–0.09 px with it.
      const double contrast = w.dot(tf) / ff;
      if (!(contrast > 0)) return false;
      Vec2 step = hessian.partialPivLu().solve(Vec2(jx.dot(e), jy.dot(e))) / contrast;
      if (!step.allFinite()) return false;
      if (step.norm() > 1) step /= step.norm();
      delta -= linear * step;
      if (step.norm() < 1e-3) break;
    }
    const double s2 = cv::norm(e, cv::NORM_L2SQR, weight) / std::max(pixels - 3, 1.0);
    const Eigen::Matrix2d hi = hessian.inverse(), jj = (Eigen::Matrix2d() << m[0], m[1], m[1], m[2]).finished();
    cov = hi * jj * hi.transpose() * s2 / (gain * gain);
    return true;
  }
};

}  // namespace

RegistrationResult MotionRegistration::solve(const Regions& regions, const Similarity& start_in, Similarity* whole) const {
  RegistrationResult res;
  const std::size_t n = patches_.size();
  const int ds = options_.downsample;
  const SplineSampler spline(options_.spline_order);
  // The start, about the roi's centre.
  Similarity start = start_in;
  start.centre = Vec2(roi_.x + 0.5 * roi_.width, roi_.y + 0.5 * roi_.height);
  start.t = start_in.displacement(start.centre);
  if (!(start.t.allFinite() && std::isfinite(start.a) && std::isfinite(start.b))) start.t.setZero(), start.a = start.b = 0;
  res.motion = start;
  res.glare.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) res.glare[k] = regions[k].glare;
  std::vector<Vec2> delta(n, Vec2::Zero());
  std::vector<Eigen::Matrix2d> cov(n, Eigen::Matrix2d::Identity());
  std::vector<double> gain(n, 1.0);
  std::vector<std::uint8_t> ok(n, 0), inlier;
  auto centre_of = [&](std::size_t k) {  // the template's centre, full-resolution px
    const cv::Rect& a = patches_[k].area;
    return Vec2(ds * (a.x + 0.5 * (a.width - 1)), ds * (a.y + 0.5 * (a.height - 1)));
  };
  Similarity s = start, full = start;
  for (int pass = 0; pass < 4; ++pass) {
    const Eigen::Matrix2d linear = (Eigen::Matrix2d() << 1 + s.a, -s.b, s.b, 1 + s.a).finished();
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t k) {
      const Patch& p = patches_[k];
      ok[k] = 0;
      if (!p.usable || regions[k].f.empty()) return;
      cv::Mat bx, by;
      base_maps(k, regions[k].origin, s, 0, bx, by);
      TemplateFit f{p.t, p.tx, p.ty, p.jx, p.jy, p.tf, p.weight, {p.h[0], p.h[1], p.h[2], p.h[3]}, {p.m[0], p.m[1], p.m[2]}, p.tt, p.ff, p.pixels};
      // The frame's glare (with the gradients' reach) left out of this frame's fit: its sums over the rest.
      if (!regions[k].glare_mask.empty()) {
        f = f.without(glare_reach(regions[k], bx, by));
        if (!fill_sums(f)) return;
      }
      Vec2 d = Vec2::Zero();
      if (!f.run(spline, regions[k].coef, bx, by, linear, uniform(k, s), options_.iterations, d, gain[k], cov[k]) || d.norm() >= 4)
        return;  // lost
      // Found, but not to max_sigma_px: no texture this frame can be registered by (its noise alone pulled it).
      if (ds * std::sqrt(std::max(cov[k](0, 0), cov[k](1, 1))) > options_.max_sigma_px) ok[k] = 2;
      else delta[k] = d, ok[k] = 1;
    });
    for (std::uint8_t& o : ok) o = o == 1;
    std::vector<Vec2> q, d;
    std::vector<Eigen::Matrix2d> info;
    std::vector<std::size_t> index;
    for (std::size_t k = 0; k < n; ++k)
      if (ok[k]) {
        const Vec2 c = centre_of(k);
        q.push_back(c - s.centre);
        d.push_back(s.displacement(c) + ds * delta[k]);
        // Overlapping patches share their pixels' noise: each counts for its share of them.
        double shared = 1;
        for (std::size_t j = 0; j < n; ++j)
          if (j != k && ok[j]) shared += static_cast<double>((rects_[k] & rects_[j]).area()) / rects_[k].area();
        const Eigen::Matrix2d c2 = cov[k] * (ds * ds * shared);
        const double floor = options_.min_sigma_px * options_.min_sigma_px;
        info.push_back(c2.allFinite() && c2.determinant() > 0 ? Eigen::Matrix2d((c2 + floor * Eigen::Matrix2d::Identity()).inverse())
                                                               : Eigen::Matrix2d(Eigen::Matrix2d::Identity() / floor));
        index.push_back(k);
      }
    res.patches = static_cast<int>(q.size());
    if (!q.empty()) textured_ = true;
    res.patch_shift.assign(n, Vec2::Constant(kNaN));
    for (std::size_t i = 0; i < index.size(); ++i) res.patch_shift[index[i]] = d[i];
    if (q.empty()) {
      res.motion.t = Vec2::Constant(kNaN);
      res.inlier.assign(n, 0);
      // None ever was registered, and the first frame's patches hold little more than their noise.
      std::vector<double> texture;
      for (const Patch& p : patches_)
        if (p.usable) texture.push_back(p.texture);
      res.no_texture = !textured_ && !texture.empty() && median(texture) < options_.min_texture;
      return res;
    }
    Similarity next;
    next.centre = s.centre;
    fit_similarity(q, d, info, options_, next, inlier, full);
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
  if (whole) *whole = full;
  return res;
}

void MotionRegistration::base_maps(std::size_t k, cv::Point origin, const Similarity& s, int apron, cv::Mat& bx, cv::Mat& by) const {
  const int ds = options_.downsample;
  const cv::Rect& a = patches_[k].area;
  bx.create(a.height + 2 * apron, a.width + 2 * apron, CV_32F), by.create(bx.size(), CV_32F);
  for (int j = 0; j < bx.rows; ++j)
    for (int i = 0; i < bx.cols; ++i) {
      const Vec2 x(a.x - apron + i, a.y - apron + j);
      const Vec2 m = x + s.displacement(ds * x) / ds;
      bx.at<float>(j, i) = static_cast<float>(m.x() - origin.x), by.at<float>(j, i) = static_cast<float>(m.y() - origin.y);
    }
}

bool MotionRegistration::uniform(std::size_t k, const Similarity& m) const {
  return (std::abs(m.a) + std::abs(m.b)) * options_.downsample * 0.5 * (patches_[k].area.width + patches_[k].area.height) < 0.01;
}

cv::Mat MotionRegistration::glare_reach(const Region& region, const cv::Mat& bx, const cv::Mat& by) const {
  cv::Mat off;
  cv::remap(region.glare_mask, off, bx, by, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::dilate(off, off, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * kApron + 3, 2 * kApron + 3)));
  return off;
}

std::vector<cv::Mat> MotionRegistration::warp_back(const Regions& regions, const Similarity& motion, const std::vector<std::uint8_t>& keep,
                                                   std::vector<cv::Mat>* glare) const {
  const SplineSampler spline(options_.spline_order);
  std::vector<cv::Mat> warped(patches_.size());
  if (glare) glare->assign(patches_.size(), cv::Mat());
  tbb::parallel_for(std::size_t(0), patches_.size(), [&](std::size_t k) {
    if (k >= keep.size() || !keep[k] || regions[k].coef.empty()) return;
    cv::Mat bx, by, w;
    base_maps(k, regions[k].origin, motion, kApron, bx, by);
    if (!spline.sample(regions[k].coef, bx, by, 0, 0, uniform(k, motion), w)) return;
    const cv::Rect in(kApron, kApron, patches_[k].area.width, patches_[k].area.height);
    if (glare && !regions[k].glare_mask.empty()) (*glare)[k] = glare_reach(regions[k], bx, by)(in).clone();
    // Not divided by the patch's gain: in logarithms the texture's contrast does not change with the light,
    // and a gain read against a noisy average is biased low (dividing by it weighted later frames' noise up).
    warped[k] = w - cv::mean(w)[0];
  });
  return warped;
}

void MotionRegistration::accumulate(const std::vector<cv::Mat>& warped, const std::vector<cv::Mat>* glare) {
  tbb::parallel_for(std::size_t(0), patches_.size(), [&](std::size_t k) {
    Patch& p = patches_[k];
    if (warped[k].empty()) return;
    if (glare && !(*glare)[k].empty() && !p.weight.empty()) {  // new buffers: copies of the patch keep theirs
      p.weight = p.weight.clone();
      p.weight.setTo(0, (*glare)[k]);
    }
    if (p.sum.empty()) p.sum = warped[k].clone(), p.sq = warped[k].mul(warped[k]);
    else p.sum += warped[k], p.sq += warped[k].mul(warped[k]);
    ++p.count;
    refresh(p);
  });
}

void MotionRegistration::refresh(Patch& p) const {
  p.usable = false;
  if (p.count < 1) return;
  const SplineSampler spline(options_.spline_order);
  const cv::Mat avg = p.sum / p.count;
  const cv::Rect in(kApron, kApron, p.area.width, p.area.height);
  const cv::Mat off = p.weight == 0;
  // The average's noise: the frames' spread about it, over their count.
  double noise = 0;  // one frame: no spread to read it from (the frames averaged later are measured again)
  if (p.count > 1) {
    const cv::Mat var = (p.sq / p.count - avg.mul(avg)) * (p.count / (p.count - 1.0));
    noise = cv::mean(var(in), p.weight)[0] / p.count;
  }
  // The gradient of a spline (the interpolant the frames are sampled with).
  auto gradient = [&](const cv::Mat& m, cv::Mat& gx, cv::Mat& gy) {
    cv::Mat coef = m.clone();
    spline.coefficients(coef);
    spline.gradient(coef, gx, gy);
    gx = gx(in).clone(), gy = gy(in).clone();
    gx.setTo(0, off), gy.setTo(0, off);
  };
  // `m` over the template, its mean over the skin taken out, 0 off the skin.
  auto zero_mean = [&](const cv::Mat& m) {
    cv::Mat z = m(in) - cv::mean(m(in), p.weight)[0];
    z.setTo(0, off);
    return z;
  };
  p.t = zero_mean(avg);
  gradient(avg, p.tx, p.ty);
  double texture = 0;
  const cv::Mat filtered = wiener(avg, noise, options_.max_frequency, &texture);
  gradient(filtered, p.jx, p.jy);
  p.tf = zero_mean(filtered);
  if (p.count == 1) p.texture = texture;
  p.usable = fill_sums(p);
}

void MotionRegistration::restrict_to_skin(const cv::Mat& bgr) {
  if (seen_map_.empty()) return;
  seen_ = seen_map_.clone();
  for (SkinBlur& c : skin_blur_) c = SkinBlur{};
  // The registered value (ln R − ρ·ln G) over the roi, its noise and finest texture taken out by a 5 × 5 median.
  cv::Mat v = registered_value(bgr, roi_, options_.green_ratio);
  cv::medianBlur(v, v, 5);
  const cv::Mat seen = seen_map_(roi_);
  std::vector<double> on;
  for (int y = 0; y < v.rows; ++y)
    for (int x = 0; x < v.cols; ++x)
      if (seen.at<std::uint8_t>(y, x)) on.push_back(v.at<float>(y, x));
  if (on.empty()) return;
  const double mid = median(on);
  for (double& e : on) e = std::abs(e - mid);
  // Far darker than the skin the map sees (a factor e^0.5 at least, and six of the skin's robust spreads): not skin.
  const double cut = std::max(0.5, 6 * 1.4826 * median(on));
  cv::Mat dark = v < static_cast<float>(mid - cut);
  cv::dilate(dark, dark, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  seen_(roi_).setTo(0, dark);
}

void MotionRegistration::set_reference(const cv::Mat& bgr) {
  if (bgr.type() != CV_8UC3 || bgr.size() != image_)
    throw std::invalid_argument("MotionRegistration: frames must be 8-bit BGR of the registration's image size");
  restrict_to_skin(bgr);
  for (Patch& p : patches_) {
    Patch fresh;
    fresh.area = p.area;
    p = fresh;
  }
  kept_.clear(), kept_warped_.clear(), kept_motion_.clear(), kept_call_.clear();
  calls_ = 0;
  frames_averaged_ = 0;
  textured_ = false;
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
  kept_warped_.push_back(std::move(warped));
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
  // Moved back by the whole motion, its turn and scale kept even when they are not significant: a turn
  // dropped from each frame averaged would turn the reference by their mean (measured: the 0.5° test
  // turn read 0.0006 rad short). The patch's own residual translation (its noise) is left in.
  Similarity whole;
  RegistrationResult r = solve(regions, start, &whole);
  if (r.found) {
    std::vector<cv::Mat> glare;
    std::vector<cv::Mat> warped = warp_back(regions, whole, r.inlier, &glare);
    accumulate(warped, &glare);
    ++frames_averaged_;
    kept_.push_back(std::move(regions));
    kept_warped_.push_back(std::move(warped));
    kept_motion_.push_back(whole);
    kept_call_.push_back(calls_);
  }
  ++calls_;
  return r;
}

std::vector<std::pair<int, RegistrationResult>> MotionRegistration::close_reference() {
  std::vector<std::pair<int, RegistrationResult>> out;
  open_ = false;
  std::vector<RegistrationResult> first(kept_.size());
  std::vector<Similarity> whole(kept_.size());
  if (kept_.size() < 2) {
    for (std::size_t i = 0; i < kept_.size(); ++i) first[i] = solve(kept_[i], kept_motion_[i], &whole[i]);
  } else {
    // Each frame against the average of the others: a frame's own noise in the average would hold it where
    // it was put while averaging.
    const std::vector<Patch> all = patches_;
    for (std::size_t i = 0; i < kept_.size(); ++i) {
      tbb::parallel_for(std::size_t(0), patches_.size(), [&](std::size_t k) {
        const cv::Mat& w = kept_warped_[i][k];
        if (w.empty()) {
          patches_[k] = all[k];
          return;
        }
        Patch p;  // new buffers (a matrix expression assigned to a shared one would write into `all`)
        p.area = all[k].area, p.weight = all[k].weight;
        p.sum = all[k].sum - w, p.sq = all[k].sq - w.mul(w), p.count = all[k].count - 1;
        refresh(p);
        patches_[k] = p;
      });
      first[i] = solve(kept_[i], kept_motion_[i], &whole[i]);
    }
    patches_ = all;
  }
  if (kept_.size() > 1 && first[0].found) {
    for (Patch& p : patches_) p.sum.release(), p.sq.release(), p.count = 0;
    for (std::size_t i = 0; i < kept_.size(); ++i)
      if (first[i].found) {
        std::vector<std::uint8_t> keep = first[i].inlier;
        if (i == 0) keep.assign(patches_.size(), 1);
        kept_motion_[i] = relative(whole[i], whole[0]);
        std::vector<cv::Mat> glare;
        const std::vector<cv::Mat> warped = warp_back(kept_[i], kept_motion_[i], keep, &glare);
        accumulate(warped, &glare);
      }
  }
  for (std::size_t i = 0; i < kept_.size(); ++i) out.emplace_back(kept_call_[i], solve(kept_[i], kept_motion_[i]));
  kept_.clear(), kept_warped_.clear(), kept_motion_.clear(), kept_call_.clear();
  return out;
}

RegistrationResult MotionRegistration::measure(const cv::Mat& bgr, const Similarity& start) const {
  const RegistrationResult r = solve(read(bgr, start), start);
  // The skin's terms (the seen mask, moved by whole pixels) lie where the start put each patch: a frame that moved a
  // patch to another whole pixel is read again where it is (measured: the skin's edge, that far off, pulled a 0.6 px
  // tremor's frames by up to 0.07 px across its steps).
  if (!r.found) return r;
  for (std::size_t k = 0; k < patches_.size(); ++k)
    if (patches_[k].usable && whole_shift(k, r.motion) != whole_shift(k, start)) return solve(read(bgr, r.motion), r.motion);
  return r;
}

}  // namespace clearfit
