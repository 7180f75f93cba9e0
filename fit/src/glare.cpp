// Glare on the clear part: detection in the window averages, its chart
// texels, and hotspots that touch it (see glare.hpp).
#include <clearfit/fit/glare.hpp>
#include "masked_smoothing.hpp"
#include <clearfit/format.hpp>
#include <clearfit/fit/photometric.hpp>
#include <clearfit/fit/srgb.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace clearfit {
namespace {

std::string fmt(double v, int digits) { return fixed_digits(v, digits); }

double median_of(std::vector<float> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Values of `m` where `valid` is set.
std::vector<float> values(const cv::Mat& m, const cv::Mat& valid) {
  std::vector<float> v;
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      if (valid.at<std::uint8_t>(y, x)) v.push_back(m.at<float>(y, x));
  return v;
}

/// Robust σ (1.4826 MAD) of `m` over `valid`.
double robust_sigma(const cv::Mat& m, const cv::Mat& valid) {
  std::vector<float> v = values(m, valid);
  const double med = median_of(v);
  for (float& x : v) x = static_cast<float>(std::abs(x - med));
  return 1.4826 * median_of(std::move(v));
}

/// Green on the half-resolution grid: the mean of the two pixels blue was read at.
cv::Mat half_green(const cv::Mat& green) {
  const cv::Size h = half_grid(green.size());
  cv::Mat out(h, CV_32F);
  for (int j = 0; j < h.height; ++j)
    for (int i = 0; i < h.width; ++i) {
      const int y = 2 * j, x = 2 * i, x1 = std::min(x + 1, green.cols - 1);
      out.at<float>(j, i) = 0.5f * (green.at<float>(y, x) + green.at<float>(y, x1));
    }
  return out;
}

/// ρ: the median ratio ΔlnB/ΔlnG over clearly blanched pixels whose ratio lies below the
/// midpoint between the default ρ and glare's 1/c; nullopt when fewer than 50 such pixels.
std::optional<double> measure_blanching_ratio(const cv::Mat& dg, const cv::Mat& db, const cv::Mat& valid, double sigma_g,
                                              double rho0, double inv_c) {
  const double floor = std::max(6 * sigma_g, 0.01), mid = 0.5 * (rho0 + inv_c);
  std::vector<float> r;
  for (int y = 0; y < dg.rows; ++y)
    for (int x = 0; x < dg.cols; ++x) {
      const float g = dg.at<float>(y, x);
      if (!valid.at<std::uint8_t>(y, x) || g < floor) continue;
      const float q = db.at<float>(y, x) / g;
      if (q < mid && q > -0.5f) r.push_back(q);
    }
  if (r.size() < 50) return std::nullopt;
  return std::clamp(median_of(std::move(r)), -0.2, 0.8);
}

/// The seen pixels within `width` (half-resolution) pixels of an unseen one: the seen skin's outline. A pixel
/// there holds skin and what lies beside the part, in shares that differ between the phases (the camera's move,
/// a held baseline's own map) and within a phase (motion blur). Its colour changes as glare's does: the
/// wristband's realistic preset, without any glare, had |γ| at or above the threshold on 11, 5 and 2 % of the
/// pixels 1, 2 and 3 half-resolution pixels from the outline (the smoothing carrying it in) and on none farther.
cv::Mat outline_band(const cv::Mat& valid, double width) {
  cv::Mat dist;
  cv::distanceTransform(valid, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::Mat band = dist <= width;
  cv::bitwise_and(band, valid, band);
  return band;
}

/// The mask grown by `margin_px`, and each region of `labels_half` (the half grid's labels) by its own `tail`
/// (camera px) where that is more. A highlight fades into the skin, and the faint light of its tail, below what
/// the detection sees pixel by pixel, still shows in the signal averaged over many pixels where the phases see a
/// texel at different pixels (a held baseline): the wristband's realistic preset at half resolution had a false
/// 0.19 mm² place at the edge of the camera's fixed highlight with the 6 px margin alone. How far the light
/// reaches is measured (measured_tails): a margin proportional to the region's size masked too much of large,
/// bright highlights, whose light falls off steeply at the detection's edge.
cv::Mat grow_by_margin(const cv::Mat& mask, int margin_px, const cv::Mat& labels_half = {}, const std::vector<double>& tail = {}) {
  cv::Mat out;
  const int m = margin_px;
  if (m > 0) cv::dilate(mask, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * m + 1, 2 * m + 1)));
  else out = mask.clone();
  if (tail.empty() || *std::max_element(tail.begin(), tail.end()) <= m) return out;
  // Regions whose light reaches beyond the fixed margin: each pixel within its tail of its nearest masked pixel.
  cv::Mat dist, nearest;
  cv::distanceTransform(~mask, dist, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<int> region_of_label;  // distanceTransform's label of a masked pixel -> its region (the half grid's label)
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (mask.at<std::uint8_t>(y, x)) {
        const int k = nearest.at<int>(y, x);
        if (k >= static_cast<int>(region_of_label.size())) region_of_label.resize(k + 1, 0);
        region_of_label[k] = labels_half.at<int>(y / 2, x / 2);
      }
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      const int k = nearest.at<int>(y, x);
      const int region = k < static_cast<int>(region_of_label.size()) ? region_of_label[k] : 0;
      if (region > 0 && tail[region] > m && dist.at<float>(y, x) <= tail[region]) out.at<std::uint8_t>(y, x) = 255;
    }
  return out;
}

/// The glare's light around each kept region, measured: the region's own measure of light (w/G: the static
/// score of both phases for a highlight in both, ±γ for one in a single phase) averaged over rings one
/// half-resolution pixel wide around it (the inner pixels nearest to it), out to the first ring whose mean is
/// below its level: `tail_light` for a highlight in both phases (it only dims the signal, but where the phases see
/// a texel at different pixels its gradient reads as a change), half of `min_change` for one that changes between
/// the phases (that light reads as pressure). The bundled sample at full scale: with 0.01 for both, two false
/// 0.08 mm² places at the edges of highlights that appear when worn (their light fell from 1 % to 0.1 % over 12-24
/// rings beyond the detection); with the changing one's level, none for a static level of 0.003-0.01 (Pearson
/// 0.992, 29-25 % of the seen skin masked), Pearson 0.976 at 0.02. Returns, per label of `labels`, that reach in camera pixels (at most the region's radius,
/// its largest inside distance, or the fixed margin where that is more); 0 for labels not kept.
std::vector<double> measured_tails(const cv::Mat& labels, const std::vector<char>& keep, const cv::Mat& mask_half, const cv::Mat& inner,
                                   const std::array<cv::Mat, 3>& light, const cv::Mat& phase0, const cv::Mat& phase1,
                                   const GlareOptions& o) {
  const int n = static_cast<int>(keep.size());
  std::vector<long> size(n, 0), in0(n, 0), in1(n, 0);
  std::vector<double> radius(n, 0);  // half-grid pixels
  cv::Mat inside, dist, nearest;
  cv::distanceTransform(mask_half, inside, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  for (int j = 0; j < labels.rows; ++j)
    for (int i = 0; i < labels.cols; ++i)
      if (const int l = labels.at<int>(j, i); l > 0 && keep[l]) {
        ++size[l], in0[l] += phase0.at<std::uint8_t>(j, i) != 0, in1[l] += phase1.at<std::uint8_t>(j, i) != 0;
        radius[l] = std::max(radius[l], static_cast<double>(inside.at<float>(j, i)));
      }
  // Which measure: 0 both phases (mean static), 1 the worn one (γ), 2 the baseline (−γ).
  std::vector<int> kind(n, 0);
  for (int l = 1; l < n; ++l)
    if (keep[l] && !(in0[l] >= 0.3 * size[l] && in1[l] >= 0.3 * size[l])) kind[l] = in1[l] >= in0[l] ? 1 : 2;
  const double fixed_half = 0.5 * o.margin_px;
  int rings = 1;
  for (int l = 1; l < n; ++l)
    if (keep[l]) rings = std::max(rings, static_cast<int>(std::ceil(std::max(radius[l], fixed_half))));
  cv::distanceTransform(~mask_half, dist, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<int> region_of_label;
  for (int j = 0; j < labels.rows; ++j)
    for (int i = 0; i < labels.cols; ++i)
      if (mask_half.at<std::uint8_t>(j, i)) {
        const int k = nearest.at<int>(j, i);
        if (k >= static_cast<int>(region_of_label.size())) region_of_label.resize(k + 1, 0);
        region_of_label[k] = labels.at<int>(j, i);
      }
  std::vector<double> sum(static_cast<std::size_t>(n) * (rings + 1), 0), count(sum.size(), 0);
  for (int j = 0; j < labels.rows; ++j)
    for (int i = 0; i < labels.cols; ++i) {
      if (mask_half.at<std::uint8_t>(j, i) || !inner.at<std::uint8_t>(j, i)) continue;
      const int ring = static_cast<int>(std::ceil(dist.at<float>(j, i))), k = nearest.at<int>(j, i);
      const int l = k < static_cast<int>(region_of_label.size()) ? region_of_label[k] : 0;
      if (l <= 0 || ring < 1 || ring > rings) continue;
      const double e = kind[l] == 0 ? 0.5 * (light[0].at<float>(j, i) + light[1].at<float>(j, i))
                                    : (kind[l] == 1 ? 1.0 : -1.0) * light[2].at<float>(j, i);
      sum[l * (rings + 1) + ring] += e, count[l * (rings + 1) + ring] += 1;
    }
  std::vector<double> tail(n, 0);
  for (int l = 1; l < n; ++l) {
    if (!keep[l]) continue;
    const int cap = static_cast<int>(std::ceil(std::max(radius[l], fixed_half)));
    const double level = kind[l] == 0 ? o.tail_light : 0.5 * o.min_change;
    int reach = cap;
    for (int ring = 1; ring <= cap; ++ring) {
      const double c = count[l * (rings + 1) + ring];
      if (c >= 8 && sum[l * (rings + 1) + ring] / c < level) {
        reach = ring;
        break;
      }
    }
    tail[l] = 2.0 * reach;
  }
  return tail;
}

}  // namespace

void GlareOptions::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(std::string("assess.glare.") + field + " = " + fmt(v, 4) + ": " + rule);
  };
  check(threshold_sigmas >= 2 && threshold_sigmas <= 100, "threshold_sigmas", threshold_sigmas, "must be in [2, 100]");
  check(min_change > 0 && min_change < 1, "min_change", min_change, "must be in (0, 1)");
  check(min_static > 0 && min_static < 10, "min_static", min_static, "must be in (0, 10)");
  check(saturation > 0.5 && saturation <= 1, "saturation", saturation, "must be in (0.5, 1]");
  check(smooth_px >= 0 && smooth_px <= 20, "smooth_px", smooth_px, "must be in [0, 20]");
  check(margin_px >= 0 && margin_px <= 200, "margin_px", margin_px, "must be in [0, 200]");
  check(tail_light >= 0 && tail_light <= 0.5, "tail_light", tail_light, "must be in [0, 0.5] (0: the fixed margin only)");
  check(outline_band_px >= 0 && outline_band_px <= 50, "outline_band_px", outline_band_px, "must be in [0, 50]");
  check(max_fraction > 0 && max_fraction <= 1, "max_fraction", max_fraction, "must be in (0, 1]");
  check(blanching_ratio > -0.5 && blanching_ratio < 0.9, "blanching_ratio", blanching_ratio, "must be in (-0.5, 0.9)");
}

GlareMask detect_glare(const PhaseAverage& base, const PhaseAverage& worn, const cv::Mat& seen, const GlareOptions& o) {
  GlareMask out;
  if (!o.enabled || base.blue_half.empty() || worn.blue_half.empty()) return out;
  o.validate();
  out.roi = base.roi;
  const cv::Size half = base.blue_half.size();
  const cv::Mat g0 = half_green(base.mean), g1 = half_green(worn.mean);
  const cv::Mat& b0 = base.blue_half;
  const cv::Mat& b1 = worn.blue_half;
  // Pixels that see the skin (both of the pair) and are not black in any channel.
  cv::Mat valid(half, CV_8U);
  for (int j = 0; j < half.height; ++j)
    for (int i = 0; i < half.width; ++i) {
      const int x = 2 * i, x1 = std::min(x + 1, seen.cols - 1);
      const bool lit = std::min({g0.at<float>(j, i), g1.at<float>(j, i), b0.at<float>(j, i), b1.at<float>(j, i)}) > 1e-3f;
      valid.at<std::uint8_t>(j, i) = seen.at<std::uint8_t>(2 * j, x) && seen.at<std::uint8_t>(2 * j, x1) && lit ? 255 : 0;
    }
  const int n_valid = cv::countNonZero(valid);
  if (n_valid < 64) return out;
  // The outline's band: out of the smoothing and the statistics, judged by saturation alone (too little inside it:
  // no band).
  cv::Mat inner;
  cv::bitwise_and(valid, ~outline_band(valid, 0.5 * o.outline_band_px), inner);
  if (cv::countNonZero(inner) < 64) inner = valid.clone();
  auto log_of = [](const cv::Mat& m) {
    cv::Mat l;
    cv::log(cv::max(m, 1e-3), l);
    return l;
  };
  const double s = o.smooth_px;
  auto smooth = [&](const cv::Mat& m) { return s > 0 ? masked_gaussian(m, inner, s, cv::BORDER_REPLICATE) : m.clone(); };
  const cv::Mat lg0 = smooth(log_of(g0)), lg1 = smooth(log_of(g1)), lb0 = smooth(log_of(b0)), lb1 = smooth(log_of(b1));
  // Skin colour c = B/G and the static score per phase.
  const cv::Mat chroma0 = lb0 - lg0, chroma1 = lb1 - lg1;
  const double m0 = median_of(values(chroma0, inner)), m1 = median_of(values(chroma1, inner));
  const double c = std::exp(0.5 * (m0 + m1));
  out.blue_over_green = c;
  const double inv_c = 1 / std::max(c, 1e-3);
  // Change between the phases, exposure and white balance taken out as medians.
  cv::Mat dg = lg1 - lg0, db = lb1 - lb0;
  dg -= median_of(values(dg, inner));
  db -= median_of(values(db, inner));
  const double sigma_dg = robust_sigma(dg, inner);
  const auto rho_measured = measure_blanching_ratio(dg, db, inner, sigma_dg, o.blanching_ratio, inv_c);
  const double rho = rho_measured.value_or(o.blanching_ratio);
  out.blanching_ratio = rho, out.ratio_measured = rho_measured.has_value();
  const double lever_change = inv_c - rho, lever_static = inv_c - 1;
  if (lever_change < 0.3)
    out.warnings.push_back("glare detection is unsure: the skin's blue is close to its green (B/G " + fmt(c, 2) +
                           "), so glare that changes between the captures is hard to tell from blanching (lever " +
                           fmt(lever_change, 2) + ", 0.3 wanted); check the white balance");
  const cv::Mat gamma = (db - rho * dg) / std::max(lever_change, 0.05);
  cv::Mat static0 = (chroma0 - m0) / std::max(lever_static, 0.05), static1 = (chroma1 - m1) / std::max(lever_static, 0.05);
  out.change_sigma = robust_sigma(gamma, inner);
  out.static_sigma = std::max(robust_sigma(static0, inner), robust_sigma(static1, inner));
  const double t_change = std::max(o.threshold_sigmas * out.change_sigma, o.min_change);
  const double t_static = std::max(o.threshold_sigmas * out.static_sigma, o.min_static);
  // Score: ≥ 1 is glare; ≥ ½ may grow a glare region (hysteresis).
  cv::Mat score(half, CV_32F, cv::Scalar(0)), phase0(half, CV_8U, cv::Scalar(0)), phase1(half, CV_8U, cv::Scalar(0));
  const float sat = static_cast<float>(o.saturation);
  for (int j = 0; j < half.height; ++j)
    for (int i = 0; i < half.width; ++i) {
      if (!valid.at<std::uint8_t>(j, i)) continue;
      const bool scored = inner.at<std::uint8_t>(j, i) != 0;
      const float ch = scored ? static_cast<float>(gamma.at<float>(j, i) / t_change) : 0.f;
      const float s0 = scored ? static_cast<float>(static0.at<float>(j, i) / t_static) : 0.f;
      const float s1 = scored ? static_cast<float>(static1.at<float>(j, i) / t_static) : 0.f;
      const bool sat0 = std::max(g0.at<float>(j, i), b0.at<float>(j, i)) >= sat, sat1 = std::max(g1.at<float>(j, i), b1.at<float>(j, i)) >= sat;
      score.at<float>(j, i) = std::max({std::abs(ch), s0, s1, sat0 || sat1 ? 10.f : 0.f});
      // Which capture holds it: glare appearing (γ > 0) is in the worn one, leaving (γ < 0) in the baseline.
      phase0.at<std::uint8_t>(j, i) = s0 >= 1 || sat0 || ch <= -1;
      phase1.at<std::uint8_t>(j, i) = s1 >= 1 || sat1 || ch >= 1;
    }
  // Hysteresis: regions ≥ ½ that hold a pixel ≥ 1.
  cv::Mat low = score >= 0.5f, labels;
  const int n = cv::connectedComponents(low, labels, 8, CV_32S);
  std::vector<char> keep(n, 0);
  for (int j = 0; j < half.height; ++j)
    for (int i = 0; i < half.width; ++i)
      if (score.at<float>(j, i) >= 1) keep[labels.at<int>(j, i)] = 1;
  cv::Mat mask_half(half, CV_8U, cv::Scalar(0));
  for (int j = 0; j < half.height; ++j)
    for (int i = 0; i < half.width; ++i)
      if (const int l = labels.at<int>(j, i); l > 0 && keep[l]) mask_half.at<std::uint8_t>(j, i) = 255;
  for (int l = 1; l < n; ++l) out.regions += keep[l];
  out.fraction_baseline = cv::countNonZero(phase0) / static_cast<double>(n_valid);
  out.fraction_worn = cv::countNonZero(phase1) / static_cast<double>(n_valid);
  // Full resolution, grown by the margin.
  cv::resize(mask_half, out.mask, cv::Size(2 * half.width, 2 * half.height), 0, 0, cv::INTER_NEAREST);
  out.mask = out.mask(cv::Rect(0, 0, base.roi.width, base.roi.height)).clone();
  const auto seen_share = [&](const cv::Mat& mask) {
    cv::Mat seen_masked;
    cv::bitwise_and(mask, seen, seen_masked);
    return cv::countNonZero(seen_masked) / std::max(1.0, static_cast<double>(cv::countNonZero(seen)));
  };
  if (out.regions > 0) {
    const cv::Mat fixed = grow_by_margin(out.mask, o.margin_px);
    out.fraction_glare = seen_share(fixed);
    if (o.tail_light > 0) {
      const std::vector<double> tail = measured_tails(labels, keep, mask_half, inner, {static0, static1, gamma}, phase0, phase1, o);
      out.mask = grow_by_margin(out.mask, o.margin_px, labels, tail);
    } else {
      out.mask = fixed;
    }
  }
  out.fraction = seen_share(out.mask);
  if (!out.ratio_measured && out.regions > 0)
    out.warnings.push_back("glare mask: blanching's blue-to-green ratio could not be measured (too little blanching), the default " +
                           fmt(rho, 2) + " was used");
  return out;
}

namespace {

/// Linear blue over green of each (blue, green) code pair, index 256·blue + green, as glare_fraction reads it.
const std::vector<float>& blue_green_ratio_table() {
  static const std::vector<float> table = [] {
    const float* lut = srgb::to_linear_table8();
    std::vector<float> t(65536);
    for (int b = 0; b < 256; ++b)
      for (int g = 0; g < 256; ++g) t[b * 256 + g] = lut[b] / std::max(lut[g], 1e-4f);
    return t;
  }();
  return table;
}

}  // namespace

cv::Mat glare_pixels(const cv::Mat& bgr, const cv::Rect& patch_in, const cv::Rect& region_in) {
  const cv::Rect image(0, 0, bgr.cols, bgr.rows), r = patch_in & image, region = region_in & image;
  cv::Mat out = cv::Mat::zeros(region_in.size(), CV_8U);
  if (r.area() == 0 || region.area() == 0) return out;
  const float* lut = srgb::to_linear_table8();
  const std::vector<float>& ratio_of = blue_green_ratio_table();
  // The medians (the value of rank n/2) from histograms, exactly: green is an increasing function
  // of its code, the ratio a function of the (blue, green) pair; the pairs seen are few.
  thread_local std::vector<int> pair_count(65536, 0);
  thread_local std::vector<int> pairs;
  pairs.clear();
  std::array<int, 256> green_count{};
  for (int y = r.y; y < r.br().y; ++y) {
    const auto* row = bgr.ptr<cv::Vec3b>(y);
    for (int x = r.x; x < r.br().x; ++x) {
      const int k = row[x][0] * 256 + row[x][1];
      if (pair_count[k]++ == 0) pairs.push_back(k);
      ++green_count[row[x][1]];
    }
  }
  const long long rank = r.area() / 2;
  long long below = 0;
  int green_code = 0;
  while (below + green_count[green_code] <= rank) below += green_count[green_code++];
  std::sort(pairs.begin(), pairs.end(), [&](int a, int b) { return ratio_of[a] < ratio_of[b]; });
  below = 0;
  std::size_t i = 0;
  while (below + pair_count[pairs[i]] <= rank) below += pair_count[pairs[i++]];
  const double c = ratio_of[pairs[i]], g = lut[green_code];
  for (const int k : pairs) pair_count[k] = 0;
  const double whiter = c + 0.5 * (1 - c);
  for (int y = region.y; y < region.br().y; ++y) {
    const auto* row = bgr.ptr<cv::Vec3b>(y);
    auto* dst = out.ptr<std::uint8_t>(y - region_in.y) - region_in.x;
    for (int x = region.x; x < region.br().x; ++x) {
      const cv::Vec3b p = row[x];
      if (std::max({p[0], p[1], p[2]}) >= 250 || (ratio_of[p[0] * 256 + p[1]] >= whiter && lut[p[1]] >= 1.2 * g)) dst[x] = 255;
    }
  }
  return out;
}

double glare_fraction(const cv::Mat& bgr, const cv::Rect& patch) {
  const cv::Rect r = patch & cv::Rect(0, 0, bgr.cols, bgr.rows);
  if (r.area() == 0) return 0;
  return cv::countNonZero(glare_pixels(bgr, r, r)) / static_cast<double>(r.area());
}

std::vector<std::uint8_t> glare_texels(const GlareMask& glare, const InverseMap& inv, const Vec2& shift) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(inv.width) * inv.height, 0);
  if (glare.empty()) return out;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const auto k = inv.index(i, j);
      if (!inv.valid[k]) continue;
      const int x = static_cast<int>(std::lround(inv.map_x[k] + shift.x())) - glare.roi.x;
      const int y = static_cast<int>(std::lround(inv.map_y[k] + shift.y())) - glare.roi.y;
      if (x >= 0 && y >= 0 && x < glare.mask.cols && y < glare.mask.rows && glare.mask.at<std::uint8_t>(y, x)) out[k] = 1;
    }
  return out;
}

void flag_hotspots_at_mask(std::vector<Hotspot>& hotspots, const std::vector<int>& label,
                           const std::vector<std::uint8_t>& excluded, const ChartGrid& g) {
  if (excluded.empty() || label.size() != g.size()) return;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const int id = label[g.index(i, j)];
      if (id <= 0) continue;
      bool touches = false;
      for (int dj = -1; dj <= 1 && !touches; ++dj)
        for (int di = -1; di <= 1 && !touches; ++di) {
          const int u = i + di, v = j + dj;
          touches = u >= 0 && v >= 0 && u < g.width && v < g.height && excluded[g.index(u, v)];
        }
      if (!touches) continue;
      for (Hotspot& h : hotspots)
        if (h.id == id) h.touches_mask = true;
    }
}

cv::Mat masked_gaussian(const cv::Mat& image, const cv::Mat& mask, double sigma_px, int border) {
  cv::Mat w, v;
  mask.convertTo(w, CV_32F, 1.0 / 255);
  v = image.mul(w);
  cv::GaussianBlur(v, v, cv::Size(), sigma_px, sigma_px, border);
  cv::GaussianBlur(w, w, cv::Size(), sigma_px, sigma_px, border);
  return v / cv::max(w, 1e-6);
}

}  // namespace clearfit
