// The blanching → pressure model: forward, closed-form inverse with
// uncertainty, and the robust fit (LM inside IRLS). File I/O is in
// pressure_model_io.cpp.
#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/format.hpp>

#include <Eigen/Dense>
#include <unsupported/Eigen/NonLinearOptimization>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <numbers>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace clearfit {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kHuberK = 1.345, kTukeyC = 4.685, kMadToSigma = 1.4826;

double sigmoid(double z) {
  if (z >= 0) return 1.0 / (1.0 + std::exp(-z));
  const double e = std::exp(z);
  return e / (1.0 + e);
}

// Closed-form inverse of the logistic model with its derivatives. Returns
// false when y is outside the model's range (y ≥ y_max or y below −y_max·s0/d).
struct LogisticInverse {
  double p = kNaN, dp_dy = kNaN;
  Eigen::Vector3d dp_dtheta = Eigen::Vector3d::Constant(kNaN);
};
bool invert_logistic(const LogisticParams& m, double y, LogisticInverse* out) {
  const double z0 = -m.p50_kpa / m.width_kpa;
  const double s0 = sigmoid(z0), d = sigmoid(-z0);  // d = 1 − s0, without cancellation
  const double u = y / m.y_max;
  const double one_minus_s = d * (1.0 - u);
  const double s = s0 + d * u;
  if (!(s > 0) || !(one_minus_s > 0)) return false;
  const double z = std::log(s) - std::log(one_minus_s);
  const double z_s = 1.0 / (s * one_minus_s);
  out->p = m.p50_kpa + m.width_kpa * z;
  out->dp_dy = m.width_kpa * z_s * d / m.y_max;
  const double k = z_s * (1.0 - u) * s0 * d;
  out->dp_dtheta = {m.width_kpa * z_s * (-d * u / m.y_max), 1.0 - k, z - k * z0};
  return true;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

std::string utc_now_iso8601() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}
}  // namespace

const char* to_string(PressureModelKind kind) {
  return kind == PressureModelKind::logistic ? "logistic" : "linear";
}
const char* to_string(PressureStatus status) {
  switch (status) {
    case PressureStatus::ok: return "ok";
    case PressureStatus::below_detection: return "below detection";
    case PressureStatus::saturated: return "saturated";
    case PressureStatus::invalid: return "invalid";
  }
  return "?";
}
const char* to_string(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::none: return "none";
    case RobustLoss::huber: return "huber";
    case RobustLoss::tukey: return "tukey";
  }
  return "?";
}

double logistic_signal(const LogisticParams& m, double p_kpa) {
  const double z = (p_kpa - m.p50_kpa) / m.width_kpa, z0 = -m.p50_kpa / m.width_kpa;
  return m.y_max * (sigmoid(z) - sigmoid(z0)) / sigmoid(-z0);
}

Eigen::Vector3d logistic_gradient(const LogisticParams& m, double p_kpa) {
  const double w = m.width_kpa;
  const double z = (p_kpa - m.p50_kpa) / w, z0 = -m.p50_kpa / w;
  const double sz = sigmoid(z), s0 = sigmoid(z0), d = sigmoid(-z0);
  const double psi = (sz - s0) / d;
  const double dpsi_dz = sz * sigmoid(-z) / d;
  const double dpsi_ds0 = (sz - 1.0) / (d * d);
  const double ds0_dz0 = s0 * d;
  return {psi, m.y_max * (dpsi_dz + dpsi_ds0 * ds0_dz0) * (-1.0 / w),
          m.y_max * (dpsi_dz * (-z / w) + dpsi_ds0 * ds0_dz0 * (-z0 / w))};
}

// ---------------------------------------------------------------- calibration

double PressureCalibration::signal(double p_kpa) const {
  return model == PressureModelKind::logistic ? logistic_signal(logistic, p_kpa) : intercept + slope_per_kpa * p_kpa;
}

double PressureCalibration::saturation_signal() const {
  if (model == PressureModelKind::linear) return signal(p_max_kpa);
  return std::min(0.95 * logistic.y_max, signal(p_max_kpa));
}

Eigen::Vector3d PressureCalibration::standard_errors() const {
  return covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

PressureEstimate PressureCalibration::invert(double y, double sigma_y) const {
  PressureEstimate e{kNaN, kNaN, kNaN, PressureStatus::invalid};
  if (!std::isfinite(y)) return e;
  if (!std::isfinite(sigma_y)) sigma_y = noise_sigma;
  // Pressure (no flags) of a signal inside the model's range, with its gradients.
  auto solve = [&](double v, LogisticInverse* inv) {
    if (model == PressureModelKind::logistic) return invert_logistic(logistic, v, inv);
    inv->p = (v - intercept) / slope_per_kpa;
    inv->dp_dy = 1.0 / slope_per_kpa;
    inv->dp_dtheta = {-1.0 / slope_per_kpa, -(v - intercept) / (slope_per_kpa * slope_per_kpa), 0.0};
    return true;
  };
  LogisticInverse inv;
  const double y_det = detection_signal(), y_sat = saturation_signal();
  if (y > y_sat) {
    e.status = PressureStatus::saturated;
    e.bound_kpa = solve(y_sat, &inv) ? inv.p : p_max_kpa;
    e.pressure_kpa = e.bound_kpa;
    return e;
  }
  const bool ok = y >= y_det && solve(y, &inv) && inv.p >= 0;
  if (!ok) {
    e.status = PressureStatus::below_detection;
    LogisticInverse at_limit;
    e.bound_kpa = solve(std::max(y_det, y), &at_limit) ? std::max(0.0, at_limit.p) : 0.0;
    return e;
  }
  e.status = PressureStatus::ok;
  e.pressure_kpa = inv.p;
  const double var = inv.dp_dy * inv.dp_dy * sigma_y * sigma_y + inv.dp_dtheta.dot(covariance * inv.dp_dtheta);
  e.sigma_kpa = std::sqrt(std::max(0.0, var));
  return e;
}

void PressureCalibration::invert(std::span<const float> signal, std::span<const float> sigma_y,
                                 std::span<float> pressure_kpa, std::span<float> sigma_kpa,
                                 std::span<std::uint8_t> status, double detection_limit) const {
  const std::size_t n = signal.size();
  if (pressure_kpa.size() != n || sigma_kpa.size() != n || status.size() != n || (!sigma_y.empty() && sigma_y.size() != n))
    throw std::invalid_argument("PressureCalibration::invert: output spans (and sigma_y when given) need signal.size() elements");
  // Everything that does not depend on the element is hoisted; the loop is the
  // closed form of invert_logistic / the linear inverse.
  const double y_det = std::isnan(detection_limit) ? detection_signal() : detection_limit, y_sat = saturation_signal();
  const float sat_p = static_cast<float>(invert(std::numeric_limits<double>::max()).pressure_kpa);
  const bool logistic_model = model == PressureModelKind::logistic;
  const double w = logistic.width_kpa, inv_ymax = 1.0 / logistic.y_max, p50 = logistic.p50_kpa;
  const double z0 = logistic_model ? -p50 / w : 0, s0 = sigmoid(z0), d = sigmoid(-z0), s0d = s0 * d;
  const double inv_b = 1.0 / slope_per_kpa;
  const Eigen::Matrix3d& C = covariance;
  const double c00 = C(0, 0), c11 = C(1, 1), c22 = C(2, 2), c01 = 2 * C(0, 1), c02 = 2 * C(0, 2), c12 = 2 * C(1, 2);
  const double noise = noise_sigma;
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 16384), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const double y = signal[i];
      const double sy = sigma_y.empty() || !std::isfinite(sigma_y[i]) ? noise : sigma_y[i];
      PressureStatus st = PressureStatus::ok;
      float p_out = nanf, s_out = nanf;
      if (!std::isfinite(y)) {
        st = PressureStatus::invalid;
      } else if (y > y_sat) {
        st = PressureStatus::saturated;
        p_out = sat_p;
      } else if (y < y_det) {
        st = PressureStatus::below_detection;
      } else {
        // The closed form of invert_logistic (or the linear inverse), unrolled.
        double p, dp_dy, g0, g1, g2;
        if (logistic_model) {
          const double u = y * inv_ymax, s = s0 + d * u, oms = d - d * u;
          const double z = std::log(s / oms), z_s = 1.0 / (s * oms), k = z_s * (1.0 - u) * s0d;
          p = p50 + w * z;
          dp_dy = w * z_s * d * inv_ymax;
          g0 = -dp_dy * u;
          g1 = 1.0 - k;
          g2 = z - k * z0;
        } else {
          p = (y - intercept) * inv_b;
          dp_dy = inv_b;
          g0 = -inv_b;
          g1 = -p * inv_b;
          g2 = 0;
        }
        if (p >= 0) {
          const double var = dp_dy * dp_dy * sy * sy + c00 * g0 * g0 + c11 * g1 * g1 + c22 * g2 * g2 + c01 * g0 * g1 +
                             c02 * g0 * g2 + c12 * g1 * g2;
          p_out = static_cast<float>(p);
          s_out = static_cast<float>(std::sqrt(std::max(0.0, var)));
        } else {
          st = PressureStatus::below_detection;
        }
      }
      status[i] = static_cast<std::uint8_t>(st);
      pressure_kpa[i] = p_out;
      sigma_kpa[i] = s_out;
    }
  });
}

// ---------------------------------------------------------------- fitting

void PressureFitOptions::validate() const {
  if (person.empty()) throw std::invalid_argument("PressureFitOptions::person must not be empty");
  if (max_iterations < 1) throw std::invalid_argument("PressureFitOptions::max_iterations must be >= 1, got " + std::to_string(max_iterations));
}

namespace {

// The logistic's weighted residuals √w·(y − f(p; θ)) on θ = (ln y_max, p50, ln w), with the analytic Jacobian,
// as Eigen's LevenbergMarquardt expects them (it minimises ½‖f‖²).
struct LogisticResiduals {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  const std::vector<double>*p, *y, *wt;
  int inputs() const { return 3; }
  int values() const { return static_cast<int>(p->size()); }
  static LogisticParams params(const Eigen::VectorXd& x) {
    return {std::exp(std::clamp(x[0], -700.0, 700.0)), x[1], std::exp(std::clamp(x[2], -700.0, 700.0))};
  }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    const LogisticParams m = params(x);
    for (std::size_t i = 0; i < p->size(); ++i) f[Eigen::Index(i)] = std::sqrt((*wt)[i]) * ((*y)[i] - logistic_signal(m, (*p)[i]));
    return 0;
  }
  int df(const Eigen::VectorXd& x, Eigen::MatrixXd& jac) const {
    const LogisticParams m = params(x);
    for (std::size_t i = 0; i < p->size(); ++i) {
      Eigen::Vector3d g = logistic_gradient(m, (*p)[i]);
      g[0] *= m.y_max;      // ∂/∂ ln y_max
      g[2] *= m.width_kpa;  // ∂/∂ ln w
      jac.row(Eigen::Index(i)) = -std::sqrt((*wt)[i]) * g.transpose();
    }
    return 0;
  }
};

// Weighted least squares of the logistic from `m` (Eigen's Levenberg–Marquardt). Returns the iterations used;
// `converged` unless the evaluation budget ran out or the parameters left the finite numbers.
int levenberg_marquardt(const std::vector<double>& p, const std::vector<double>& y, const std::vector<double>& wt,
                        LogisticParams& m, int max_iterations, bool* converged) {
  LogisticResiduals f{&p, &y, &wt};
  Eigen::LevenbergMarquardt<LogisticResiduals> lm(f);
  lm.parameters.maxfev = 20 * max_iterations;
  lm.parameters.xtol = 1e-12;
  lm.parameters.ftol = 1e-14;
  Eigen::VectorXd x(3);
  x << std::log(m.y_max), m.p50_kpa, std::log(m.width_kpa);
  const Eigen::LevenbergMarquardtSpace::Status status = lm.minimize(x);
  *converged = x.allFinite() && status != Eigen::LevenbergMarquardtSpace::TooManyFunctionEvaluation &&
               status != Eigen::LevenbergMarquardtSpace::ImproperInputParameters;
  if (x.allFinite()) m = LogisticResiduals::params(x);
  return static_cast<int>(lm.iter);
}

// ψ(u) and ψ'(u) of the loss, u = residual / scale.
double psi(double u, RobustLoss loss) {
  if (loss == RobustLoss::huber) return std::clamp(u, -kHuberK, kHuberK);
  if (loss == RobustLoss::tukey) {
    const double t = u / kTukeyC;
    return std::abs(t) < 1 ? u * (1 - t * t) * (1 - t * t) : 0.0;
  }
  return u;
}
double dpsi(double u, RobustLoss loss) {
  if (loss == RobustLoss::huber) return std::abs(u) <= kHuberK ? 1.0 : 0.0;
  if (loss == RobustLoss::tukey) {
    const double t2 = (u / kTukeyC) * (u / kTukeyC);
    return t2 < 1 ? (1 - t2) * (1 - 5 * t2) : 0.0;
  }
  return 1.0;
}
// E[ψ(u)²] for u ~ N(0, 1) (Simpson's rule), so that robust scales are
// consistent for Gaussian noise.
double gaussian_psi2(RobustLoss loss) {
  const int n = 4000;
  const double a = -12, h = 24.0 / n;
  double sum = 0;
  for (int i = 0; i <= n; ++i) {
    const double u = a + i * h, f = psi(u, loss) * psi(u, loss) * std::exp(-0.5 * u * u);
    sum += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
  }
  return sum * h / 3 / std::sqrt(2 * std::numbers::pi);
}
// σ̂ = s·sqrt(Σψ(r/s)² / ((n − 3) E[ψ²])): consistent for Gaussian noise,
// bounded influence of outliers; with loss none the plain residual RMS.
double psi_scale(const std::vector<double>& r, double s, RobustLoss loss) {
  double sum = 0;
  for (double v : r) sum += s > 0 ? std::pow(psi(v / s, loss), 2) : 0.0;
  const double dof = std::max(1.0, static_cast<double>(r.size()) - 3.0);
  if (loss == RobustLoss::none || !(s > 0)) {
    double ss = 0;
    for (double v : r) ss += v * v;
    return std::sqrt(ss / dof);
  }
  static const double kappa_huber = gaussian_psi2(RobustLoss::huber), kappa_tukey = gaussian_psi2(RobustLoss::tukey);
  return s * std::sqrt(sum / (dof * (loss == RobustLoss::huber ? kappa_huber : kappa_tukey)));
}
// Huber's proposal-2 scale: the fixed point of psi_scale, from the MAD.
double huber_scale(const std::vector<double>& r) {
  std::vector<double> a(r.size());
  for (std::size_t i = 0; i < r.size(); ++i) a[i] = std::abs(r[i]);
  double s = kMadToSigma * median(a);
  if (!(s > 0)) return s;
  for (int it = 0; it < 50; ++it) {
    const double next = psi_scale(r, s, RobustLoss::huber);
    if (std::abs(next - s) <= 1e-12 * s) return next;
    s = next;
  }
  return s;
}
std::vector<double> robust_weights(const std::vector<double>& r, double scale, RobustLoss loss) {
  std::vector<double> w(r.size(), 1.0);
  if (loss == RobustLoss::none || !(scale > 0)) return w;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double u = r[i] / scale;
    w[i] = u == 0 ? 1.0 : psi(u, loss) / u;
  }
  return w;
}

}  // namespace

namespace {

/// The presses as numbers, checked, with their distinct levels.
struct FitData {
  std::string src;
  int n = 0;
  std::vector<double> p, y;
  double p_min = 0, p_max = 0, ss_tot = 0;
  std::vector<std::vector<int>> levels;  ///< indices of the presses at each distinct pressure, ascending
};

FitData fit_data(const std::vector<CalibrationPress>& presses, const std::string& src) {
  FitData d;
  d.src = src;
  const int n = d.n = static_cast<int>(presses.size());
  d.p.resize(n), d.y.resize(n);
  for (int i = 0; i < n; ++i) {
    const CalibrationPress& c = presses[i];
    const std::string where = c.line ? "line " + std::to_string(c.line) : "trial '" + c.trial + "'";
    if (!std::isfinite(c.mean_pressure_kpa) || c.mean_pressure_kpa < 0 || !std::isfinite(c.signal))
      throw InputError(src, where, "needs a finite mean pressure >= 0 kPa and a finite signal");
    d.p[i] = c.mean_pressure_kpa;
    d.y[i] = c.signal;
  }
  if (n < 4)
    throw InputError(src, "presses", "found " + std::to_string(n) + " presses; the logistic model has 3 parameters and needs at least 4",
                     "the protocol: 8-10 pressure levels over 0-30 kPa, 3 repetitions each");
  const auto [pmin_it, pmax_it] = std::minmax_element(d.p.begin(), d.p.end());
  d.p_min = *pmin_it, d.p_max = *pmax_it;
  // Distinct pressure levels: sorted pressures split where the gap exceeds max(0.5 kPa, 5 %).
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return d.p[a] < d.p[b]; });
  d.levels = {{order[0]}};
  for (int k = 1; k < n; ++k) {
    const double prev = d.p[d.levels.back().back()], cur = d.p[order[k]];
    if (cur - prev > std::max(0.5, 0.05 * cur)) d.levels.emplace_back();
    d.levels.back().push_back(order[k]);
  }
  if (d.levels.size() < 3)
    throw InputError(src, "presses", "the presses cover only " + std::to_string(d.levels.size()) +
                     " distinct pressure level(s); a calibration needs at least 3 (better 8-10)",
                     "press at 8-10 levels over 0-30 kPa mean pressure");
  const double ybar = std::accumulate(d.y.begin(), d.y.end(), 0.0) / n;
  for (double v : d.y) d.ss_tot += (v - ybar) * (v - ybar);
  return d;
}

/// The study's linear model, ordinary least squares; refuses a signal that does not rise.
LinearFit linear_fit(const FitData& d) {
  const int n = d.n;
  Eigen::MatrixXd X(n, 2);
  Eigen::VectorXd Y(n);
  for (int i = 0; i < n; ++i) X(i, 0) = 1.0, X(i, 1) = d.p[i], Y[i] = d.y[i];
  const Eigen::Matrix2d XtX = X.transpose() * X;
  const Eigen::Vector2d ab = XtX.ldlt().solve(X.transpose() * Y);
  const double ssr = (Y - X * ab).squaredNorm();
  const Eigen::Matrix2d cov = ssr / std::max(1, n - 2) * XtX.inverse();
  const LinearFit f{ab[0], ab[1], std::sqrt(cov(0, 0)), std::sqrt(cov(1, 1)), d.ss_tot > 0 ? 1 - ssr / d.ss_tot : kNaN};
  // A signal that is the same at every press (to rounding) has no slope to speak of, whatever its sign.
  double y_abs = 0;
  for (double v : d.y) y_abs = std::max(y_abs, std::abs(v));
  if (std::sqrt(d.ss_tot / n) <= 64 * std::numeric_limits<double>::epsilon() * y_abs)
    throw InputError(d.src, "signal", "is the same (" + significant_digits(d.y[0], 6) + ") at every press: nothing blanched",
                     "check that the signal column holds each press's measured change, and that the presses reached the skin");
  // Within two standard errors of flat: the signal does not rise beyond its noise (nothing to calibrate).
  if (f.slope_per_kpa > 0 && f.slope_per_kpa < 2 * f.se_slope)
    throw InputError(d.src, "signal",
                     "does not rise with pressure beyond its noise (linear slope " + significant_digits(f.slope_per_kpa, 3) +
                         " +- " + significant_digits(f.se_slope, 3) + " per kPa): nothing measurable blanched",
                     "check the signal column and that the presses reached the skin; press harder or longer");
  if (!(f.slope_per_kpa > 0))
    throw InputError(d.src, "signal",
                     "does not rise with pressure (linear slope " + significant_digits(f.slope_per_kpa, 3) +
                         " per kPa); blanching makes the green signal grow with pressure",
                     "check the signal's sign (ln of contact over baseline) and the pressure column");
  return f;
}

/// Initial guess: coarse grid over (p50, w), y_max solved linearly, least absolute deviations.
LogisticParams logistic_start(const FitData& d) {
  const int n = d.n;
  const std::vector<double>& p = d.p;
  const std::vector<double>& y = d.y;
  const double span = std::max(d.p_max, 1e-6);
  LogisticParams m{};
  double best = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 40; ++a)
    for (int b = 0; b < 25; ++b) {
      const LogisticParams q0{1.0, span * (0.02 + 1.18 * a / 39.0), span * 0.01 * std::pow(50.0, b / 24.0)};
      double num = 0, den = 0;
      for (int i = 0; i < n; ++i) {
        const double psi = logistic_signal(q0, p[i]);
        num += psi * y[i];
        den += psi * psi;
      }
      if (!(den > 0) || !(num > 0)) continue;
      const LogisticParams q{num / den, q0.p50_kpa, q0.width_kpa};
      double c = 0;
      for (int i = 0; i < n; ++i) c += std::abs(y[i] - logistic_signal(q, p[i]));
      if (c < best) best = c, m = q;
    }
  if (!(m.y_max > 0))
    throw InputError(d.src, "signal", "does not follow a rising curve through 0 at 0 kPa",
                     "check the signal's sign and that the presses span the blanching range");

  return m;
}

/// The robust fit's state: parameters, weights, residuals and the loss's scale.
struct RobustFit {
  LogisticParams m;
  std::vector<double> wt, r;
  double scale = 0;
};

/// IRLS: Huber (scale re-estimated each round), then Tukey with the scale fixed. Adds to res.iterations and
/// clears res.converged when a stage does not settle.
RobustFit robust_logistic(const FitData& d, const PressureFitOptions& options, LogisticParams start, PressureFitResult& res) {
  const int n = d.n;
  const std::vector<double>& p = d.p;
  const std::vector<double>& y = d.y;
  LogisticParams m = start;
  std::vector<double> wt(n, 1.0), r(n);
  auto residuals = [&] {
    for (int i = 0; i < n; ++i) r[i] = y[i] - logistic_signal(m, p[i]);
  };
  res.converged = true;
  double final_scale = 0;
  auto run_rounds = [&](RobustLoss loss, double fixed_scale) {
    for (int round = 0; round < 50; ++round) {
      const LogisticParams before = m;
      bool conv = false;
      res.iterations += levenberg_marquardt(p, y, wt, m, options.max_iterations, &conv);
      residuals();
      if (loss == RobustLoss::none) {
        res.converged = res.converged && conv;
        return;
      }
      final_scale = fixed_scale > 0 ? fixed_scale : huber_scale(r);
      wt = robust_weights(r, final_scale, loss);
      const bool settled = std::abs(m.y_max - before.y_max) <= 1e-9 * m.y_max &&
                           std::abs(m.p50_kpa - before.p50_kpa) <= 1e-9 * std::max(1.0, std::abs(m.p50_kpa)) &&
                           std::abs(m.width_kpa - before.width_kpa) <= 1e-9 * m.width_kpa;
      if (settled && round > 0) return;
    }
    res.converged = false;
  };
  if (options.loss == RobustLoss::none) {
    run_rounds(RobustLoss::none, 0);
  } else {
    residuals();
    wt = robust_weights(r, huber_scale(r), RobustLoss::huber);
    run_rounds(RobustLoss::huber, 0);
    if (options.loss == RobustLoss::tukey) {
      const double scale = huber_scale(r);  // the Tukey stage keeps the Huber fit's scale
      wt = robust_weights(r, scale, RobustLoss::tukey);
      run_rounds(RobustLoss::tukey, scale);
    }
  }
  residuals();
  wt = robust_weights(r, final_scale, options.loss);  // consistent with the final parameters

  return {m, wt, r, final_scale};
}

/// Covariance (Huber 1981, §7.6): s² · [Σψ²/(n − 3)] / mean ψ' · (Σ ψ' g gᵀ)⁻¹ with u = r/s; for plain least
/// squares σ̂² (JᵀJ)⁻¹. Points the loss rejects drop out.
Eigen::Matrix3d robust_covariance(const FitData& d, const RobustFit& f, RobustLoss loss) {
  const double s = loss == RobustLoss::none ? 1.0 : f.scale;
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  double psi2 = 0, dpsi_sum = 0;
  for (int i = 0; i < d.n; ++i) {
    const double u = f.r[i] / s, d1 = std::max(0.0, dpsi(u, loss));
    const Eigen::Vector3d g = logistic_gradient(f.m, d.p[i]);
    A += d1 * g * g.transpose();
    psi2 += psi(u, loss) * psi(u, loss);
    dpsi_sum += d1;
  }
  const double factor = s * s * psi2 / std::max(1.0, d.n - 3.0) / std::max(dpsi_sum / d.n, 1e-12);
  const Eigen::Matrix3d cov_raw = factor * A.ldlt().solve(Eigen::Matrix3d::Identity());
  return 0.5 * (cov_raw + cov_raw.transpose());
}

/// The calibration of the model the options choose (the linear one refitted for its own noise and covariance).
void fill_calibration(const FitData& d, const PressureFitOptions& options, const RobustFit& f, const Eigen::Matrix3d& cov_logistic,
                      PressureFitResult& res) {
  PressureCalibration& cal = res.calibration;
  cal.model = options.model;
  cal.person = options.person;
  cal.camera_hash = options.camera_hash;
  cal.created = utc_now_iso8601();
  cal.p_min_kpa = d.p_min;
  cal.p_max_kpa = d.p_max;
  cal.presses = d.n;
  cal.r2_linear = res.linear.r2;
  cal.noise_sigma = psi_scale(f.r, options.loss == RobustLoss::none ? 1.0 : f.scale, options.loss);
  if (cal.model == PressureModelKind::logistic) {
    cal.logistic = f.m;
    cal.covariance = cov_logistic;
    cal.r2 = res.r2_logistic;
    return;
  }
  cal.intercept = res.linear.intercept;
  cal.slope_per_kpa = res.linear.slope_per_kpa;
  double ssr = 0;
  Eigen::Matrix2d XtX = Eigen::Matrix2d::Zero();
  for (int i = 0; i < d.n; ++i) {
    const double e = d.y[i] - cal.signal(d.p[i]);
    ssr += e * e;
    XtX += Eigen::Vector2d(1, d.p[i]) * Eigen::RowVector2d(1, d.p[i]);
  }
  cal.noise_sigma = std::sqrt(ssr / std::max(1, d.n - 2));
  const Eigen::Matrix2d c2 = ssr / std::max(1, d.n - 2) * XtX.inverse();
  cal.covariance.topLeftCorner<2, 2>() = 0.5 * (c2 + c2.transpose());
  cal.r2 = res.linear.r2;
}

/// Residuals per trial, and the RMSE in kPa over the presses inside the invertible range: known pressure
/// between the pressures of the detection and saturation signals, and a signal that inverts without a flag.
void press_residuals(const FitData& d, const std::vector<CalibrationPress>& presses, const std::vector<double>& wt,
                     PressureFitResult& res) {
  const int n = d.n;
  const std::vector<double>& p = d.p;
  const std::vector<double>& y = d.y;
  PressureCalibration& cal = res.calibration;
  const PressureEstimate det = cal.invert(cal.detection_signal(), 0.0);
  const double p_lo = det.status == PressureStatus::ok ? det.pressure_kpa : det.bound_kpa;
  const double p_hi = cal.invert(std::numeric_limits<double>::max()).bound_kpa;
  double se_kpa = 0, se_inliers = 0;
  int inliers = 0;
  for (int i = 0; i < n; ++i) {
    PressResidual pr;
    pr.trial = presses[i].trial;
    pr.pressure_kpa = p[i];
    pr.signal = y[i];
    pr.residual_signal = y[i] - cal.signal(p[i]);
    pr.residual_linear = y[i] - (res.linear.intercept + res.linear.slope_per_kpa * p[i]);
    pr.weight = wt[i];
    const PressureEstimate e = cal.invert(y[i]);
    pr.status = e.status;
    pr.predicted_kpa = e.status == PressureStatus::ok ? e.pressure_kpa : kNaN;
    pr.residual_kpa = pr.predicted_kpa - p[i];
    if (e.status == PressureStatus::ok && p[i] >= p_lo && p[i] <= p_hi) {
      se_kpa += pr.residual_kpa * pr.residual_kpa;
      if (wt[i] >= 0.5) se_inliers += pr.residual_kpa * pr.residual_kpa, ++inliers;
      ++res.presses_in_range;
    }
    res.residuals.push_back(pr);
  }
  res.rmse_kpa = res.presses_in_range ? std::sqrt(se_kpa / res.presses_in_range) : kNaN;
  res.rmse_kpa_inliers = inliers ? std::sqrt(se_inliers / inliers) : kNaN;
  cal.rmse_kpa = res.rmse_kpa;

}

/// Warnings: no convergence, too few levels, nothing near p50, no saturation, non-monotone levels, outliers.
void fit_warnings(const FitData& d, const std::vector<CalibrationPress>& presses, const RobustFit& f, PressureFitResult& res) {
  const int n = d.n;
  const std::vector<double>& p = d.p;
  const std::vector<double>& y = d.y;
  const std::vector<double>& wt = f.wt;
  const LogisticParams& m = f.m;
  const double p_min = d.p_min, p_max = d.p_max;
  const auto& levels = d.levels;
  const PressureCalibration& cal = res.calibration;
  auto& warn = res.warnings;
  if (!res.converged) warn.push_back("the logistic fit did not converge; its parameters are the last iterate");
  if (res.levels < 6)
    warn.push_back("too few pressure levels: " + std::to_string(res.levels) +
                   " (the protocol asks for 8-10 levels over 0-30 kPa)");
  if (std::none_of(p.begin(), p.end(), [&](double v) { return std::abs(v - m.p50_kpa) <= m.width_kpa; }))
    warn.push_back("no press within one width (" + significant_digits(m.width_kpa, 3) +
                   " kPa) of p50 = " + significant_digits(m.p50_kpa, 3) +
                   " kPa: the midpoint is not pinned by data; add levels near it");
  if (logistic_signal(m, p_max) < 0.9 * m.y_max)
    warn.push_back("saturation not reached: the highest press (" + significant_digits(p_max, 3) +
                   " kPa) gives " + significant_digits(100 * logistic_signal(m, p_max) / m.y_max, 2) +
                   " % of y_max, so y_max is extrapolated; press up to about " +
                   significant_digits(m.p50_kpa + 3 * m.width_kpa, 3) + " kPa");
  for (std::size_t k = 1; k < levels.size(); ++k) {
    // Level means over the presses the robust fit kept (outliers are reported apart).
    auto mean = [&](const std::vector<int>& idx, int* count) {
      double s = 0;
      *count = 0;
      for (int i : idx)
        if (wt[i] >= 0.5) s += y[i], ++*count;
      return *count ? s / *count : kNaN;
    };
    int na = 0, nb = 0;
    const double drop = mean(levels[k - 1], &na) - mean(levels[k], &nb);
    const double se = na && nb ? cal.noise_sigma * std::sqrt(1.0 / na + 1.0 / nb) : kNaN;
    if (drop > 3 * se && drop > 0) {
      double pa = 0, pb = 0;
      for (int i : levels[k - 1]) pa += p[i] / levels[k - 1].size();
      for (int i : levels[k]) pb += p[i] / levels[k].size();
      warn.push_back("non-monotone data: the mean signal drops from " + significant_digits(pa, 3) +
                     " kPa to " + significant_digits(pb, 3) + " kPa by " +
                     significant_digits(drop / std::max(se, 1e-300), 2) + " standard errors");
    }
  }
  std::string outliers;
  int n_out = 0;
  for (int i = 0; i < n; ++i)
    if (wt[i] < 0.5) outliers += (n_out++ ? ", " : "") + presses[i].trial;
  if (n_out)
    warn.push_back(std::to_string(n_out) + " press(es) down-weighted as outliers by the robust fit: trial " + outliers);
  if (m.p50_kpa < p_min || m.p50_kpa > p_max)
    warn.push_back("p50 = " + significant_digits(m.p50_kpa, 3) + " kPa lies outside the pressed range [" +
                   significant_digits(p_min, 3) + ", " + significant_digits(p_max, 3) + "] kPa");
}

}  // namespace

PressureFitResult fit_pressure_calibration(const std::vector<CalibrationPress>& presses, const PressureFitOptions& options) {
  options.validate();
  const FitData d = fit_data(presses, options.source);
  PressureFitResult res;
  res.levels = static_cast<int>(d.levels.size());
  res.linear = linear_fit(d);
  const RobustFit f = robust_logistic(d, options, logistic_start(d), res);
  const Eigen::Matrix3d cov_logistic = robust_covariance(d, f, options.loss);
  double ssr_logistic = 0;
  for (double v : f.r) ssr_logistic += v * v;
  res.logistic = f.m;
  res.logistic_se = cov_logistic.diagonal().cwiseMax(0.0).cwiseSqrt();
  res.r2_logistic = d.ss_tot > 0 ? 1 - ssr_logistic / d.ss_tot : kNaN;
  fill_calibration(d, options, f, cov_logistic, res);
  press_residuals(d, presses, f.wt, res);
  fit_warnings(d, presses, f, res);
  return res;
}

}  // namespace clearfit
