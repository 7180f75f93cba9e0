// The calibration fitted to the radially resolved signal with the indenter's
// pressure field (pressure_field_fit.hpp).
#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_field_fit.hpp>

#include <Eigen/Dense>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

namespace clearfit {
namespace {

struct Ring {
  double force_n = 0, signal = 0, drive_kpa = 0;  // drive: the ring's mean blurred pressure
  std::vector<double> drive_samples;              // kPa at equal-area sub-radii
  std::size_t press = 0;
};

LogisticParams params_of(const Eigen::VectorXd& x) { return {std::exp(x[0]), x[1], std::exp(x[2])}; }

double ring_model(const LogisticParams& m, const Ring& r) {
  double s = 0;
  for (double d : r.drive_samples) s += logistic_signal(m, d);
  return s / double(r.drive_samples.size());
}

struct Residuals {  // the functor Eigen's NumericalDiff and LevenbergMarquardt expect
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  const std::vector<Ring>* rings;
  explicit Residuals(const std::vector<Ring>& r) : rings(&r) {}
  int inputs() const { return 3; }
  int values() const { return static_cast<int>(rings->size()); }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    const LogisticParams m = params_of(x);
    for (std::size_t k = 0; k < rings->size(); ++k) f[k] = (*rings)[k].signal - ring_model(m, (*rings)[k]);
    return 0;
  }
};

std::vector<Ring> make_rings(const std::vector<CalibrationPress>& presses, const FieldFitOptions& o, const std::string& file) {
  std::map<double, std::unique_ptr<IndenterProfile>> profiles;  // by radius
  std::vector<Ring> rings;
  for (std::size_t i = 0; i < presses.size(); ++i) {
    const CalibrationPress& c = presses[i];
    const std::string where = "line " + std::to_string(c.line);
    if (c.ring_signal.empty())
      throw InputError(file, where, "has no radial profile (ring_edges_mm, ring_signal)",
                       "write the presses with `clearfit presses`, or fit with --pressure-field uniform");
    if (!std::isfinite(c.force_n) || !std::isfinite(c.indenter_diameter_mm))
      throw InputError(file, where, "gives no force_n or indenter_diameter_mm; the indenter's pressure field needs both");
    const double a = c.indenter_diameter_mm / 2;
    auto& profile = profiles[a];
    if (!profile) profile = std::make_unique<IndenterProfile>(o.field, a, o.blur_sigma_mm);
    for (std::size_t k = 0; k < c.ring_signal.size(); ++k) {
      if (!std::isfinite(c.ring_signal[k])) continue;
      Ring r;
      r.force_n = c.force_n, r.signal = c.ring_signal[k], r.press = i;
      const double r0 = c.ring_edges_mm[k], r1 = c.ring_edges_mm[k + 1];
      for (int j = 0; j < o.samples_per_ring; ++j) {
        const double rr = std::sqrt(r0 * r0 + (j + 0.5) / o.samples_per_ring * (r1 * r1 - r0 * r0));
        r.drive_samples.push_back(c.force_n * profile->kpa_per_newton(rr));
      }
      for (double d : r.drive_samples) r.drive_kpa += d / double(r.drive_samples.size());
      rings.push_back(std::move(r));
    }
  }
  return rings;
}

double robust_scale(std::vector<double> v) {
  for (double& x : v) x = std::abs(x);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return 1.4826 * v[v.size() / 2];
}

}  // namespace

void FieldFitOptions::validate() const {
  if (!(blur_sigma_mm >= 0 && blur_sigma_mm < 5)) throw InputError("", "--blur-mm", "expected the skin's blur in mm, from 0 to 5");
  if (samples_per_ring < 1) throw std::invalid_argument("samples_per_ring must be >= 1");
}

bool presses_have_profiles(const std::vector<CalibrationPress>& presses) {
  return !presses.empty() && std::all_of(presses.begin(), presses.end(), [](const auto& c) { return !c.ring_signal.empty(); });
}

PressureFitResult fit_pressure_field(const std::vector<CalibrationPress>& presses, const PressureFitOptions& options,
                                     const FieldFitOptions& field) {
  field.validate();
  const std::vector<Ring> rings = make_rings(presses, field, options.source);
  PressureFitResult r = fit_pressure_calibration(presses, options);  // the uniform fit of the disc means: the start
  Eigen::VectorXd x(3);
  x << std::log(r.logistic.y_max), r.logistic.p50_kpa, std::log(r.logistic.width_kpa);
  Residuals f(rings);
  Eigen::NumericalDiff<Residuals> nd(f);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Residuals>> lm(nd);
  lm.parameters.maxfev = 4000;
  const auto status = lm.minimize(x);
  r.converged = status != Eigen::LevenbergMarquardtSpace::TooManyFunctionEvaluation && x.allFinite();
  r.iterations = static_cast<int>(lm.iter);
  if (!x.allFinite()) throw InputError(options.source, "", "the pressure-field fit did not converge", "check the presses' profiles");
  const LogisticParams m = params_of(x);
  // Covariance in (y_max, p50, w): s²(JᵀJ)⁻¹ in x, through dθ/dx = diag(y_max, 1, w).
  Eigen::MatrixXd jac(rings.size(), 3);
  nd.df(x, jac);
  Eigen::VectorXd res(rings.size());
  f(x, res);
  const double dof = std::max(1.0, double(rings.size()) - 3), s2 = res.squaredNorm() / dof;
  const Eigen::Matrix3d d = Eigen::Vector3d(m.y_max, 1, m.width_kpa).asDiagonal();
  const Eigen::Matrix3d cov = d * (s2 * (jac.transpose() * jac).inverse()) * d;

  PressureCalibration& cal = r.calibration;
  cal.model = PressureModelKind::logistic;
  cal.logistic = m;
  cal.covariance = cov;
  cal.noise_sigma = robust_scale(std::vector<double>(res.data(), res.data() + res.size()));
  cal.p_min_kpa = 1e300, cal.p_max_kpa = 0;
  for (const Ring& g : rings) cal.p_min_kpa = std::min(cal.p_min_kpa, g.drive_kpa), cal.p_max_kpa = std::max(cal.p_max_kpa, g.drive_kpa);
  r.logistic = m;
  r.logistic_se = cov.diagonal().cwiseSqrt();
  double ss_tot = 0, mean = 0;
  for (const Ring& g : rings) mean += g.signal / double(rings.size());
  for (const Ring& g : rings) ss_tot += (g.signal - mean) * (g.signal - mean);
  r.r2_logistic = ss_tot > 0 ? 1 - res.squaredNorm() / ss_tot : NAN;
  // Inverse-predicted against the rings' drive.
  double se = 0;
  int n = 0;
  for (const Ring& g : rings) {
    const PressureEstimate e = cal.invert(g.signal);
    if (e.status != PressureStatus::ok) continue;
    se += (e.pressure_kpa - g.drive_kpa) * (e.pressure_kpa - g.drive_kpa), ++n;
  }
  r.rmse_kpa = n ? std::sqrt(se / n) : NAN;
  r.rmse_kpa_inliers = r.rmse_kpa;
  r.presses_in_range = n;
  cal.rmse_kpa = r.rmse_kpa;
  cal.r2 = r.r2_logistic;
  for (std::size_t i = 0; i < presses.size(); ++i) {  // per press: the mean ring residual
    PressResidual& pr = r.residuals[i];
    double sum = 0, count = 0;
    for (std::size_t k = 0; k < rings.size(); ++k)
      if (rings[k].press == i) sum += res[static_cast<Eigen::Index>(k)], count += 1;
    pr.residual_signal = count ? sum / count : NAN;
    pr.predicted_kpa = pr.residual_kpa = NAN;
    pr.weight = 1;
  }
  std::erase_if(r.warnings, [](const std::string& w) { return w.find("outlier") != std::string::npos; });
  r.warnings.push_back(std::string("fitted to ") + std::to_string(rings.size()) + " rings of " + std::to_string(presses.size()) +
                       " presses with the " + to_string(field.field) + " pressure field (blur " +
                       std::to_string(field.blur_sigma_mm).substr(0, 4) + " mm); per-press residuals are ring means");
  return r;
}

}  // namespace clearfit
