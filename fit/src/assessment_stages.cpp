// The assessment's stages on plain values (assessment_stages.hpp): the checks on the captures, where on
// the skin each texel lies, the blur's first-order effect, the signal's σ and the pressure.
#include <clearfit/error.hpp>
#include <clearfit/fit/assessment_stages.hpp>
#include <clearfit/format.hpp>
#include "map_jacobian.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <opencv2/imgproc.hpp>

namespace clearfit {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}  // namespace

void check_glare(const GlareMask& g, const PhaseReport& base, const PhaseReport& worn, const GlareOptions& o,
                 std::vector<std::string>& warnings) {
  const bool worn_worse = g.fraction_worn >= g.fraction_baseline;
  // The highlights with the fixed margin: a highlight's measured tail (GlareOptions::tail_light) is masked, not counted.
  const double worst = std::max({g.fraction_glare, g.fraction_worn, g.fraction_baseline});
  if (worst > o.max_fraction)
    throw InputError(worn_worse ? worn.source : base.source, worn_worse ? "worn capture" : "baseline capture",
                     "is mostly glare: specular reflections of the part cover " + fixed_digits(100 * worst, 1) +
                         " % of the skin the camera sees (at most " + fixed_digits(100 * o.max_fraction, 1) + " % allowed)",
                     "move the light or the camera so its reflection on the part falls beside the skin (or use a diffuser or "
                     "crossed polarisers), and film again");
  if (g.regions > 0)
    warnings.push_back("glare: " + std::to_string(g.regions) + " specular highlight" + (g.regions == 1 ? "" : "s") + " masked (" +
                       fixed_digits(100 * g.fraction, 1) + " % of the seen skin): not assessed there");
  for (const auto& w : g.warnings) warnings.push_back(w);
}

void warn_gains(const PhaseReport& p, const std::string& role, std::vector<std::string>& warnings) {
  if (p.gain_max / std::max(p.gain_min, 1e-9) > 1.02)
    warnings.push_back("the exposure or white balance changed by " + fixed_digits(100 * (p.gain_max / p.gain_min - 1), 1) + " % during the " + role +
                       " window (chunk gains " + fixed_digits(p.gain_min, 3) + " to " + fixed_digits(p.gain_max, 3) +
                       "), normalised; lock the camera's exposure and white balance to avoid it");
  if (p.gain_sigma > 0.002)
    warnings.push_back("the exposure normalisation of the " + role + " window is unsure: each chunk's gain is known to " +
                       fixed_digits(100 * p.gain_sigma, 2) + " % only");
}

void check_exposure(const PhaseAverage& avg, const std::string& source, const std::string& role, const AssessmentOptions& o,
                    double glare_fraction) {
  const std::string frames = "frames " + std::to_string(avg.window.first) + ".." + std::to_string(avg.window.first + avg.window.count - 1);
  if (avg.saturated_fraction > o.max_saturated_fraction + glare_fraction)
    throw InputError(source, frames,
                     "the " + role + " capture is overexposed: " + fixed_digits(100 * avg.saturated_fraction, 1) +
                         " % of the pixels that see the skin are saturated (at most " + fixed_digits(100 * o.max_saturated_fraction, 1) + " % allowed)",
                     "lower the exposure or the light, lock auto exposure, and film again");
  if (avg.mean_code < o.min_mean_code)
    throw InputError(source, frames,
                     "the " + role + " capture is too dark: mean green " + fixed_digits(avg.mean_code, 1) + " of 255 where the skin is seen (at least " +
                         fixed_digits(o.min_mean_code, 1) + " needed)",
                     "raise the exposure or the light, and film again");
}

ChartField position_sigma(const ChartRaster& raster, const Rigid3& cam_from_part, const PoseCovariance& covariance) {
  ChartField out{raster.grid, std::vector<float>(raster.grid.size(), kNaN)};
  for (std::size_t k = 0; k < raster.grid.size(); ++k) {
    if (raster.face[k] < 0) continue;
    const Vec3 p = cam_from_part.apply(raster.point[k]), v = p - cam_from_part.translation;
    Eigen::Matrix<double, 3, 6> J;
    J << 0, v.z(), -v.y(), 1, 0, 0,  //  δθ × v = −[v]× δθ
        -v.z(), 0, v.x(), 0, 1, 0,   //
        v.y(), -v.x(), 0, 0, 0, 1;
    const Eigen::Matrix3d moved = J * covariance * J.transpose();
    const Vec3 u = p.normalized();
    const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - u * u.transpose();
    out.value[k] = static_cast<float>(std::sqrt(std::max(0.0, (across * moved * across).trace() / 2)));
  }
  return out;
}

IntrinsicsTerm intrinsics_term(const InverseMap& inv, const ChartField& y, const ProjectionUncertainty& u, int width, int height) {
  const ChartGrid& grid = y.grid;
  const ChartField nan{grid, std::vector<float>(grid.size(), kNaN)};
  IntrinsicsTerm out{nan, nan, nan};
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const auto J = pixel_jacobian(inv, i, j);
      if (!J) continue;
      const Vec2 q = texel_pixel(inv, i, j);
      const Eigen::Matrix2d A = J->inverse();
      const double sigma_q = u.at(q, width, height);
      const auto k = grid.index(i, j);
      out.pixel_sigma_px.value[k] = static_cast<float>(sigma_q);
      out.position_mm.value[k] = static_cast<float>(sigma_q * A.norm() / std::sqrt(2.0));
      if (std::isfinite(y.value[k])) out.signal.value[k] = static_cast<float>(sigma_q * (A.transpose() * gradient(y, i, j)).norm());
    }
  return out;
}

ProjectionSigmaOnContact projection_sigma_on_contact(const IntrinsicsTerm& term, const ChartField& y, const InverseMap& inv,
                                                     double threshold_px) {
  ProjectionSigmaOnContact s;
  s.threshold_px = threshold_px;
  if (term.pixel_sigma_px.value.size() != y.value.size()) return s;
  std::vector<double> all;
  long long above = 0;
  for (int j = 0; j < y.grid.height; ++j)
    for (int i = 0; i < y.grid.width; ++i) {
      const auto k = y.grid.index(i, j);
      const double q = term.pixel_sigma_px.value[k];
      if (!std::isfinite(y.value[k]) || !std::isfinite(q)) continue;
      all.push_back(q);
      above += q > threshold_px;
      if (q > s.largest_px || all.size() == 1) {
        s.largest_px = q;
        const auto m = inv.index(i, j);
        s.largest_at_px = Vec2(inv.map_x[m], inv.map_y[m]);
      }
      if (const double mm = term.position_mm.value[k]; std::isfinite(mm)) s.position_mm = std::max(s.position_mm, mm);
    }
  s.texels = static_cast<long long>(all.size());
  if (all.empty()) return s;
  const auto mid = all.begin() + static_cast<std::ptrdiff_t>(all.size() / 2);
  std::nth_element(all.begin(), mid, all.end());
  s.median_px = *mid;
  s.fraction_above = static_cast<double>(above) / static_cast<double>(all.size());
  return s;
}

void warn_projection_sigma(const ProjectionSigmaOnContact& s, std::vector<std::string>& warnings) {
  if (s.texels == 0 || !(s.largest_px > s.threshold_px)) return;
  const std::string at = "(" + fixed_digits(s.largest_at_px.x(), 0) + ", " + fixed_digits(s.largest_at_px.y(), 0) + ")";
  warnings.push_back("the part lies where the camera model is unsure: its projection uncertainty reaches " + fixed_digits(s.largest_px, 2) +
                     " px at pixel " + at + " (median " + fixed_digits(s.median_px, 2) + " px over the seen contact surface, " +
                     fixed_digits(100 * s.fraction_above, 1) + " % of it above " + fixed_digits(s.threshold_px, 2) +
                     " px), so where on the skin a texel lies is uncertain by up to " + fixed_digits(s.position_mm, 3) +
                     " mm (1-σ, in the pressure's σ); the calibration's boards did not cover that part of the view: calibrate "
                     "again (`clearfit calibrate`) with images whose boards fill the view around pixel " + at + " at the part's distance");
}

ChartField position_sigma_total(const ChartField& pose, const ChartField& intrinsics) {
  if (pose.value.empty()) return intrinsics;
  if (intrinsics.value.empty()) return pose;
  ChartField out = pose;
  for (std::size_t k = 0; k < out.value.size(); ++k) {
    const float a = pose.value[k], b = intrinsics.value[k];
    out.value[k] = std::isfinite(a) && std::isfinite(b) ? std::hypot(a, b) : std::isfinite(a) ? a : b;
  }
  return out;
}

namespace {
/// `field` blurred by a Gaussian of `sigma_mm`, normalised over its finite texels (the unseen ones neither count
/// nor receive a value: NaN stays NaN).
ChartField seen_blur(const ChartField& field, double sigma_mm) {
  const ChartGrid& g = field.grid;
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  if (g.size() == 0) return out;
  cv::Mat v(g.height, g.width, CV_32F, cv::Scalar(0)), w(g.height, g.width, CV_32F, cv::Scalar(0)), gv, gw;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i)
      if (const float y = field.value[g.index(i, j)]; std::isfinite(y)) v.at<float>(j, i) = y, w.at<float>(j, i) = 1;
  const double s = sigma_mm / g.texel_mm;
  if (s > 0) {
    cv::GaussianBlur(v, gv, cv::Size(), s, s, cv::BORDER_CONSTANT);
    cv::GaussianBlur(w, gw, cv::Size(), s, s, cv::BORDER_CONSTANT);
  } else {
    gv = v, gw = w;
  }
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i)
      if (std::isfinite(field.value[g.index(i, j)]) && gw.at<float>(j, i) > 0) out.value[g.index(i, j)] = gv.at<float>(j, i) / gw.at<float>(j, i);
  return out;
}
}  // namespace

std::vector<DeblurTerm> deblur_terms(const BlanchingOptions& o) {
  const double b2 = o.skin_blur_mm * o.skin_blur_mm + o.smoothing_mm * o.smoothing_mm, c = o.curvature_smoothing_mm;
  return {{2 * b2 / (c * c), c}, {-0.5 * b2 / (c * c), std::sqrt(2.0) * c}};
}

double deblur_noise_gain(const BlanchingOptions& o, double texel_mm) {
  const std::vector<DeblurTerm> terms = deblur_terms(o);
  const double n2 = std::pow(std::max(o.smoothing_mm, 0.5 * texel_mm), 2);
  // H(k) = A − Σ a_i·exp(−k²c_i²/2) with A = 1 + Σ a_i, over noise whose spectrum is exp(−k²n²): each product of two
  // Gaussians integrates to n² / (n² + (c_i² + c_j²)/2) of the noise's variance (1 for the constant).
  double a = 1;
  for (const DeblurTerm& t : terms) a += t.weight;
  double g2 = a * a;
  for (const DeblurTerm& t : terms) {
    g2 -= 2 * a * t.weight * n2 / (n2 + 0.5 * t.scale_mm * t.scale_mm);
    for (const DeblurTerm& u : terms) g2 += t.weight * u.weight * n2 / (n2 + 0.5 * (t.scale_mm * t.scale_mm + u.scale_mm * u.scale_mm));
  }
  return std::sqrt(std::max(g2, 1.0));
}

ChartField blur_effect(const BlanchingSignal& signal, const BlanchingOptions& o) {
  const ChartGrid& g = signal.y.grid;
  ChartField out{g, std::vector<float>(g.size(), 0.f)};
  if (g.size() == 0) return out;
  cv::Mat effect(g.height, g.width, CV_32F, cv::Scalar(0));
  for (const DeblurTerm& t : deblur_terms(o)) {  // −a·(y − G_c∗y), G_c∗y normalised over the seen texels
    const ChartField smooth = seen_blur(signal.y, t.scale_mm);
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i)
        if (const auto k = g.index(i, j); std::isfinite(smooth.value[k]))
          effect.at<float>(j, i) -= static_cast<float>(t.weight * (signal.y.value[k] - smooth.value[k]));
  }
  for (int j = 1; j + 1 < g.height; ++j)
    for (int i = 1; i + 1 < g.width; ++i) {
      bool seen = true;
      for (auto [di, dj] : {std::pair{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}}) seen = seen && std::isfinite(signal.y.value[g.index(i + di, j + dj)]);
      if (seen) out.value[g.index(i, j)] = effect.at<float>(j, i);
    }
  return out;
}

ChartField sharpened_signal(const ChartField& y, const ChartField& blur) {
  ChartField out = y;
  for (std::size_t k = 0; k < out.value.size() && k < blur.value.size(); ++k)
    if (std::isfinite(out.value[k])) out.value[k] -= blur.value[k];
  return out;
}

ChartField signal_sigma(const BlanchingSignal& signal, const ChartField& position_mm, const ChartField& intrinsics_signal,
                        const ChartField& blur, double noise_gain) {
  ChartField out = signal.sigma_y;
  for (std::size_t k = 0; k < out.value.size(); ++k)
    if (std::isfinite(out.value[k])) out.value[k] = static_cast<float>(std::hypot(noise_gain * out.value[k], blur.value[k]));
  for (std::size_t k = 0; k < intrinsics_signal.value.size(); ++k)
    if (std::isfinite(out.value[k]) && std::isfinite(intrinsics_signal.value[k])) out.value[k] = std::hypot(out.value[k], intrinsics_signal.value[k]);
  if (position_mm.value.empty()) return out;
  const ChartGrid& g = signal.y.grid;
  const ChartField sharpened = sharpened_signal(signal.y, blur);
  const auto& y = signal.y.value;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (!std::isfinite(y[k]) || !std::isfinite(position_mm.value[k])) continue;
      const double gradient = gradient_norm(sharpened, i, j);
      out.value[k] = static_cast<float>(std::hypot(static_cast<double>(out.value[k]), gradient * position_mm.value[k]));
    }
  return out;
}

void add_position_to_centres(std::vector<Hotspot>& hotspots, const std::vector<int>& labels, const ChartField& position_mm) {
  if (position_mm.value.empty()) return;
  std::vector<double> sum(hotspots.size() + 1, 0.0);
  std::vector<long long> n(hotspots.size() + 1, 0);
  for (std::size_t k = 0; k < labels.size(); ++k)
    if (labels[k] > 0 && labels[k] <= static_cast<int>(hotspots.size()) && std::isfinite(position_mm.value[k]))
      sum[labels[k]] += position_mm.value[k] * position_mm.value[k], ++n[labels[k]];
  for (Hotspot& h : hotspots)
    if (n[h.id] > 0)
      for (double* sigma : {&h.centre_of_pressure_sigma_mm, &h.centroid_sigma_mm})
        if (std::isfinite(*sigma)) *sigma = std::sqrt(*sigma * *sigma + 2 * sum[h.id] / n[h.id]);
}

namespace {
// Hysteresis, as Canny's edges have it: a texel below detection whose signal is at least `sigmas` of its own
// σ_y and that is 8-connected, through such texels, to a detected texel keeps its estimate. The detection
// gate keeps the noise from making places; the tails of the places it found (1-4 kPa on the robustness
// benchmark's hotspots, blanching clearly but under 5 σ) are read instead of being set to 0. Only detected
// pieces of at least min_area_mm2 (the smallest place reported) grow: a speck of a few texels over the gate
// at the contact surface's oblique end grew into a 0.24 mm² place on AssessCli's wristband.
void extend_detection(const PressureCalibration& calibration, const ChartField& sharpened, double sigmas, double min_area_mm2,
                      Assessment& a) {
  const ChartGrid& g = a.signal.y.grid;
  const auto ok = static_cast<std::uint8_t>(PressureStatus::ok), below = static_cast<std::uint8_t>(PressureStatus::below_detection);
  // mask: the detected texels and the candidates; detected_mask: the detected ones alone (their pieces' areas).
  cv::Mat1b mask(g.height, g.width, std::uint8_t{0}), detected_mask(g.height, g.width, std::uint8_t{0});
  std::vector<std::size_t> candidates;
  for (std::size_t k = 0; k < g.size(); ++k) {
    const float y = a.signal.y.value[k], sy = static_cast<float>(detection_sigma(a, k));
    const bool detected = a.pressure_status[k] == ok;
    const bool candidate = a.pressure_status[k] == below && std::isfinite(sy) && y >= sigmas * sy;
    const int row = static_cast<int>(k / g.width), col = static_cast<int>(k % g.width);
    mask(row, col) = detected || candidate, detected_mask(row, col) = detected;
    if (candidate) candidates.push_back(k);
  }
  if (candidates.empty()) return;
  auto at = [&](const cv::Mat1i& l, std::size_t k) { return static_cast<std::size_t>(l(static_cast<int>(k / g.width), static_cast<int>(k % g.width))); };
  cv::Mat1i pieces;
  std::vector<long long> piece_texels(static_cast<std::size_t>(cv::connectedComponents(detected_mask, pieces, 8, CV_32S)), 0);
  for (std::size_t k = 0; k < g.size(); ++k)
    if (a.pressure_status[k] == ok) ++piece_texels[at(pieces, k)];
  const double texel_mm2 = g.texel_mm * g.texel_mm;
  cv::Mat1i labels;
  const int n = cv::connectedComponents(mask, labels, 8, CV_32S);
  std::vector<std::uint8_t> detected(static_cast<std::size_t>(n), 0);
  for (std::size_t k = 0; k < g.size(); ++k)
    if (a.pressure_status[k] == ok && static_cast<double>(piece_texels[at(pieces, k)]) * texel_mm2 >= min_area_mm2) detected[at(labels, k)] = 1;
  std::erase_if(candidates, [&](std::size_t k) { return !detected[at(labels, k)]; });
  std::vector<float> y(candidates.size()), sy(candidates.size()), p(candidates.size()), sp(candidates.size());
  std::vector<std::uint8_t> st(candidates.size());
  for (std::size_t i = 0; i < candidates.size(); ++i) y[i] = sharpened.value[candidates[i]], sy[i] = a.signal_sigma.value[candidates[i]];
  calibration.invert(y, sy, p, sp, st, 0.0);
  for (std::size_t i = 0; i < candidates.size(); ++i)
    if (st[i] == ok) {
      const std::size_t k = candidates[i];
      a.pressure_status[k] = ok, a.pressure.value[k] = p[i], a.pressure_sigma.value[k] = sp[i];
    }
}
}  // namespace

double detection_sigma(const Assessment& a, std::size_t k) {
  const double sy = a.signal.sigma_y.value[k];
  if (k >= a.gap_signal_sigma.value.size() || !std::isfinite(a.gap_signal_sigma.value[k])) return sy;
  return std::hypot(sy, static_cast<double>(a.gap_signal_sigma.value[k]));
}

double local_gate(double gate, double sigma_y, double typical_sigma) {
  if (!(typical_sigma > 0) || !std::isfinite(sigma_y)) return gate;
  return gate * std::max(1.0, sigma_y / typical_sigma);
}

std::vector<std::uint8_t> calibrated_pressure(const PressureCalibration& calibration, bool spatial_noise, const AssessmentOptions& o,
                                              Assessment& a) {
  const ChartGrid& g = a.signal.y.grid;
  std::vector<std::uint8_t> saturated(g.size(), 0);
  a.calibrated = true;
  a.pressure = {g, std::vector<float>(g.size(), kNaN)};
  a.pressure_sigma = {g, std::vector<float>(g.size(), kNaN)};
  a.pressure_status.assign(g.size(), static_cast<std::uint8_t>(PressureStatus::invalid));
  // The pressure of the signal with the blur's first-order effect undone (blur_effect).
  const ChartField sharpened = sharpened_signal(a.signal.y, a.blur_effect);
  calibration.invert(sharpened.value, a.signal_sigma.value, a.pressure.value, a.pressure_sigma.value, a.pressure_status);
  // Detection is read on y itself, the estimate on the sharpened signal: the deblur raises the noise (and a capture's
  // spatial error) by its gain, and gated on the sharpened signal the band's oblique ends on PhotometricCli's
  // wristband (smoothing 0.5 mm) became 2 false places at 4.3 kPa. A detected place's tail is read by the hysteresis.
  // Lossy captures and phases with their own geometry: the calibration's detection limit is its presses'
  // noise, not the capture's; a texel not significant against this capture's own noise (spatial term
  // included) is below detection. The gate is signal_threshold_sigmas (5), not the calibration's own
  // detection_sigmas (3): at 3 σ the texture left in a held or lossy capture's signal became false places
  // at 4.3 kPa (21 on AssessCli's wristband, 2 on LossyCli's), while the σ coverage gained 0.6 points.
  // The calibration's gate is a signal for a texel of this capture's typical noise (the median σ_y); a texel whose own
  // σ_y is larger (beside a glare mask, at the seen outline, seen obliquely) needs as much more (local_gate).
  // Saturated texels too: beyond the calibration's range is no reason to be above a σ that reaches it (at the band's end
  // on wristband quarter-scale seed 14 the gap's σ term was 0.1, as large as the signal of a false saturated speck).
  const double gate = calibration.detection_signal();
  for (std::size_t k = 0; k < g.size(); ++k)
    if ((a.pressure_status[k] == static_cast<std::uint8_t>(PressureStatus::ok) ||
         a.pressure_status[k] == static_cast<std::uint8_t>(PressureStatus::saturated)) &&
        !(a.signal.y.value[k] >= local_gate(gate, detection_sigma(a, k), a.signal.noise_sigma) &&
          (!spatial_noise || a.signal.y.value[k] >= o.signal_threshold_sigmas * detection_sigma(a, k)))) {
      a.pressure_status[k] = static_cast<std::uint8_t>(PressureStatus::below_detection);
      a.pressure_sigma.value[k] = kNaN;  // 0 kPa below detection is a bound, not an estimate
    }
  extend_detection(calibration, sharpened, o.hysteresis_sigmas, o.min_hotspot_area_mm2, a);
  a.pressure_sigma_parts = pressure_sigma_parts(calibration, a, o.blanching);
  // Below detection is a measurement (less than the detection limit), shown and counted as 0 kPa;
  // pressure_status keeps the flag. Unseen texels stay NaN.
  for (std::size_t k = 0; k < g.size(); ++k)
    if (a.pressure_status[k] == static_cast<std::uint8_t>(PressureStatus::below_detection)) a.pressure.value[k] = 0.f;
  long long seen = 0, below = 0, sat = 0, est = 0;
  double sum = 0;
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (!std::isfinite(a.signal.y.value[k])) continue;
    ++seen;
    const auto st = static_cast<PressureStatus>(a.pressure_status[k]);
    if (st == PressureStatus::below_detection) ++below;
    if (st == PressureStatus::saturated) ++sat, saturated[k] = 1;
    if (std::isfinite(a.pressure.value[k])) {
      ++est;
      sum += a.pressure.value[k];
      a.peak_kpa = std::max(a.peak_kpa, static_cast<double>(a.pressure.value[k]));
    }
  }
  a.detection_limit = detection_limit(calibration, a.signal.noise_sigma, spatial_noise, o);
  a.below_detection_fraction = seen ? static_cast<double>(below) / seen : 0;
  a.saturated_fraction = seen ? static_cast<double>(sat) / seen : 0;
  a.mean_kpa = est ? sum / est : 0;
  if (a.saturated_fraction > 0)
    a.warnings.push_back(fixed_digits(100 * a.saturated_fraction, 2) + " % of the seen skin is beyond the calibration's range (saturated): "
                         "the pressure there is at least the value shown");
  return saturated;
}

ChartField deblur_residual(const ChartField& sharpened, const BlanchingOptions& o) {
  const ChartGrid& g = sharpened.grid;
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  BlanchingSignal reblurred;
  reblurred.y = seen_blur(sharpened, std::hypot(o.skin_blur_mm, o.smoothing_mm));  // G_β∗y'
  const ChartField again = sharpened_signal(reblurred.y, blur_effect(reblurred, o));
  // Where blur_effect leaves a texel undeblurred (a 4-neighbour unseen, the grid's border) the miss is unknown: NaN.
  for (int j = 1; j + 1 < g.height; ++j)
    for (int i = 1; i + 1 < g.width; ++i) {
      bool seen = true;
      for (auto [di, dj] : {std::pair{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}}) seen = seen && std::isfinite(sharpened.value[g.index(i + di, j + dj)]);
      if (const auto k = g.index(i, j); seen) out.value[k] = sharpened.value[k] - again.value[k];
    }
  return out;
}

ChartField logistic_residual(const PressureCalibration& calibration, const ChartField& pressure, double skin_blur_mm) {
  const ChartGrid& g = pressure.grid;
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  if (calibration.model != PressureModelKind::logistic || !(skin_blur_mm > 0) || !(calibration.logistic.width_kpa > 0)) {
    for (std::size_t k = 0; k < g.size(); ++k)
      if (std::isfinite(pressure.value[k])) out.value[k] = 0.f;
    return out;
  }
  // |∇p| on the pressure smoothed by the skin's blur (the noise would raise |∇p|²; the place's slope barely moves).
  const ChartField smooth = seen_blur(pressure, skin_blur_mm);
  const double w = calibration.logistic.width_kpa, p50 = calibration.logistic.p50_kpa;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      const double p = smooth.value[k];
      if (!std::isfinite(pressure.value[k]) || !std::isfinite(p)) continue;
      const double grad = gradient_norm(smooth, i, j), curvature = (1 - 2 / (1 + std::exp(-(p - p50) / w))) / w;  // f''/f'
      out.value[k] = static_cast<float>(0.5 * skin_blur_mm * skin_blur_mm * curvature * grad * grad);
    }
  return out;
}

PressureSigmaParts pressure_sigma_parts(const PressureCalibration& calibration, const Assessment& a, const BlanchingOptions& o) {
  const ChartGrid& g = a.signal.y.grid;
  PressureSigmaParts out;
  out.shared = out.blur = out.residual = ChartField{g, std::vector<float>(g.size(), kNaN)};
  if (a.pressure_sigma.value.size() != g.size()) return out;
  const bool blur = a.blur_effect.value.size() == g.size();
  const ChartField sharpened = blur ? sharpened_signal(a.signal.y, a.blur_effect) : a.signal.y;
  const auto ok = static_cast<std::uint8_t>(PressureStatus::ok);
  std::vector<float> p(g.size()), with_blur(g.size()), gap(g.size(), 0.f), size(g.size(), 0.f);
  std::vector<std::uint8_t> status(g.size()), status_blur(g.size());
  // Shared by a place: the calibration's parameters and the estimated gap's term (one gap for every texel:
  // Assessment::gap_signal_sigma as σ_y); then with |blur_effect| too: the blur's kPa is what it adds.
  if (a.gap_signal_sigma.value.size() == g.size())
    for (std::size_t k = 0; k < g.size(); ++k) gap[k] = std::isfinite(a.gap_signal_sigma.value[k]) ? a.gap_signal_sigma.value[k] : 0.f;
  calibration.invert(sharpened.value, gap, p, out.shared.value, status, 0.0);
  for (std::size_t k = 0; k < g.size(); ++k) size[k] = std::hypot(blur ? std::abs(a.blur_effect.value[k]) : 0.f, gap[k]);
  calibration.invert(sharpened.value, size, p, with_blur, status_blur, 0.0);
  // The residual in kPa: the inverse at y' + r less the inverse at y' (ungated, as the estimate itself), r smoothed
  // by β: the miss passes the noise's high frequencies, which moved the outline's band sums (on SigmaCoverage's
  // seeds 1–4, 11–16, 21–26, 31–34 the area's intervals held 36 of 40 times unsmoothed, 38 smoothed).
  const double beta = std::hypot(o.skin_blur_mm, o.smoothing_mm);
  ChartField moved = blur ? seen_blur(deblur_residual(sharpened, o), beta) : ChartField{g, std::vector<float>(g.size(), kNaN)};
  std::vector<float> p_moved(g.size()), unused(g.size());
  std::vector<std::uint8_t> status_moved(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) moved.value[k] = sharpened.value[k] + moved.value[k];
  calibration.invert(moved.value, {}, p_moved, unused, status_moved, 0.0);
  // The logistic's curvature on the skin's blur, on the pressure read (0 where below detection, as the estimate).
  ChartField read{g, p};
  for (std::size_t k = 0; k < g.size(); ++k)
    if (status[k] == static_cast<std::uint8_t>(PressureStatus::below_detection)) read.value[k] = 0.f;
  const ChartField curvature = logistic_residual(calibration, read, o.skin_blur_mm);
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (!std::isfinite(a.pressure_sigma.value[k]) || status[k] != ok) {
      out.shared.value[k] = kNaN;
      continue;
    }
    const double s = out.shared.value[k], sb = with_blur[k];
    out.blur.value[k] = static_cast<float>(std::sqrt(std::max(0.0, sb * sb - s * s)));
    if (status_moved[k] == ok) out.residual.value[k] = p_moved[k] - p[k];
    if (std::isfinite(out.residual.value[k]) && std::isfinite(curvature.value[k])) out.residual.value[k] += curvature.value[k];
  }
  return out;
}

namespace {
/// The calibration's inverse at signal y with no detection gate (its lower bound when y is beyond saturation).
double pressure_at(const PressureCalibration& calibration, double y) {
  PressureCalibration ungated = calibration;
  ungated.noise_sigma = 0;
  const PressureEstimate e = ungated.invert(y);
  return e.status == PressureStatus::ok ? e.pressure_kpa : e.status == PressureStatus::saturated ? e.bound_kpa : std::numeric_limits<double>::quiet_NaN();
}
}  // namespace

DetectionLimit detection_limit(const PressureCalibration& calibration, double noise_sigma, bool spatial_noise, const AssessmentOptions& o) {
  DetectionLimit d;
  d.signal = calibration.detection_signal();
  d.sigmas = PressureCalibration::detection_sigmas;
  d.noise_sigma = calibration.noise_sigma;
  if (spatial_noise && o.signal_threshold_sigmas * noise_sigma > d.signal) {
    d.signal = o.signal_threshold_sigmas * noise_sigma;
    d.sigmas = o.signal_threshold_sigmas;
    d.noise_sigma = noise_sigma;
    d.capture_noise = true;
  }
  d.kpa = pressure_at(calibration, d.signal);
  if (o.hysteresis_sigmas * noise_sigma < d.signal) d.tail_kpa = pressure_at(calibration, o.hysteresis_sigmas * noise_sigma);
  return d;
}

void warn_thresholds_below_detection(const std::vector<double>& thresholds_kpa, const DetectionLimit& limit,
                                     std::vector<std::string>& warnings) {
  if (!std::isfinite(limit.kpa)) return;
  const std::string noise = limit.capture_noise ? "this capture's noise (median σ " + fixed_digits(limit.noise_sigma, 4) + ")"
                                                : "the calibration presses' noise (σ " + fixed_digits(limit.noise_sigma, 4) + ")";
  const std::string gate = "the detection limit of " + fixed_digits(limit.kpa, 1) + " kPa (the pressure whose signal is " +
                           fixed_digits(limit.sigmas, 0) + " σ of " + noise + ")";
  const bool tail = std::isfinite(limit.tail_kpa) && limit.tail_kpa < limit.kpa;
  const double floor_kpa = tail ? limit.tail_kpa : limit.kpa;
  for (double t : thresholds_kpa) {
    const std::string at = significant_digits(t, 4) + " kPa";
    if (!(t < limit.kpa)) continue;
    if (t < floor_kpa)
      warnings.push_back("hotspot threshold " + at + " is below " + gate +
                         (tail ? ", and below the " + fixed_digits(limit.tail_kpa, 1) + " kPa down to which a detected place's tail is read" : "") +
                         ": the outline at " + at + " is where the signal stops being significant, not where the pressure crosses " + at +
                         ", so the areas at that threshold are underestimated (and their σ does not cover it); give thresholds of at least " +
                         fixed_digits(floor_kpa, 1) + " kPa, or film with less noise (more frames, lossless video)");
    else
      warnings.push_back("hotspot threshold " + at + " is below " + gate + ": a place is found only where its pressure reaches " +
                         fixed_digits(limit.kpa, 1) + " kPa, so one that stays between " + at + " and " + fixed_digits(limit.kpa, 1) +
                         " kPa is not reported; a place found is read down to about " + fixed_digits(limit.tail_kpa, 1) +
                         " kPa (its tail), so its area at " + at + " is not underestimated by the limit");
  }
}

std::vector<float> vertex_reach_texels(const InverseMap& inv, const std::vector<std::uint8_t>& excluded, const Chart& chart,
                                       double pixels) {
  // Per seen texel, the skin length of a camera pixel's longer axis there: 1/σ_min(∂pixel/∂uv).
  std::vector<float> footprint_mm(static_cast<std::size_t>(inv.width) * inv.height, kNaN);
  float longest = 0;
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const auto k = inv.index(i, j);
      if (!excluded.empty() && excluded[k]) continue;
      const auto J = pixel_jacobian(inv, i, j);
      if (!J) continue;
      const double smallest = Eigen::JacobiSVD<Eigen::Matrix2d>(*J).singularValues()(1);
      // Bounded: a texel seen at grazing incidence would otherwise reach across the chart.
      if (smallest > 0) longest = std::max(longest, footprint_mm[k] = static_cast<float>(std::min(1 / smallest, 16 * inv.texel_mm)));
    }
  const double window = std::max(kVertexReachTexels, pixels * longest / inv.texel_mm);
  std::vector<float> out(chart.uv.size(), kNaN);
  for (std::size_t v = 0; v < chart.uv.size(); ++v) {
    if (!chart.uv[v].allFinite()) continue;
    const double fx = (chart.uv[v].x() - inv.uv_origin.x()) / inv.texel_mm, fy = (chart.uv[v].y() - inv.uv_origin.y()) / inv.texel_mm;
    const int x0 = std::max(0, static_cast<int>(std::floor(fx - window))), x1 = std::min(inv.width - 1, static_cast<int>(std::ceil(fx + window)));
    const int y0 = std::max(0, static_cast<int>(std::floor(fy - window))), y1 = std::min(inv.height - 1, static_cast<int>(std::ceil(fy + window)));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const float f = footprint_mm[inv.index(x, y)];
        if (!std::isfinite(f)) continue;
        const double reach = std::max(kVertexReachTexels, pixels * f / inv.texel_mm);
        if (std::hypot(x - fx, y - fy) <= reach && !(out[v] >= reach)) out[v] = static_cast<float>(reach);
      }
  }
  return out;
}

std::vector<float> vertex_values(const ChartField& field, const Chart& chart, const std::vector<float>& reach_texels, double extra_mm) {
  std::vector<float> out(chart.uv.size(), kNaN);
  for (std::size_t v = 0; v < chart.uv.size() && v < reach_texels.size(); ++v) {
    if (!std::isfinite(reach_texels[v])) continue;
    out[v] = field.sample(chart.uv[v]);
    if (!std::isfinite(out[v])) out[v] = field.nearest_defined(chart.uv[v], reach_texels[v] + extra_mm / field.grid.texel_mm);
  }
  return out;
}

}  // namespace clearfit
