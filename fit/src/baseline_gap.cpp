// The not-worn capture's gap from the captures (baseline_gap.hpp).
#include <clearfit/fit/baseline_gap.hpp>
#include <clearfit/format.hpp>
#include <clearfit/fit/blanching.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <sstream>

namespace clearfit {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr int kBlockPx = 32;
constexpr std::size_t kMaxSamples = 150000;  ///< more baseline pixels are subsampled evenly
/// The phases' move is measured only where the texture's blur weight (the share of seen skin under
/// the Gaussian) is at least this: next to the edge of the seen skin the texture is extrapolated.
constexpr float kInteriorWeight = 0.8f;

std::string fmt(double v, int digits = 2) { return fixed_digits(v, digits); }

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Log of a linear field where it is usable, NaN elsewhere.
ChartField log_field(const ChartField& f) {
  ChartField out{f.grid, std::vector<float>(f.value.size(), kNaN)};
  for (std::size_t k = 0; k < f.value.size(); ++k)
    if (std::isfinite(f.value[k]) && f.value[k] > 1e-4f) out.value[k] = std::log(f.value[k]);
  return out;
}

/// Bilinear sample of a CV_32F image with NaN holes at (x, y); NaN outside or next to a hole.
float bilinear(const cv::Mat& m, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return kNaN;
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const float a = m.at<float>(y0, x0), b = m.at<float>(y0, x0 + 1), c = m.at<float>(y0 + 1, x0), d = m.at<float>(y0 + 1, x0 + 1);
  return (1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d);
}

/// What every gap is compared on: per exit ray (index into rays.pixels()) its
/// pixel's baseline texture and log green, and its block.
struct Samples {
  std::vector<std::uint32_t> ray;
  std::vector<float> texture, log_green;  ///< at the sample's position moved by `shift`
  std::vector<int> block;
  int blocks = 0;
  cv::Mat tex, lg;                ///< the baseline's texture and log green (roi image, NaN off the seen skin)
  std::vector<cv::Point2f> at;    ///< each sample's position in tex, unmoved
  std::vector<char> interior;     ///< the texture's blur saw mostly seen skin around it (not next to the skin's edge)
  Vec2 shift = Vec2::Zero();      ///< the baseline image read this much further (px): the motion between the phases
};

/// Reads every sample's texture and log green at its position moved by `d`.
void move_samples(Samples& s, const Vec2& d) {
  s.shift = d;
  for (std::size_t i = 0; i < s.at.size(); ++i) {
    const double x = s.at[i].x + d.x(), y = s.at[i].y + d.y();
    s.texture[i] = bilinear(s.tex, x, y), s.log_green[i] = bilinear(s.lg, x, y);
  }
}

/// True when the finite values are all one value (or there are none): a capture without any skin
/// texture, e.g. saturated or black where it sees the skin.
bool uniform(const std::vector<float>& values) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (float v : values)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  return !(hi > lo);
}

/// Chart uv of each sample at a gap (NaN where the baseline map is invalid), each gap landed once for the
/// samples' rays (the coarse grid is searched up to three times). One gap at a time: landing gaps in parallel
/// (each an offset skin surface, its ray index and rays) made the run's peak memory 8-21 MB larger and vary
/// from run to run (175-188 MB against 167 MB, LongCaptureCli). The samples' rays do not change (move_samples
/// reads them elsewhere in the image, not other rays).
class GapUv {
 public:
  GapUv(const BaselineRays& rays, const Samples& s) : rays_(rays), s_(s) {}
  /// Lands the gaps not landed yet (each is one offset skin surface and its rays; that surface's own casts run in parallel).
  void land(const std::vector<double>& gaps) {
    std::vector<double> todo;
    for (double g : gaps)
      if (!memo_.count(g) && std::find(todo.begin(), todo.end(), g) == todo.end()) todo.push_back(g);
    std::vector<std::vector<Vec2>> uv(todo.size());
    for (std::size_t k = 0; k < todo.size(); ++k) uv[k] = rays_.chart_uv(todo[k], s_.ray);
    for (std::size_t k = 0; k < todo.size(); ++k) memo_.emplace(todo[k], std::move(uv[k]));
  }
  const std::vector<Vec2>& operator()(double gap) {
    land({gap});
    return memo_.at(gap);
  }

 private:
  const BaselineRays& rays_;
  const Samples& s_;
  std::map<double, std::vector<Vec2>> memo_;
};

/// Camera pixels per mm of skin at the baseline map of `gap` (median over horizontal neighbours).
double pixels_per_mm(const BaselineRays& rays, double gap) {
  const auto& px = rays.pixels();
  std::vector<std::uint32_t> pairs;  // i, i + 1: horizontal neighbours
  const std::size_t every = std::max<std::size_t>(1, px.size() / 20000);
  for (std::size_t i = 0; i + 1 < px.size(); i += every)
    if (px[i + 1] == px[i] + 1 && (px[i] + 1) % rays.width() != 0) pairs.push_back(static_cast<std::uint32_t>(i)), pairs.push_back(static_cast<std::uint32_t>(i + 1));
  const std::vector<Vec2> uv = rays.chart_uv(gap, pairs);
  std::vector<double> steps;
  for (std::size_t k = 0; k + 1 < uv.size(); k += 2)
    if (const double d = (uv[k + 1] - uv[k]).norm(); d > 0) steps.push_back(d);
  const double mm = median(std::move(steps));
  return std::isfinite(mm) && mm > 0 ? 1.0 / mm : 1.0;
}

/// The baseline's texture per candidate pixel: log green minus its blur,
/// normalised over the pixels that see the skin at gap `seen_at` (not the background).
Samples baseline_samples(const BaselineRays& rays, const PhaseAverage& base, double sigma_px, double seen_at) {
  const cv::Rect& roi = base.roi;
  const RefractionMap seen = rays.map(seen_at);
  cv::Mat L(roi.size(), CV_32F, cv::Scalar(0)), w(roi.size(), CV_32F, cv::Scalar(0));
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) {
      // The average at q shows the image at q − residual + roi origin.
      const int ix = static_cast<int>(std::lround(x - base.residual_shift_px.x() + roi.x));
      const int iy = static_cast<int>(std::lround(y - base.residual_shift_px.y() + roi.y));
      if (ix < 0 || iy < 0 || ix >= seen.width || iy >= seen.height || seen.status[seen.index(ix, iy)] != PixelStatus::valid) continue;
      if (const float g = base.mean.at<float>(y, x); std::isfinite(g) && g > 1e-4f) L.at<float>(y, x) = std::log(g), w.at<float>(y, x) = 1;
    }
  cv::Mat Lb, wb;
  cv::GaussianBlur(L, Lb, cv::Size(), sigma_px, sigma_px, cv::BORDER_CONSTANT);
  cv::GaussianBlur(w, wb, cv::Size(), sigma_px, sigma_px, cv::BORDER_CONSTANT);
  cv::Mat tex(roi.size(), CV_32F, cv::Scalar(kNaN)), lg(roi.size(), CV_32F, cv::Scalar(kNaN));
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x)
      if (w.at<float>(y, x) > 0 && wb.at<float>(y, x) > 0.05f) {
        tex.at<float>(y, x) = L.at<float>(y, x) - Lb.at<float>(y, x) / wb.at<float>(y, x);
        lg.at<float>(y, x) = L.at<float>(y, x);
      }
  Samples s;
  const int bx = (rays.width() + kBlockPx - 1) / kBlockPx;
  std::vector<int> block_id(static_cast<std::size_t>(bx) * ((rays.height() + kBlockPx - 1) / kBlockPx), -1);
  const auto& px = rays.pixels();
  const std::size_t every = std::max<std::size_t>(1, (px.size() + kMaxSamples - 1) / kMaxSamples);
  for (std::size_t ray = 0; ray < px.size(); ray += every) {
    const std::uint32_t p = px[ray];
    const int x = static_cast<int>(p % rays.width()), y = static_cast<int>(p / rays.width());
    // The image at pixel p is the average at p + residual − roi origin.
    const double qx = x + base.residual_shift_px.x() - roi.x, qy = y + base.residual_shift_px.y() - roi.y;
    const float t = bilinear(tex, qx, qy), l = bilinear(lg, qx, qy);
    if (!std::isfinite(t) || !std::isfinite(l)) continue;
    int& b = block_id[static_cast<std::size_t>(y / kBlockPx) * bx + x / kBlockPx];
    if (b < 0) b = s.blocks++;
    s.ray.push_back(static_cast<std::uint32_t>(ray)), s.texture.push_back(t), s.log_green.push_back(l), s.block.push_back(b);
    s.at.emplace_back(static_cast<float>(qx), static_cast<float>(qy));
    s.interior.push_back(bilinear(wb, qx, qy) >= kInteriorWeight);
  }
  s.tex = tex, s.lg = lg;
  return s;
}

/// Normalised correlation of the samples' texture with the worn texture at `uv` (NaN where it is undefined).
/// Running sums of a normalised (Pearson) correlation.
struct Pearson {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  long long n = 0;
  void add(double x, double y) { sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y, ++n; }
  /// The correlation, or `none` with fewer than 100 pairs or no spread.
  double value(double none) const {
    if (n < 100) return none;
    const double vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
    return vx > 0 && vy > 0 ? (sxy - sx * sy / n) / std::sqrt(vx * vy) : none;
  }
};

double correlation(const Samples& s, const std::vector<Vec2>& uv, const ChartField& worn_texture, const std::vector<char>& use,
                   long long* count = nullptr) {
  Pearson r;
  for (std::size_t i = 0; i < s.ray.size(); ++i) {
    if (!use[i] || !uv[i].allFinite() || !std::isfinite(s.texture[i])) continue;
    const double y = worn_texture.sample(uv[i]);
    if (std::isfinite(y)) r.add(s.texture[i], y);
  }
  if (count) *count = r.n;
  return r.value(0);
}

/// Pixels of pressed places at `uv`: the log ratio worn / baseline, smoothed on
/// the chart, more than 4 robust deviations above its median.
std::vector<char> not_pressed(const Samples& s, const std::vector<Vec2>& uv, const ChartField& worn_log) {
  const ChartGrid& g = worn_log.grid;
  std::vector<float> sum(g.size(), 0.f), cnt(g.size(), 0.f);
  std::vector<float> ratio(s.ray.size(), kNaN);
  for (std::size_t i = 0; i < s.ray.size(); ++i) {
    if (!uv[i].allFinite() || !std::isfinite(s.log_green[i])) continue;
    const float w = worn_log.sample(uv[i]);
    if (!std::isfinite(w)) continue;
    ratio[i] = w - s.log_green[i];
    const int ti = static_cast<int>(std::lround((uv[i].x() - g.uv_origin.x()) / g.texel_mm));
    const int tj = static_cast<int>(std::lround((uv[i].y() - g.uv_origin.y()) / g.texel_mm));
    if (ti < 0 || tj < 0 || ti >= g.width || tj >= g.height) continue;
    sum[g.index(ti, tj)] += ratio[i], cnt[g.index(ti, tj)] += 1;
  }
  ChartField r{g, std::vector<float>(g.size(), kNaN)};
  for (std::size_t k = 0; k < g.size(); ++k)
    if (cnt[k] > 0) r.value[k] = sum[k] / cnt[k];
  r = smooth_field(r, 0.5);
  std::vector<double> v;
  for (float x : r.value)
    if (std::isfinite(x)) v.push_back(x);
  const double m = median(v);
  for (double& x : v) x = std::abs(x - m);
  const double limit = m + 4 * 1.4826 * std::max(median(v), 1e-6);
  std::vector<char> keep(s.ray.size(), 1);
  for (std::size_t i = 0; i < s.ray.size(); ++i)
    if (uv[i].allFinite())
      if (const float x = r.sample(uv[i]); std::isfinite(x) && x > limit) keep[i] = 0;
  return keep;
}

/// Vertex of the least-squares parabola through (g_j, t_j); NaN unless it opens upwards.
double parabola_vertex(const std::vector<double>& g, const std::vector<double>& t) {
  const double c = g[g.size() / 2];
  Eigen::MatrixXd A(g.size(), 3);
  Eigen::VectorXd b(g.size());
  for (std::size_t j = 0; j < g.size(); ++j) A(j, 0) = (g[j] - c) * (g[j] - c), A(j, 1) = g[j] - c, A(j, 2) = 1, b(j) = t[j];
  const Eigen::Vector3d q = A.colPivHouseholderQr().solve(b);
  return q(0) > 0 ? c - q(1) / (2 * q(0)) : std::numeric_limits<double>::quiet_NaN();
}

/// Fine stage around `centre`: the vertex of the summed block residuals, its bootstrap σ, the
/// match and the pixels compared.
struct Fine {
  double gap = NAN, sigma = NAN, match = 0, shift = 0;
  long long pixels = 0;
};
Fine fine_fit(GapUv& uv_at, const Samples& s, const ChartField& worn_texture, const std::vector<char>& keep,
              double centre, const GapSearchOptions& o) {
  const double d = o.step_mm / 2;
  const double lo = std::clamp(centre - 2 * d, 0.0, o.max_mm - 4 * d);
  std::vector<double> gaps;
  for (int j = 0; j < 5; ++j) gaps.push_back(lo + j * d);
  uv_at.land(gaps);
  std::vector<const std::vector<Vec2>*> uv_of;
  for (double g : gaps) uv_of.push_back(&uv_at(g));
  auto uv = [&uv_of](int j) -> const std::vector<Vec2>& { return *uv_of[j]; };
  // Pixels compared at every gap.
  std::vector<char> use = keep;
  std::vector<std::array<float, 5>> y(s.ray.size());
  for (std::size_t i = 0; i < s.ray.size(); ++i) {
    if (!std::isfinite(s.texture[i])) use[i] = 0;
    for (int j = 0; j < 5 && use[i]; ++j) {
      y[i][j] = uv(j)[i].allFinite() ? worn_texture.sample(uv(j)[i]) : kNaN;
      if (!std::isfinite(y[i][j])) use[i] = 0;
    }
  }
  Fine f;
  f.match = correlation(s, uv(2), worn_texture, use, &f.pixels);
  double sxy = 0, syy = 0;
  std::vector<double> shifts;
  for (std::size_t i = 0; i < s.ray.size(); ++i)
    if (use[i]) {
      sxy += s.texture[i] * y[i][2], syy += double(y[i][2]) * y[i][2];
      if (shifts.size() < 50000) shifts.push_back((uv(4)[i] - uv(0)[i]).norm() / (gaps[4] - gaps[0]));
    }
  f.shift = median(std::move(shifts));
  if (f.pixels < 100 || !(syy > 0)) return f;
  const double a = sxy / syy;
  std::vector<std::array<double, 5>> block(s.blocks, std::array<double, 5>{});
  for (std::size_t i = 0; i < s.ray.size(); ++i)
    if (use[i])
      for (int j = 0; j < 5; ++j) {
        const double r = s.texture[i] - a * y[i][j];
        block[s.block[i]][j] += r * r;
      }
  auto vertex = [&](const std::vector<int>& which) {
    std::vector<double> t(5, 0.0);
    for (int b : which)
      for (int j = 0; j < 5; ++j) t[j] += block[b][j];
    return parabola_vertex(gaps, t);
  };
  std::vector<int> all(s.blocks);
  for (int b = 0; b < s.blocks; ++b) all[b] = b;
  f.gap = vertex(all);
  std::mt19937_64 rng(o.seed);
  std::uniform_int_distribution<int> pick(0, std::max(0, s.blocks - 1));
  double sum = 0, sum2 = 0;
  int n = 0;
  std::vector<int> draw(s.blocks);
  for (int r = 0; r < o.bootstrap; ++r) {
    for (int& b : draw) b = pick(rng);
    const double v = vertex(draw);
    if (!std::isfinite(v)) continue;
    sum += v, sum2 += v * v, ++n;
  }
  f.sigma = n > 10 ? std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n))) : NAN;
  if (n < o.bootstrap / 2) f.sigma = NAN;  // the parabola often does not open upwards: no minimum here
  return f;
}

/// Normalised correlation of the baseline texture read `d` further with the worn values `y`, over every `every`-th sample.
double shifted_correlation(const Samples& s, const std::vector<float>& y, const Vec2& d, int every) {
  Pearson r;
  for (std::size_t i = 0; i < y.size(); i += every) {
    if (!std::isfinite(y[i])) continue;
    const double x = bilinear(s.tex, s.at[i].x + d.x(), s.at[i].y + d.y());
    if (std::isfinite(x)) r.add(x, y[i]);
  }
  return r.value(-1);
}

/// Per block, the normal equations of Gauss–Newton on (d, gain) for the residual
/// baseline texture(at + d) − gain · y.
using ShiftNormals = std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>>;
ShiftNormals shift_normals(const Samples& s, const std::vector<float>& y, const Vec2& d, double gain) {
  ShiftNormals n(s.blocks, {Eigen::Matrix3d::Zero(), Eigen::Vector3d::Zero()});
  for (std::size_t i = 0; i < y.size(); ++i) {
    if (!std::isfinite(y[i])) continue;
    const double x = s.at[i].x + d.x(), yy = s.at[i].y + d.y();
    const double t = bilinear(s.tex, x, yy);
    const double gx = bilinear(s.tex, x + 0.5, yy) - bilinear(s.tex, x - 0.5, yy);
    const double gy = bilinear(s.tex, x, yy + 0.5) - bilinear(s.tex, x, yy - 0.5);
    if (!std::isfinite(t) || !std::isfinite(gx) || !std::isfinite(gy)) continue;
    const Eigen::Vector3d J(gx, gy, -y[i]);
    auto& [A, b] = n[s.block[i]];
    A += J * J.transpose(), b += J * (t - gain * y[i]);
  }
  return n;
}

/// The step that solves the summed normal equations of `which` blocks (NaN when singular).
Eigen::Vector3d shift_step(const ShiftNormals& n, const std::vector<int>& which) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (int k : which) A += n[k].first, b += n[k].second;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
  if (ldlt.info() != Eigen::Success || !(A.trace() > 0) || ldlt.rcond() < 1e-9) return Eigen::Vector3d::Constant(NAN);
  return -ldlt.solve(b);
}

/// The motion between the phases' references (GapSearchOptions::max_shift_px): the shift of the
/// baseline image that best carries its texture onto the worn texture at `uv` (one gap), over the
/// samples `keep`. The best whole-pixel shift by correlation (every fourth sample), then Gauss–Newton
/// on the shift and a gain; σ: the spread of the step over block-bootstrap resamplings at the optimum.
struct ShiftFit {
  Vec2 shift = Vec2::Zero(), sigma = Vec2::Constant(NAN);
  bool converged = false;
};
ShiftFit fit_shift(const Samples& s, const std::vector<Vec2>& uv, const ChartField& worn_texture, const std::vector<char>& keep,
                   const GapSearchOptions& o) {
  std::vector<float> y(s.ray.size(), kNaN);
  for (std::size_t i = 0; i < y.size(); ++i)
    if (keep[i] && s.interior[i] && uv[i].allFinite()) y[i] = worn_texture.sample(uv[i]);
  ShiftFit f;
  Vec2 d = Vec2::Zero();
  double best = shifted_correlation(s, y, d, 4);
  const int reach = static_cast<int>(std::ceil(o.max_shift_px));
  for (int dy = -reach; dy <= reach; ++dy)
    for (int dx = -reach; dx <= reach; ++dx)
      if (dx * dx + dy * dy <= reach * reach)
        if (const double c = shifted_correlation(s, y, Vec2(dx, dy), 4); c > best) best = c, d = Vec2(dx, dy);
  if (!(best > o.min_match)) return f;
  const Vec2 start = d;
  double gain = 1;
  std::vector<int> all(s.blocks);
  for (int k = 0; k < s.blocks; ++k) all[k] = k;
  for (int iter = 0; iter < 20 && !f.converged; ++iter) {
    const Eigen::Vector3d step = shift_step(shift_normals(s, y, d, gain), all);
    if (!step.allFinite()) return f;
    d += step.head<2>(), gain += step(2);
    if ((d - start).norm() > 2) return f;  // walked off the whole-pixel optimum: no fine minimum
    f.converged = step.head<2>().norm() < 1e-3;
  }
  if (!f.converged || (d.array().abs() > o.max_shift_px).any()) return ShiftFit{};
  f.shift = d;
  const ShiftNormals n = shift_normals(s, y, d, gain);
  std::mt19937_64 rng(o.seed);
  std::uniform_int_distribution<int> pick(0, std::max(0, s.blocks - 1));
  Vec2 sum = Vec2::Zero(), sum2 = Vec2::Zero();
  int m = 0;
  std::vector<int> draw(s.blocks);
  for (int r = 0; r < o.bootstrap; ++r) {
    for (int& b : draw) b = pick(rng);
    const Eigen::Vector3d step = shift_step(n, draw);
    if (!step.allFinite()) continue;
    sum += step.head<2>(), sum2 += step.head<2>().cwiseAbs2(), ++m;
  }
  if (m > o.bootstrap / 2) f.sigma = (sum2 / m - (sum / m).cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
  return f;
}

}  // namespace

void GapSearchOptions::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("GapSearchOptions::" + what); };
  if (!(std::isfinite(max_mm) && max_mm > 0 && max_mm <= 20)) fail("max_mm = " + std::to_string(max_mm) + ": must be in (0, 20] mm");
  if (!(std::isfinite(step_mm) && step_mm > 0 && step_mm <= max_mm / 4))
    fail("step_mm = " + std::to_string(step_mm) + ": must be positive and at most max_mm / 4");
  if (!(std::isfinite(highpass_mm) && highpass_mm > 0)) fail("highpass_mm = " + std::to_string(highpass_mm) + ": must be positive");
  if (!(std::isfinite(max_sigma_mm) && max_sigma_mm > 0)) fail("max_sigma_mm = " + std::to_string(max_sigma_mm) + ": must be positive");
  if (!(warn_sigma_mm > 0 && warn_sigma_mm <= max_sigma_mm))
    fail("warn_sigma_mm = " + std::to_string(warn_sigma_mm) + ": must be positive and at most max_sigma_mm");
  if (!(min_match >= 0 && min_match < 1)) fail("min_match = " + std::to_string(min_match) + ": must be in [0, 1)");
  if (bootstrap < 20) fail("bootstrap = " + std::to_string(bootstrap) + ": must be at least 20");
  if (!(std::isfinite(max_shift_px) && max_shift_px >= 0 && max_shift_px <= 20))
    fail("max_shift_px = " + std::to_string(max_shift_px) + ": must be in [0, 20] px");
}

namespace {

/// The worn average's texture on the chart: log green minus its blur of highpass_mm.
ChartField worn_texture_of(const ChartField& worn_log, const GapSearchOptions& o) {
  ChartField t = worn_log;
  const ChartField blurred = smooth_field(worn_log, o.highpass_mm);
  for (std::size_t k = 0; k < t.value.size(); ++k) t.value[k] -= blurred.value[k];
  return t;
}

/// Stage 1: the correlation every step_mm over [0, max_mm] (into e.curve); the best gap's index
/// and, between its neighbours, the parabola's vertex.
std::pair<int, double> coarse_search(GapUv& uv_at, const Samples& s, const ChartField& worn_texture, const GapSearchOptions& o,
                                     GapEstimate& e) {
  const std::vector<char> everything(s.ray.size(), 1);
  int best = -1;
  std::vector<double> cost, grid;
  e.curve.clear();
  for (double g = 0; g <= o.max_mm + 1e-9; g += o.step_mm) grid.push_back(g);
  uv_at.land(grid);
  for (double g : grid) {
    cost.push_back(1 - correlation(s, uv_at(g), worn_texture, everything));
    e.curve.emplace_back(g, cost.back());
    if (best < 0 || cost.back() < cost[best]) best = static_cast<int>(cost.size()) - 1;
  }
  const int last = static_cast<int>(cost.size()) - 1;
  double centre = e.curve[best].first;
  if (best > 0 && best < last) {
    const double den = cost[best - 1] - 2 * cost[best] + cost[best + 1];
    if (den > 0) centre += o.step_mm * 0.5 * (cost[best - 1] - cost[best + 1]) / den;
  }
  return {best, centre};
}

/// The motion between the phases at `gap`, with the pressed places there left out; the samples are
/// moved by it and e.phase_shift_* filled. False when it could not be measured (samples unmoved).
bool measure_phase_shift(GapUv& uv_at, Samples& s, const ChartField& worn_texture, const ChartField& worn_log, double gap,
                         const GapSearchOptions& o, GapEstimate& e) {
  move_samples(s, Vec2::Zero());
  const std::vector<Vec2>& uv = uv_at(gap);
  const ShiftFit sf = fit_shift(s, uv, worn_texture, not_pressed(s, uv, worn_log), o);
  e.phase_shift_measured = sf.converged && sf.sigma.allFinite();
  e.phase_shift_px = e.phase_shift_measured ? sf.shift : Vec2::Zero();
  e.phase_shift_sigma_px = e.phase_shift_measured ? sf.sigma : Vec2::Zero();
  move_samples(s, e.phase_shift_px);
  return e.phase_shift_measured;
}

/// The shift could not be measured at the best gap of the unshifted textures: a move between the phases larger
/// than the gap's own moves the unshifted curve's minimum far off (measured: the sample's scene at a quarter of its
/// resolution, 1.7 px of move, read its best match at 0 mm for a 1 mm gap, where the shift's fit found no minimum).
/// So the shift is measured at every other gap of the coarse grid and the gap whose shifted textures match best
/// (the coarse curve's least cost) is kept, with its shift; none measured: the samples are left unmoved.
std::pair<int, double> shift_over_the_range(GapUv& uv_at, Samples& s, const ChartField& worn_texture, const ChartField& worn_log,
                                            const GapSearchOptions& o, GapEstimate& e) {
  GapEstimate trial = e, kept;
  double least = std::numeric_limits<double>::infinity();
  for (double g = 0; g <= o.max_mm + 1e-9; g += 2 * o.step_mm) {
    if (!measure_phase_shift(uv_at, s, worn_texture, worn_log, g, o, trial)) continue;
    coarse_search(uv_at, s, worn_texture, o, trial);
    for (const auto& c : trial.curve)
      if (c.second < least) least = c.second, kept = trial;
  }
  if (!kept.phase_shift_measured) {
    move_samples(s, Vec2::Zero());
    e.phase_shift_measured = false, e.phase_shift_px = e.phase_shift_sigma_px = Vec2::Zero();
    return coarse_search(uv_at, s, worn_texture, o, e);
  }
  e.phase_shift_measured = true, e.phase_shift_px = kept.phase_shift_px, e.phase_shift_sigma_px = kept.phase_shift_sigma_px;
  move_samples(s, e.phase_shift_px);
  return coarse_search(uv_at, s, worn_texture, o, e);
}

Samples samples_for(const BaselineRays& rays, const PhaseAverage& baseline, const GapSearchOptions& o) {
  return baseline_samples(rays, baseline, o.highpass_mm * pixels_per_mm(rays, 0.5 * o.max_mm), 0.5 * o.max_mm);
}

}  // namespace

GapEstimate estimate_gap(const BaselineRays& rays, const PhaseAverage& baseline, const ChartField& worn_green, const GapSearchOptions& o) {
  o.validate();
  GapEstimate e;
  const ChartField worn_log = log_field(worn_green);
  const ChartField worn_texture = worn_texture_of(worn_log, o);
  Samples s = samples_for(rays, baseline, o);
  GapUv uv_at(rays, s);
  // 1. Coarse; with the motion between the phases measured at its best gap and taken out, again.
  auto [best, centre] = coarse_search(uv_at, s, worn_texture, o, e);
  if (o.max_shift_px > 0) {
    if (!measure_phase_shift(uv_at, s, worn_texture, worn_log, centre, o, e))
      std::tie(best, centre) = shift_over_the_range(uv_at, s, worn_texture, worn_log, o, e);
    else
      std::tie(best, centre) = coarse_search(uv_at, s, worn_texture, o, e);
    if (e.phase_shift_measured && measure_phase_shift(uv_at, s, worn_texture, worn_log, centre, o, e))
      std::tie(best, centre) = coarse_search(uv_at, s, worn_texture, o, e);
  }
  const int last = static_cast<int>(e.curve.size()) - 1;
  std::vector<double> cost;
  for (const auto& c : e.curve) cost.push_back(c.second);
  // 2. Pressed places out, 3. fine.
  const std::vector<char> keep = not_pressed(s, uv_at(centre), worn_log);
  for (char k : keep) e.pressed_pixels += !k;
  Fine f;
  for (int iter = 0; iter < 4; ++iter) {
    f = fine_fit(uv_at, s, worn_texture, keep, centre, o);
    if (!std::isfinite(f.gap)) break;
    const double d = o.step_mm / 2, lo = std::clamp(centre - 2 * d, 0.0, o.max_mm - 4 * d);
    if (f.gap >= lo - 0.25 * d && f.gap <= lo + 4.25 * d) break;
    centre = std::clamp(f.gap, 0.0, o.max_mm);
  }
  e.gap_mm = std::isfinite(f.gap) ? std::clamp(f.gap, 0.0, o.max_mm) : centre;
  e.sigma_mm = std::isfinite(f.sigma) ? f.sigma : o.max_mm;
  if (e.phase_shift_measured) measure_phase_shift(uv_at, s, worn_texture, worn_log, e.gap_mm, o, e);
  e.match = f.match;
  e.shift_mm_per_mm = std::isfinite(f.shift) ? f.shift : 0;
  e.pixels = f.pixels;
  // Trustworthy?
  const std::string at = " (best texture correlation " + fmt(1 - cost[best], 3) + " at " + fmt(e.curve[best].first) + " mm)";
  const char* blank = uniform(worn_green.value) ? "worn" : uniform(s.log_green) ? "not-worn" : nullptr;
  if (blank)
    e.problem = std::string("the ") + blank + " capture shows no skin texture at all: every pixel that sees the skin has the same "
                "green value (a saturated, black or blank capture)";
  else if (s.ray.size() < 100 || f.pixels < 100)
    e.problem = "too few baseline pixels see skin that the worn capture sees too (" + std::to_string(f.pixels) + ")";
  else if (best == last)
    e.problem = "the textures match best at the end of the searched range, " + fmt(o.max_mm) + " mm" + at;
  else if (e.match < o.min_match)
    e.problem = "the skin texture of the two captures does not match at any gap" + at;
  else if (!std::isfinite(f.gap) || !(e.sigma_mm <= o.max_sigma_mm))
    e.problem = "the estimate is unsure: " + fmt(e.gap_mm) + " ± " + fmt(e.sigma_mm) + " mm (at most ± " + fmt(o.max_sigma_mm) + " mm accepted)";
  e.estimated = e.problem.empty();
  return e;
}

}  // namespace clearfit
