#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/fit/timeseries.hpp>

#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace clearfit {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string fmt(double v, int digits = 2) { return fixed_digits(v, digits); }

}  // namespace

void TimeSeriesOptions::validate() const {
  auto fail = [](const std::string& key, const std::string& rule) { throw InputError("", "timeseries." + key, rule); };
  if (cell_px < 1 || cell_px > 256) fail("cell_px", "must be a whole number of pixels in 1..256");
  if (!(max_mb >= 1 && max_mb <= 65536)) fail("max_mb", "must be in 1..65536 (MB)");
  if (!(texel_mm > 0 && texel_mm <= 10)) fail("texel_mm", "must be in (0, 10] mm");
  if (!(onset_window_s > 0 && onset_window_s <= 600)) fail("onset_window_s", "must be in (0, 600] s");
  if (!(min_refill_taus >= 1 && min_refill_taus <= 20)) fail("min_refill_taus", "must be in 1..20");
}

// ---------------------------------------------------------------------------------------------
// Recorder

TimeSeriesRecorder::TimeSeriesRecorder(const cv::Rect& roi, const TimeSeriesOptions& o, int expected_frames)
    : roi_(roi), cell_px_(o.cell_px) {
  if (roi.area() <= 0) throw std::invalid_argument("TimeSeriesRecorder: empty roi");
  cells_ = cv::Size((roi.width + cell_px_ - 1) / cell_px_, (roi.height + cell_px_ - 1) / cell_px_);
  const double per_bin = static_cast<double>(cell_count()) * sizeof(float);
  max_bins_ = std::max(16, static_cast<int>(std::min(1e9, o.max_mb * 1048576.0 / per_bin)) / 2 * 2);
  const int first = expected_frames > 0 ? std::min(expected_frames + 1, max_bins_) : std::min(256, max_bins_);
  sum_.reserve(static_cast<std::size_t>(first) * cell_count());
  count_.reserve(max_bins_);
  row_.assign(cell_count(), 0.f);
}

void TimeSeriesRecorder::merge_pairs() {
  const std::size_t n = cell_count();
  const int merged = (bins_ + 1) / 2;
  for (int b = 0; b < merged; ++b) {
    float* dst = sum_.data() + static_cast<std::size_t>(b) * n;
    const float* a = sum_.data() + static_cast<std::size_t>(2 * b) * n;
    std::copy(a, a + n, dst);
    int count = count_[2 * b];
    if (2 * b + 1 < bins_) {
      const float* c = a + n;
      for (std::size_t k = 0; k < n; ++k) dst[k] += c[k];
      count += count_[2 * b + 1];
    }
    count_[b] = count;
  }
  bins_ = merged;
  sum_.resize(static_cast<std::size_t>(bins_) * n);
  count_.resize(bins_);
  bin_frames_ *= 2;
}

void TimeSeriesRecorder::add(const cv::Mat& frame, cv::Point d) {
  if (frame.type() != CV_8UC3 && frame.type() != CV_16UC3) throw std::invalid_argument("TimeSeriesRecorder::add: expected a BGR frame, 8 or 16 bits");
  std::fill(row_.begin(), row_.end(), 0.f);
  // Every other row and column: the cells' means, not their detail, are kept.
  auto sum_rows = [&]<class Pixel>(const float* lut) {
    for (int y = 0; y < roi_.height; y += 2) {
      const auto* src = frame.ptr<Pixel>(std::clamp(roi_.y + y + d.y, 0, frame.rows - 1));
      float* cells = row_.data() + static_cast<std::size_t>(y / cell_px_) * cells_.width;
      for (int x = 0; x < roi_.width; x += 2) cells[x / cell_px_] += lut[src[std::clamp(roi_.x + x + d.x, 0, frame.cols - 1)][1]];
    }
  };
  if (frame.depth() == CV_8U) sum_rows.operator()<cv::Vec3b>(srgb::to_linear_table8());
  else sum_rows.operator()<cv::Vec3w>(srgb::to_linear_table16());
  // Samples per cell: the even offsets inside it.
  for (int j = 0; j < cells_.height; ++j) {
    const int h = std::min(cell_px_, roi_.height - j * cell_px_), y0 = j * cell_px_;
    const int rows = (y0 + h + 1) / 2 - (y0 + 1) / 2;
    for (int i = 0; i < cells_.width; ++i) {
      const int w = std::min(cell_px_, roi_.width - i * cell_px_), x0 = i * cell_px_;
      const int cols = (x0 + w + 1) / 2 - (x0 + 1) / 2;
      row_[static_cast<std::size_t>(j) * cells_.width + i] /= static_cast<float>(std::max(1, rows * cols));
    }
  }
  int b = frames_ / bin_frames_;
  if (b >= bins_) {
    if (bins_ == max_bins_) {
      merge_pairs();
      b = frames_ / bin_frames_;
    }
    if (b >= bins_) {
      ++bins_;
      sum_.resize(static_cast<std::size_t>(bins_) * cell_count(), 0.f);
      count_.push_back(0);
    }
  }
  float* dst = sum_.data() + static_cast<std::size_t>(b) * cell_count();
  for (std::size_t k = 0; k < cell_count(); ++k) dst[k] += row_[k];
  ++count_[b];
  ++frames_;
}

// ---------------------------------------------------------------------------------------------
// Fits

namespace {

/// Least squares of residuals r(p) (m values) by Levenberg–Marquardt with a numerical
/// Jacobian; the covariance is s²·(JᵀJ)⁻¹, s² = |r|²/(m − n).
struct LeastSquares {
  Eigen::VectorXd p;
  Eigen::MatrixXd covariance;
  double rms = 0;
  bool ok = false;
};

LeastSquares least_squares(const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>& residuals, Eigen::VectorXd p, int m) {
  struct Functor {
    using Scalar = double;
    using InputType = Eigen::VectorXd;
    using ValueType = Eigen::VectorXd;
    using JacobianType = Eigen::MatrixXd;
    enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
    const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>* f;
    int n, m;
    int inputs() const { return n; }
    int values() const { return m; }
    int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& r) const {
      (*f)(x, r);
      return 0;
    }
  };
  Functor fn{&residuals, static_cast<int>(p.size()), m};
  Eigen::NumericalDiff<Functor, Eigen::Central> diff(fn);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Functor, Eigen::Central>> lm(diff);
  lm.parameters.maxfev = 2000;
  lm.parameters.xtol = 1e-10;
  lm.parameters.ftol = 1e-12;
  const int status = lm.minimize(p);
  LeastSquares out;
  out.p = p;
  Eigen::VectorXd r(m);
  residuals(p, r);
  Eigen::MatrixXd J(m, p.size());
  diff.df(p, J);
  const double dof = std::max(1, m - static_cast<int>(p.size()));
  out.rms = std::sqrt(r.squaredNorm() / m);
  const Eigen::MatrixXd JtJ = J.transpose() * J;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(JtJ);
  out.ok = status > 0 && r.allFinite() && p.allFinite() && lu.isInvertible();
  if (out.ok) out.covariance = lu.inverse() * (r.squaredNorm() / dof);
  return out;
}

/// The model's mean over bin k's frames.
double bin_mean(const BinnedSeries& s, int k, const std::function<double(double)>& model) {
  double sum = 0;
  for (int f = s.first[k]; f < s.first[k] + s.count[k]; ++f) sum += model(f / s.fps);
  return sum / s.count[k];
}

}  // namespace

TimeConstantFit fit_onset(const BinnedSeries& s, double t0_guess) {
  TimeConstantFit fit;
  const int m = static_cast<int>(s.y.size());
  fit.bins = m;
  if (m < 6) {
    fit.note = "too few samples around the press (" + std::to_string(m) + ", 6 needed)";
    return fit;
  }
  double tail = 0;
  const int q = std::max(1, m / 4);
  for (int k = m - q; k < m; ++k) tail += s.y[k];
  auto model = [](const Eigen::VectorXd& p) {
    return [a = p[0], t0 = p[1], tau = std::exp(p[2])](double t) { return t > t0 ? a * (1 - std::exp(-(t - t0) / tau)) : 0.0; };
  };
  auto residuals = [&](const Eigen::VectorXd& p, Eigen::VectorXd& r) {
    const auto f = model(p);
    for (int k = 0; k < m; ++k) r[k] = bin_mean(s, k, f) - s.y[k];
  };
  // Several starting time constants (0.1–1 s, SKIN.md's onset range): the best fit is kept.
  LeastSquares best;
  for (double tau0 : {0.1, 0.3, 1.0}) {
    const LeastSquares ls = least_squares(residuals, Eigen::Vector3d(tail / q, t0_guess, std::log(tau0)), m);
    if (ls.ok && (!best.ok || ls.rms < best.rms)) best = ls;
  }
  if (!best.ok) {
    fit.note = "the onset fit did not converge";
    return fit;
  }
  fit.fitted = true;
  fit.amplitude = best.p[0];
  fit.t0_s = best.p[1];
  fit.t0_sigma_s = std::sqrt(std::max(0.0, best.covariance(1, 1)));
  fit.tau_s = std::exp(best.p[2]);
  fit.tau_sigma_s = fit.tau_s * std::sqrt(std::max(0.0, best.covariance(2, 2)));
  fit.rms = best.rms;
  return fit;
}

TimeConstantFit fit_refill(const BinnedSeries& s, double t_r) {
  TimeConstantFit fit;
  const int m = static_cast<int>(s.y.size());
  fit.bins = m;
  fit.t0_s = t_r;
  if (m < 5) {
    fit.note = "too few samples after the removal (" + std::to_string(m) + ", 5 needed)";
    return fit;
  }
  // Start: the refilled level from the last quarter, τ from the first 1/e crossing.
  const int q = std::max(1, m / 4);
  double c0 = 0;
  for (int k = m - q; k < m; ++k) c0 += s.y[k] / q;
  const double a0 = s.y[0] - c0;
  double tau0 = (s.first[m - 1] / s.fps - t_r) / 3;
  for (int k = 1; k < m; ++k)
    if ((s.y[k] - c0) * (a0 > 0 ? 1 : -1) < std::abs(a0) / std::exp(1.0)) {
      tau0 = std::max(1e-3, (s.first[k] + 0.5 * s.count[k]) / s.fps - t_r);
      break;
    }
  auto residuals = [&](const Eigen::VectorXd& p, Eigen::VectorXd& r) {
    const double c = p[0], a = p[1], tau = std::exp(p[2]);
    const auto f = [&](double t) { return c + a * std::exp(-(t - t_r) / tau); };
    for (int k = 0; k < m; ++k) r[k] = bin_mean(s, k, f) - s.y[k];
  };
  const double t_first = s.first[0] / s.fps;
  const LeastSquares ls = least_squares(residuals, Eigen::Vector3d(c0, a0 * std::exp((t_first - t_r) / tau0), std::log(tau0)), m);
  if (!ls.ok) {
    fit.note = "the refill fit did not converge";
    return fit;
  }
  fit.fitted = true;
  fit.offset = ls.p[0];
  fit.amplitude = ls.p[1];
  fit.tau_s = std::exp(ls.p[2]);
  fit.tau_sigma_s = fit.tau_s * std::sqrt(std::max(0.0, ls.covariance(2, 2)));
  fit.rms = ls.rms;
  return fit;
}

// ---------------------------------------------------------------------------------------------
// Analysis

namespace {

/// Where the series reads each texel: its cell in the worn view and in the not-worn view (the
/// same cell when the not-worn capture has no geometry of its own), and the not-worn green there
/// (for the worn view times the texels' mean transmittance ratio T_worn / T_baseline). Texels
/// with the same two cells share a site.
struct Sites {
  std::vector<int> worn_cell, base_cell;
  std::vector<double> g0_worn, g0_base;
  std::vector<int> of_texel;  ///< per texel, -1 where the series does not see it
  std::size_t size() const { return worn_cell.size(); }
  int cell(std::size_t site, bool worn) const { return worn ? worn_cell[site] : base_cell[site]; }
  double g0(std::size_t site, bool worn) const { return worn ? g0_worn[site] : g0_base[site]; }
};

/// The cell (of `s`) holding the texel's pixel in `inv` moved by `shift`, or -1.
int cell_of(const TimeSeriesRecorder& s, const InverseMap& inv, const Vec2& shift, std::size_t k) {
  if (!inv.valid[k]) return -1;
  const double x = inv.map_x[k] + shift.x() - s.roi().x, y = inv.map_y[k] + shift.y() - s.roi().y;
  if (!(x >= 0 && y >= 0 && x < s.roi().width && y < s.roi().height)) return -1;
  return static_cast<int>(y) / s.cell_px() * s.cells().width + static_cast<int>(x) / s.cell_px();
}

Sites texel_sites(const TimeInputs& in, const TimeSeriesRecorder& s, const std::vector<double>& g0) {
  const ChartGrid& grid = in.field->grid;
  Sites out;
  out.of_texel.assign(grid.size(), -1);
  std::unordered_map<long long, int> site_of;
  std::vector<double> ratio_sum;
  std::vector<int> texels;
  for (std::size_t k = 0; k < grid.size(); ++k) {
    if (!std::isfinite(in.field->value[k])) continue;
    const int cw = cell_of(s, *in.inverse, in.residual_shift_px, k);
    const int cb = in.baseline_inverse ? cell_of(s, *in.baseline_inverse, in.baseline_residual_shift_px, k) : cw;
    if (cw < 0 || cb < 0 || !(g0[cb] > 0)) continue;
    const double ratio = in.log_transmittance_ratio ? std::exp(static_cast<double>((*in.log_transmittance_ratio)[k])) : 1.0;
    if (!std::isfinite(ratio)) continue;
    const auto [it, added] = site_of.try_emplace(static_cast<long long>(cw) * static_cast<long long>(s.cell_count()) + cb,
                                                 static_cast<int>(out.size()));
    if (added) {
      out.worn_cell.push_back(cw), out.base_cell.push_back(cb), out.g0_base.push_back(g0[cb]);
      ratio_sum.push_back(0), texels.push_back(0);
    }
    ratio_sum[it->second] += ratio, ++texels[it->second];
    out.of_texel[k] = it->second;
  }
  for (std::size_t i = 0; i < out.size(); ++i) out.g0_worn.push_back(out.g0_base[i] * ratio_sum[i] / texels[i]);
  return out;
}

/// Sites of a set of texels, each weighted by its texels; the not-worn green of the set in either view.
struct Region {
  std::vector<std::pair<int, float>> sites;
  double g0_worn = 0, g0_base = 0;
  long long texels = 0;
};

Region make_region(std::vector<int> texel_sites, const Sites& sites) {
  Region r;
  r.texels = static_cast<long long>(texel_sites.size());
  std::sort(texel_sites.begin(), texel_sites.end());
  for (std::size_t k = 0; k < texel_sites.size();) {
    std::size_t e = k;
    while (e < texel_sites.size() && texel_sites[e] == texel_sites[k]) ++e;
    const int i = texel_sites[k];
    r.sites.emplace_back(i, static_cast<float>(e - k));
    r.g0_worn += static_cast<double>(e - k) * sites.g0_worn[i];
    r.g0_base += static_cast<double>(e - k) * sites.g0_base[i];
    k = e;
  }
  return r;
}

/// The region's signal in bin b (seen through the worn view or not): ln(ΣwG / ΣwG0) − the bin's reference.
double region_signal(const TimeSeriesRecorder& s, int b, const Region& r, const Sites& sites, bool worn, double reference) {
  double g = 0;
  for (const auto& [i, w] : r.sites) g += w * s.mean(b, sites.cell(i, worn));
  const double g0 = worn ? r.g0_worn : r.g0_base;
  return g > 0 && g0 > 0 ? std::log(g / g0) - reference : kNaN;
}

/// Mean green per cell over `window` (frames) of a recorder, each bin weighted by its frames inside.
std::vector<double> window_green(const TimeSeriesRecorder& s, FrameWindow window) {
  std::vector<double> g(s.cell_count(), 0.0);
  double weight = 0;
  for (int b = 0; b < s.bins(); ++b) {
    const int f0 = b * s.bin_frames(), f1 = f0 + s.count(b);
    const int overlap = std::min(f1, window.first + window.count) - std::max(f0, window.first);
    if (overlap <= 0) continue;
    for (std::size_t c = 0; c < g.size(); ++c) g[c] += overlap * static_cast<double>(s.mean(b, static_cast<int>(c)));
    weight += overlap;
  }
  if (weight > 0)
    for (double& v : g) v /= weight;
  return g;
}

/// Time at or above `threshold` of a series sampled at bin centres `t` (linear between
/// them; the first and last bins count half a bin beyond their centre); first time reached.
void time_above(const std::vector<double>& t, const std::vector<double>& v, double half_bin, ThresholdTime& out) {
  out.reached = false;
  out.time_above_s = 0;
  auto reach = [&](double when) {
    if (!out.reached) out.reached = true, out.first_above_s = when;
  };
  const std::size_t n = t.size();
  if (n == 0) return;
  if (std::isfinite(v[0]) && v[0] >= out.threshold) reach(t[0] - half_bin), out.time_above_s += half_bin;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const double a = v[k], b = v[k + 1], dt = t[k + 1] - t[k];
    if (!std::isfinite(a) || !std::isfinite(b)) continue;
    const bool ia = a >= out.threshold, ib = b >= out.threshold;
    if (ia && ib) {
      out.time_above_s += dt;
    } else if (ia != ib) {
      const double f = (out.threshold - a) / (b - a);  // crossing at t[k] + f·dt
      if (ib) reach(t[k] + f * dt), out.time_above_s += (1 - f) * dt;
      else out.time_above_s += f * dt;
    }
  }
  if (std::isfinite(v[n - 1]) && v[n - 1] >= out.threshold) out.time_above_s += half_bin;
}

BinnedSeries binned(const TimeSeriesRecorder& s, const std::vector<double>& y, double fps, int frame_from, int frame_to) {
  BinnedSeries out;
  out.fps = fps;
  for (int b = 0; b < s.bins(); ++b) {
    const int f0 = b * s.bin_frames();
    if (f0 < frame_from || f0 + s.count(b) > frame_to || !std::isfinite(y[b])) continue;
    out.y.push_back(y[b]);
    out.first.push_back(f0);
    out.count.push_back(s.count(b));
  }
  return out;
}

std::vector<double> to_kpa(const PressureCalibration& cal, const std::vector<double>& y) {
  std::vector<double> p(y.size(), kNaN);
  for (std::size_t k = 0; k < y.size(); ++k) {
    if (!std::isfinite(y[k])) continue;
    const PressureEstimate e = cal.invert(y[k]);
    p[k] = e.status == PressureStatus::below_detection ? 0.0 : e.pressure_kpa;
  }
  return p;
}

/// Onset and refill of one place (fits on its lowest level's signal).
void fit_times(const TimeInputs& in, const TimeSeriesOptions& o, const TimeSeriesRecorder& s, const TimeAnalysis& a,
               HotspotTimeline& h) {
  const int worn_end = in.release_frame >= 0 ? in.release_frame : s.frames();
  const int from = in.press_frame - static_cast<int>(std::lround(0.5 * in.fps));
  const int to = std::min(worn_end, in.press_frame + static_cast<int>(std::lround(o.onset_window_s * in.fps)));
  h.onset = fit_onset(binned(s, h.signal, in.fps, from, to), in.press_frame / in.fps);
  if (in.release_frame < 0) {
    h.refill.note = "the capture ends with the part worn: no refill to measure";
    return;
  }
  h.refill = fit_refill(binned(s, h.signal, in.fps, in.release_frame, s.frames()), in.release_frame / in.fps);
  const double after_s = (s.frames() - in.release_frame) / in.fps, bin_s = a.bin_frames / in.fps;
  if (!h.refill.fitted) {
    h.refill.note += " (the capture goes on " + fmt(after_s) + " s after the part's removal)";
  } else if (after_s < o.min_refill_taus * h.refill.tau_s) {
    h.refill.fitted = false;
    h.refill.note = "the capture goes on " + fmt(after_s) + " s after the part's removal; " + fmt(o.min_refill_taus, 0) +
                    " refill time constants (" + fmt(o.min_refill_taus * h.refill.tau_s) +
                    " s) are needed to measure it: film longer after removing the part";
  } else if (h.refill.tau_s < 2 * bin_s) {
    h.refill.note = "τ is shorter than two time bins (" + fmt(bin_s, 3) +
                    " s each): uncertain; raise timeseries.max_mb or film a shorter capture for a finer time step";
  }
}

}  // namespace

TimeAnalysis analyse_time(const TimeInputs& in, const TimeSeriesOptions& o) {
  TimeAnalysis a;
  if (!in.series || !in.inverse || !in.field || !in.labels || !in.hotspots) return a;
  if (!(in.fps > 0)) {
    a.warnings.push_back("timeline: the capture's frame rate is unknown (a folder of images?): no time series");
    return a;
  }
  const TimeSeriesRecorder& s = *in.series;
  const TimeSeriesRecorder& base = in.baseline ? *in.baseline : s;
  const InverseMap& inv = *in.inverse;
  const ChartGrid& grid = in.field->grid;
  if (inv.width != grid.width || inv.height != grid.height) throw std::invalid_argument("analyse_time: inverse map and field differ");
  if (in.baseline_inverse && (in.baseline_inverse->width != grid.width || in.baseline_inverse->height != grid.height))
    throw std::invalid_argument("analyse_time: the baseline's inverse map and the field differ");
  if (in.log_transmittance_ratio && in.log_transmittance_ratio->size() != grid.size())
    throw std::invalid_argument("analyse_time: log_transmittance_ratio is not one value per texel");
  a.present = true;
  a.fps = in.fps;
  a.frames = s.frames();
  a.bin_frames = s.bin_frames();
  a.bins = s.bins();
  a.cell_px = s.cell_px();
  a.press_frame = in.press_frame;
  a.release_frame = in.release_frame;
  a.memory_bytes = s.bytes() + (in.baseline ? in.baseline->bytes() : 0);
  for (int b = 0; b < s.bins(); ++b) a.time_s.push_back((b * s.bin_frames() + 0.5 * (s.count(b) - 1)) / in.fps);

  // Baseline green per cell; where the series reads each chart texel (its cells in both views).
  const std::vector<double> g0 = window_green(base, in.baseline_window);
  const Sites sites = texel_sites(in, s, g0);
  // Per bin: which view its frames show (the not-worn one before the press and after the
  // removal, when that capture has a geometry of its own and shares the series' video).
  std::vector<char> worn_view(s.bins(), 1);
  if (in.baseline_inverse && !in.baseline)
    for (int b = 0; b < s.bins(); ++b) {
      const int f = b * s.bin_frames() + s.count(b) / 2;
      worn_view[b] = f >= in.press_frame && (in.release_frame < 0 || f < in.release_frame);
    }
  // Per bin: the median log ratio over the seen sites (what changes all cells alike).
  std::vector<double> reference(s.bins(), 0.0);
  std::vector<double> r;
  for (int b = 0; b < s.bins(); ++b) {
    r.clear();
    for (std::size_t i = 0; i < sites.size(); ++i)
      if (const float m = s.mean(b, sites.cell(i, worn_view[b])); m > 0) r.push_back(std::log(m / sites.g0(i, worn_view[b])));
    if (r.empty()) continue;
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    reference[b] = r[r.size() / 2];
  }
  auto series_of = [&](const Region& region) {
    std::vector<double> y;
    for (int b = 0; b < s.bins(); ++b) y.push_back(region_signal(s, b, region, sites, worn_view[b], reference[b]));
    return y;
  };
  const double half_bin = 0.5 * s.bin_frames() / in.fps;
  for (const Hotspot& spot : *in.hotspots) {
    HotspotTimeline h;
    h.hotspot = spot.id;
    std::vector<std::vector<int>> level_sites(in.thresholds.size() + 1);
    for (std::size_t k = 0; k < grid.size(); ++k) {
      if ((*in.labels)[k] != spot.id || sites.of_texel[k] < 0) continue;
      level_sites[0].push_back(sites.of_texel[k]);
      for (std::size_t i = 0; i < in.thresholds.size(); ++i)
        if (in.field->value[k] >= in.thresholds[i]) level_sites[i + 1].push_back(sites.of_texel[k]);
    }
    h.signal = series_of(make_region(level_sites[0], sites));
    if (in.calibration) h.kpa = to_kpa(*in.calibration, h.signal);
    for (std::size_t i = 0; i < in.thresholds.size(); ++i) {
      ThresholdTime t;
      t.threshold = in.thresholds[i];
      t.signal = in.calibration ? in.calibration->signal(t.threshold) : t.threshold;
      const Region level = make_region(level_sites[i + 1], sites);
      t.texels = level.texels;
      std::vector<double> y;
      if (level.texels > 0) y = series_of(level);
      h.level_signal.push_back(y);
      if (level.texels > 0) time_above(a.time_s, in.calibration ? to_kpa(*in.calibration, y) : y, half_bin, t);
      h.thresholds.push_back(t);
    }
    fit_times(in, o, s, a, h);
    if (!h.refill.note.empty() && in.release_frame >= 0)
      a.warnings.push_back("timeline, place " + std::to_string(spot.id) + ": refill " + (h.refill.fitted ? "" : "not measured: ") +
                           h.refill.note);
    a.hotspots.push_back(std::move(h));
  }

  // Per texel of the coarse chart grid.
  const Vec2 uv_lo = grid.uv(0, 0), uv_hi = grid.uv(grid.width - 1, grid.height - 1);
  a.texel_grid = ChartGrid::covering(uv_lo, uv_hi, std::max(o.texel_mm, grid.texel_mm));
  const ChartGrid& cg = a.texel_grid;
  std::vector<std::vector<int>> coarse(cg.size());
  for (int j = 0; j < grid.height; ++j)
    for (int i = 0; i < grid.width; ++i) {
      const std::size_t k = grid.index(i, j);
      if (sites.of_texel[k] < 0) continue;
      const Vec2 q = (grid.uv(i, j) - cg.uv_origin) / cg.texel_mm;
      const int ci = static_cast<int>(std::lround(q.x())), cj = static_cast<int>(std::lround(q.y()));
      if (ci >= 0 && cj >= 0 && ci < cg.width && cj < cg.height) coarse[cg.index(ci, cj)].push_back(sites.of_texel[k]);
    }
  a.texel_signal.assign(static_cast<std::size_t>(s.bins()) * cg.size(), std::numeric_limits<float>::quiet_NaN());
  for (std::size_t t = 0; t < cg.size(); ++t) {
    if (coarse[t].empty()) continue;
    const std::vector<double> y = series_of(make_region(std::move(coarse[t]), sites));
    for (int b = 0; b < s.bins(); ++b) a.texel_signal[static_cast<std::size_t>(b) * cg.size() + t] = static_cast<float>(y[b]);
  }
  if (in.calibration) {
    const std::size_t n = a.texel_signal.size();
    a.texel_kpa.assign(n, 0.f);
    std::vector<float> sigma(n);
    std::vector<std::uint8_t> status(n);
    in.calibration->invert(a.texel_signal, {}, a.texel_kpa, sigma, status);
    for (std::size_t k = 0; k < n; ++k)
      if (status[k] == static_cast<std::uint8_t>(PressureStatus::below_detection)) a.texel_kpa[k] = 0.f;
  }
  return a;
}

}  // namespace clearfit
