// The contact surface's outline in a phase's average (outline.hpp).
#include <clearfit/fit/outline.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace clearfit {

void OutlineOptions::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("OutlineOptions::" + what); };
  if (!(std::isfinite(band_px) && band_px >= 1 && band_px <= 50)) fail("band_px = " + std::to_string(band_px) + ": must be in [1, 50] px");
  if (!(std::isfinite(smoothing_px) && smoothing_px >= 0.5 && smoothing_px <= 10))
    fail("smoothing_px = " + std::to_string(smoothing_px) + ": must be in [0.5, 10] px");
  if (!(std::isfinite(max_sigma_px) && max_sigma_px > 0)) fail("max_sigma_px = " + std::to_string(max_sigma_px) + ": must be positive");
  if (!(std::isfinite(min_contrast) && min_contrast > 0 && min_contrast < 1))
    fail("min_contrast = " + std::to_string(min_contrast) + ": must be in (0, 1)");
  if (!(std::isfinite(max_shift_px) && max_shift_px > 0 && max_shift_px <= 20))
    fail("max_shift_px = " + std::to_string(max_shift_px) + ": must be in (0, 20] px");
}

namespace {

/// One band pixel: where it is, its sector (for the jackknife) and the blurred average there.
struct BandPixel {
  float x, y;     ///< roi pixel
  float u, v;     ///< normalised position (affine terms)
  float value;    ///< the blurred average
  int sector;
};

/// The mask blurred at one scale, with its gradient (central differences), bilinearly sampled.
struct StepModel {
  cv::Mat1f s, gx, gy;
  StepModel(const cv::Mat1f& seen, double sigma) {
    cv::GaussianBlur(seen, s, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    cv::Sobel(s, gx, CV_32F, 1, 0, 1, 0.5, 0, cv::BORDER_REPLICATE);
    cv::Sobel(s, gy, CV_32F, 0, 1, 1, 0.5, 0, cv::BORDER_REPLICATE);
  }
  static double at(const cv::Mat1f& f, double x, double y) {
    x = std::clamp(x, 0.0, f.cols - 1.001), y = std::clamp(y, 0.0, f.rows - 1.001);
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double tx = x - x0, ty = y - y0;
    return (1 - ty) * ((1 - tx) * f(y0, x0) + tx * f(y0, x0 + 1)) + ty * ((1 - tx) * f(y0 + 1, x0) + tx * f(y0 + 1, x0 + 1));
  }
};

/// The band around the outline at one scale (where the roi's border cuts the seen region there is no
/// outline: the distance transforms do not count the border); sectors by angle around the seen region's centroid.
std::vector<BandPixel> band_of(const cv::Mat& average, const cv::Mat1f& seen_share, const cv::Mat& exclude, double band_px, double sigma) {
  const cv::Mat seen = seen_share >= 0.5f;
  cv::Mat inside, outside, not_seen;
  cv::bitwise_not(seen, not_seen);
  cv::distanceTransform(seen, inside, cv::DIST_L2, 3);
  cv::distanceTransform(not_seen, outside, cv::DIST_L2, 3);
  cv::Mat1f blurred;
  average.convertTo(blurred, CV_32F);
  cv::GaussianBlur(blurred, blurred, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  const cv::Moments mo = cv::moments(seen, true);
  const double cx = mo.m00 > 0 ? mo.m10 / mo.m00 : 0.5 * seen.cols, cy = mo.m00 > 0 ? mo.m01 / mo.m00 : 0.5 * seen.rows;
  const double scale = 0.5 * std::max(seen.cols, seen.rows);
  // The roi's border is kept clear by two pixels (the central differences); the blur pads both the
  // average and the mask by replication, so they agree there.
  const int edge = 2;
  std::vector<BandPixel> band;
  for (int y = edge; y < seen.rows - edge; ++y)
    for (int x = edge; x < seen.cols - edge; ++x) {
      const float d = seen.at<std::uint8_t>(y, x) ? inside.at<float>(y, x) : outside.at<float>(y, x);
      if (d > band_px || (!exclude.empty() && exclude.at<std::uint8_t>(y, x)) || !std::isfinite(blurred(y, x))) continue;
      const double angle = std::atan2(y - cy, x - cx) + std::numbers::pi;
      const int sector = std::min(15, static_cast<int>(angle / (2 * std::numbers::pi) * 16));
      band.push_back({static_cast<float>(x), static_cast<float>(y), static_cast<float>((x - cx) / scale),
                      static_cast<float>((y - cy) / scale), blurred(y, x), sector});
    }
  return band;
}

/// θ = (t_x, t_y, ω, e_x, e_y, a, b): J ≈ a·φ + (b·φ)·S(p − d), φ = (1, u, v, u², uv, v²) (the illumination's
/// fall-off is quadratic: an affine a and b leave a gradient across the outline at the band's far ends, opposite
/// at either end), d = t + ω·L·(−v, u) + L·(e_x u, e_y v) the displacement at p (a small rotation ω and stretch
/// e about the seen region's centroid; L the normalising length). The stretch is fitted so that an outline seen
/// larger or smaller than the map's (a distance, or edge pixels drawn whole where the map sees a share of them)
/// does not read as a shift: with a shift alone the robust weights settled on one side's edge (on a simulated
/// slab whose top and bottom edge rows the map sees at 3/4 and the render draws whole, 0.17 px towards the top).
constexpr int kTerms = 6, kMotion = 5, kParams = kMotion + 2 * kTerms;
using Terms = Eigen::Matrix<double, kTerms, 1>;
Terms terms(double u, double v) { return (Terms() << 1, u, v, u * u, u * v, v * v).finished(); }
using Params = Eigen::Matrix<double, kParams, 1>;

/// Gauss–Newton from θ over the band pixels not in `left_out` (a sector, or −1), `iterations` steps,
/// Tukey weights from the residuals' robust scale (fixed `scale` when positive). Returns false when the
/// normal equations are singular.
bool fit_step(const std::vector<BandPixel>& band, const StepModel& m, double length, int left_out, int iterations, Params& theta,
              double* scale_out) {
  for (int it = 0; it < iterations; ++it) {
    std::vector<double> residuals(band.size(), 0.0);
    std::vector<Params> rows(band.size());
    for (std::size_t i = 0; i < band.size(); ++i) {
      const BandPixel& p = band[i];
      const double rx = -length * p.v, ry = length * p.u;  // the rotation's displacement per radian
      const double ex = length * p.u, ey = length * p.v;   // the stretch's per unit
      const double qx = p.x - theta[0] - theta[2] * rx - theta[3] * ex, qy = p.y - theta[1] - theta[2] * ry - theta[4] * ey;
      const double s = StepModel::at(m.s, qx, qy), gx = StepModel::at(m.gx, qx, qy), gy = StepModel::at(m.gy, qx, qy);
      const Terms phi = terms(p.u, p.v);
      const double a = theta.segment<kTerms>(kMotion).dot(phi), b = theta.segment<kTerms>(kMotion + kTerms).dot(phi);
      residuals[i] = p.value - (a + b * s);
      rows[i] << -b * gx, -b * gy, -b * (gx * rx + gy * ry), -b * gx * ex, -b * gy * ey, phi, s * phi;
    }
    std::vector<double> magnitude;
    magnitude.reserve(band.size());
    for (std::size_t i = 0; i < band.size(); ++i)
      if (band[i].sector != left_out) magnitude.push_back(std::abs(residuals[i]));
    if (magnitude.size() < 16) return false;
    std::nth_element(magnitude.begin(), magnitude.begin() + magnitude.size() / 2, magnitude.end());
    const double scale = std::max(1.4826 * magnitude[magnitude.size() / 2], 1e-9), c = 4.685 * scale;
    if (scale_out) *scale_out = scale;
    Eigen::Matrix<double, kParams, kParams> normal = Eigen::Matrix<double, kParams, kParams>::Zero();
    Params rhs = Params::Zero();
    for (std::size_t i = 0; i < band.size(); ++i) {
      if (band[i].sector == left_out) continue;
      const double r = residuals[i] / c, w = std::abs(r) < 1 ? (1 - r * r) * (1 - r * r) : 0.0;
      normal.selfadjointView<Eigen::Lower>().rankUpdate(rows[i], w);
      rhs += w * residuals[i] * rows[i];
    }
    const Eigen::LDLT<Eigen::Matrix<double, kParams, kParams>> ldlt(normal.selfadjointView<Eigen::Lower>());
    if (ldlt.info() != Eigen::Success) return false;
    Params step = ldlt.solve(rhs);
    if (!step.allFinite()) return false;
    const double move = step.head<2>().norm() + (std::abs(step[2]) + std::abs(step[3]) + std::abs(step[4])) * length;
    if (move > 1.0) step *= 1.0 / move;  // at most a pixel a step: the blurred step's basin
    theta += step;
    if (move < 1e-4) break;
  }
  return true;
}

}  // namespace

OutlineFit locate_outline(const cv::Mat& average, const cv::Mat& seen_share, const cv::Mat& exclude, const OutlineOptions& o) {
  OutlineFit f;
  if (average.empty() || average.size() != seen_share.size() || seen_share.type() != CV_32F ||
      (!exclude.empty() && exclude.size() != seen_share.size()))
    throw std::invalid_argument("locate_outline: the average, the seen share (CV_32F) and the excluded pixels must have the same size");
  const cv::Mat1f seen = seen_share;
  Params theta = Params::Zero();
  const double length = 0.5 * std::max(seen.cols, seen.rows);  // band_of's normalising length
  // Coarse to fine: a wide blur first (a basin of several pixels), then the measuring scale.
  bool first = true;
  std::vector<BandPixel> band;
  for (double sigma : {4 * o.smoothing_px, 2 * o.smoothing_px, o.smoothing_px}) {
    band = band_of(average, seen, exclude, std::max(o.band_px, 2.5 * sigma + 1), sigma);
    if (band.size() < 200) {
      f.problem = "the outline of the skin seen through the part is too short in the image (" + std::to_string(band.size()) + " band pixels)";
      return f;
    }
    const StepModel model(seen, sigma);  // the seen share is already the pixel's footprint over the outline
    if (first) {  // a and b for t = 0: linear least squares
      Eigen::MatrixXd A(band.size(), 2 * kTerms);
      Eigen::VectorXd y(band.size());
      for (std::size_t i = 0; i < band.size(); ++i) {
        const BandPixel& p = band[i];
        const double s = StepModel::at(model.s, p.x, p.y);
        const Terms phi = terms(p.u, p.v);
        A.row(static_cast<Eigen::Index>(i)) << phi.transpose(), s * phi.transpose();
        y[static_cast<Eigen::Index>(i)] = p.value;
      }
      theta.tail<2 * kTerms>() = A.colPivHouseholderQr().solve(y);
      first = false;
    }
    if (!fit_step(band, model, length, -1, 30, theta, nullptr)) {
      f.problem = "the outline fit is singular (no step across the band)";
      return f;
    }
    if (sigma == o.smoothing_px) {
      f.pixels = static_cast<long long>(band.size());
      f.shift_px = theta.head<2>();
      f.rotation_rad = theta[2];
      f.stretch = Vec2(theta[3], theta[4]);
      std::vector<double> step;  // (skin − beside) / skin along the band
      for (const BandPixel& p : band) {
        const Terms phi = terms(p.u, p.v);
        const double a = theta.segment<kTerms>(kMotion).dot(phi), b = theta.segment<kTerms>(kMotion + kTerms).dot(phi);
        if (std::abs(a + b) > 1e-9) step.push_back(b / (a + b));
      }
      if (!step.empty()) {
        std::nth_element(step.begin(), step.begin() + step.size() / 2, step.end());
        f.contrast = step[step.size() / 2];
      }
      // σ: jackknife over the 16 sectors.
      std::vector<Vec2> leave_one;
      for (int k = 0; k < 16; ++k) {
        Params t = theta;
        if (fit_step(band, model, length, k, 5, t, nullptr)) leave_one.push_back(t.head<2>());
      }
      if (leave_one.size() >= 8) {
        Vec2 mean = Vec2::Zero();
        for (const Vec2& t : leave_one) mean += t;
        mean /= static_cast<double>(leave_one.size());
        Vec2 var = Vec2::Zero();
        for (const Vec2& t : leave_one) var += (t - mean).cwiseAbs2();
        const double n = static_cast<double>(leave_one.size());
        f.sigma_px = (var * (n - 1) / n).cwiseSqrt();
      }
    }
  }
  if (!f.shift_px.allFinite() || !f.sigma_px.allFinite()) f.problem = "the outline fit did not converge";
  else if (f.contrast < o.min_contrast)
    f.problem = "the skin seen through the part hardly differs from what is seen beside it (step " + std::to_string(f.contrast) + ")";
  else if (f.sigma_px.maxCoeff() > o.max_sigma_px)
    f.problem = "the outline's position is unsure (1-sigma " + std::to_string(f.sigma_px.maxCoeff()) + " px)";
  else if (f.shift_px.norm() > o.max_shift_px)
    f.problem = "the outline moved by " + std::to_string(f.shift_px.norm()) + " px, more than is believed";
  f.found = f.problem.empty();
  return f;
}

}  // namespace clearfit
