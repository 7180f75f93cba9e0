// The calibration fitted to the radially resolved signal with the indenter's
// pressure field (pressure_field_fit.hpp).
#include <clearfit/error.hpp>
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/format.hpp>
#include <clearfit/fit/pressure_field_fit.hpp>

#include <Eigen/Dense>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>

namespace clearfit {
namespace {

struct Ring {
  double force_n = 0, signal = 0, drive_kpa = 0;  // drive: the ring's mean blurred pressure
  double indenter_radius_mm = 0, sphere_radius_mm = NAN;
  std::vector<double> radii;                      // equal-area sub-radii, mm
  std::vector<double> drive_samples;              // kPa there
  std::size_t press = 0;
};

LogisticParams params_of(const Eigen::VectorXd& x) { return {std::exp(x[0]), x[1], std::exp(x[2])}; }

double ring_model(const LogisticParams& m, const Ring& r) {
  double s = 0;
  for (double d : r.drive_samples) s += logistic_signal(m, d);
  return s / double(r.drive_samples.size());
}

/// Ring k of a press, its drive not yet set.
Ring ring_of(const CalibrationPress& c, std::size_t k, int samples) {
  Ring r;
  r.force_n = c.force_n, r.signal = c.ring_signal[k];
  r.indenter_radius_mm = c.indenter_diameter_mm / 2, r.sphere_radius_mm = c.sphere_radius_mm;
  const double r0 = c.ring_edges_mm[k], r1 = c.ring_edges_mm[k + 1];
  for (int j = 0; j < samples; ++j) r.radii.push_back(std::sqrt(r0 * r0 + (j + 0.5) / samples * (r1 * r1 - r0 * r0)));
  r.drive_samples.assign(r.radii.size(), 0.0);
  return r;
}

/// Every ring's drive under the field: the punch's and the uniform disc's profiles tabulated once per
/// radius; the sphere's at its contact radius for E* = e_star_kpa, recomputed at each radius.
void set_drives(std::vector<Ring>& rings, const FieldFitOptions& o, double e_star_kpa) {
  std::map<double, std::unique_ptr<IndenterProfile>> profiles;  // by radius
  for (Ring& g : rings) {
    if (o.field == PressureField::hertz) {
      const double a = contact::HertzSphere{g.sphere_radius_mm, g.force_n, e_star_kpa}.contact_radius_mm();
      for (std::size_t j = 0; j < g.radii.size(); ++j) g.drive_samples[j] = g.force_n * blurred_hertz_kpa_per_newton(g.radii[j], a, o.skin_blur_mm);
    } else {
      auto& profile = profiles[g.indenter_radius_mm];
      if (!profile) profile = std::make_unique<IndenterProfile>(o.field, g.indenter_radius_mm, o.skin_blur_mm);
      for (std::size_t j = 0; j < g.radii.size(); ++j) g.drive_samples[j] = g.force_n * profile->kpa_per_newton(g.radii[j]);
    }
    g.drive_kpa = 0;
    for (double d : g.drive_samples) g.drive_kpa += d / double(g.drive_samples.size());
  }
}

struct Residuals {  // the functor Eigen's NumericalDiff and LevenbergMarquardt expect
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  std::vector<Ring>* rings;
  const FieldFitOptions* options;
  int parameters = 3;  // 4: ln E* as well (hertz), the drives recomputed at every evaluation
  Residuals(std::vector<Ring>& r, const FieldFitOptions& o, int n) : rings(&r), options(&o), parameters(n) {}
  int inputs() const { return parameters; }
  int values() const { return static_cast<int>(rings->size()); }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    if (parameters == 4) set_drives(*rings, *options, std::exp(x[3]));
    const LogisticParams m = params_of(x);
    for (std::size_t k = 0; k < rings->size(); ++k) f[k] = (*rings)[k].signal - ring_model(m, (*rings)[k]);
    return 0;
  }
};

std::vector<Ring> make_rings(const std::vector<CalibrationPress>& presses, const FieldFitOptions& o, const std::string& file) {
  std::vector<Ring> rings;
  for (std::size_t i = 0; i < presses.size(); ++i) {
    const CalibrationPress& c = presses[i];
    const std::string where = "line " + std::to_string(c.line);
    if (c.ring_signal.empty())
      throw InputError(file, where, "has no radial profile (ring_edges_mm, ring_signal)",
                       "write the presses with `clearfit presses`, or fit with --pressure-field uniform");
    if (!std::isfinite(c.force_n) || !std::isfinite(c.indenter_diameter_mm))
      throw InputError(file, where, "gives no force_n or indenter_diameter_mm; the indenter's pressure field needs both");
    if (o.field == PressureField::hertz && !std::isfinite(c.sphere_radius_mm))
      throw InputError(file, where, "gives no sphere_radius_mm; Hertz's pressure field needs the sphere's radius",
                       "write the presses with `clearfit presses --sphere-radius-mm R`, or fit a flat indenter with --pressure-field punch");
    for (std::size_t k = 0; k < c.ring_signal.size(); ++k) {
      if (!std::isfinite(c.ring_signal[k])) continue;
      rings.push_back(ring_of(c, k, o.samples_per_ring));
      rings.back().press = i;
    }
  }
  return rings;
}

/// A start for E* (kPa): the strongest press's contact radius taken where its profile falls to half its centre.
double e_star_start(const std::vector<CalibrationPress>& presses) {
  const auto& c = *std::max_element(presses.begin(), presses.end(), [](const auto& a, const auto& b) { return a.force_n < b.force_n; });
  double centre = NAN;
  for (double y : c.ring_signal)
    if (std::isfinite(y)) { centre = y; break; }
  double a = c.ring_edges_mm.back();
  for (std::size_t k = 0; k < c.ring_signal.size(); ++k)
    if (std::isfinite(c.ring_signal[k]) && c.ring_signal[k] < 0.5 * centre) { a = c.ring_edges_mm[k]; break; }
  a = std::max(a, 2 * c.ring_edges_mm[1]);
  return 3 * c.force_n * c.sphere_radius_mm / (4 * a * a * a) * 1000;  // N/mm² → kPa
}

/// The Hertz fit's start: a coarse grid over E* (factors of √2 about `e_star0`, or `e_star0` alone when
/// given) × p50 × w, y_max solved linearly, least squares; leaves the rings' drives at the E* chosen.
/// Returns (ln y_max, p50, ln w, ln E*).
Eigen::Vector4d hertz_start(std::vector<Ring>& rings, const FieldFitOptions& o, double e_star0, bool fit_e_star) {
  Eigen::Vector4d best_x = Eigen::Vector4d::Constant(NAN);
  double best = std::numeric_limits<double>::infinity();
  for (int e = fit_e_star ? -4 : 0; e <= (fit_e_star ? 4 : 0); ++e) {
    const double e_star = e_star0 * std::pow(2.0, e / 2.0);
    set_drives(rings, o, e_star);
    double span = 1e-6;
    for (const Ring& g : rings) span = std::max(span, g.drive_kpa);
    for (int a = 0; a < 40; ++a)
      for (int b = 0; b < 25; ++b) {
        const LogisticParams q0{1.0, span * (0.02 + 1.18 * a / 39.0), span * 0.01 * std::pow(50.0, b / 24.0)};
        double num = 0, den = 0, yy = 0;
        for (const Ring& g : rings) {
          const double psi = ring_model(q0, g);
          num += psi * g.signal, den += psi * psi, yy += g.signal * g.signal;
        }
        if (!(den > 0) || !(num > 0)) continue;
        const double cost = yy - num * num / den;  // the residual sum of squares at y_max = num / den
        if (cost < best) best = cost, best_x << std::log(num / den), q0.p50_kpa, std::log(q0.width_kpa), std::log(e_star);
      }
  }
  set_drives(rings, o, std::exp(best_x[3]));
  return best_x;
}

/// Levenberg–Marquardt from x; returns whether it converged within the evaluations allowed.
bool minimise(Residuals& f, Eigen::VectorXd& x, int& iterations) {
  Eigen::NumericalDiff<Residuals> nd(f);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Residuals>> lm(nd);
  lm.parameters.maxfev = 4000;
  const auto status = lm.minimize(x);
  iterations += static_cast<int>(lm.iter);
  return status != Eigen::LevenbergMarquardtSpace::TooManyFunctionEvaluation && x.allFinite();
}

double robust_scale(std::vector<double> v) {
  for (double& x : v) x = std::abs(x);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return 1.4826 * v[v.size() / 2];
}

}  // namespace

void FieldFitOptions::validate() const {
  if (!SkinBlur{skin_blur_mm}.valid())
    throw InputError("", "--skin-blur-mm", std::string("expected ") + SkinBlur::rule + ", got " + significant_digits(skin_blur_mm, 4));
  if (!(e_star_kpa >= 0 && e_star_kpa < 1e5))
    throw InputError("", "--e-star-kpa", "expected the skin's plane-strain modulus in kPa (> 0), or 0 to fit it");
  if (samples_per_ring < 1) throw std::invalid_argument("samples_per_ring must be >= 1");
}

bool presses_have_profiles(const std::vector<CalibrationPress>& presses) {
  return !presses.empty() && std::all_of(presses.begin(), presses.end(), [](const auto& c) { return !c.ring_signal.empty(); });
}

std::vector<double> ring_drives_kpa(const CalibrationPress& press, const FieldFitOptions& field, double e_star_kpa) {
  std::vector<Ring> rings;
  for (std::size_t k = 0; k < press.ring_signal.size(); ++k) rings.push_back(ring_of(press, k, field.samples_per_ring));
  set_drives(rings, field, e_star_kpa);
  std::vector<double> out;
  for (const Ring& g : rings) out.push_back(g.drive_kpa);
  return out;
}

PressureFitResult fit_pressure_field(const std::vector<CalibrationPress>& presses, const PressureFitOptions& options,
                                     const FieldFitOptions& field) {
  field.validate();
  std::vector<Ring> rings = make_rings(presses, field, options.source);
  PressureFitResult r = fit_pressure_calibration(presses, options);  // the uniform fit of the disc means: the start
  const bool hertz = field.field == PressureField::hertz, fit_e_star = hertz && field.e_star_kpa == 0;
  const double e_star0 = !hertz ? NAN : fit_e_star ? e_star_start(presses) : field.e_star_kpa;
  Eigen::VectorXd x(3);
  x << std::log(r.logistic.y_max), r.logistic.p50_kpa, std::log(r.logistic.width_kpa);
  double e_star = e_star0;
  if (hertz) {  // the uniform fit of the disc means says little about a sphere's field: a grid instead
    const Eigen::Vector4d start = hertz_start(rings, field, e_star0, fit_e_star);
    x = start.head(3), e_star = std::exp(start[3]);
  } else {
    set_drives(rings, field, NAN);
  }
  Residuals f3(rings, field, 3);
  r.iterations = 0;
  r.converged = minimise(f3, x, r.iterations);
  if (fit_e_star && x.allFinite()) {  // then E* with the logistic, from there
    Eigen::VectorXd x4(4);
    x4 << x, std::log(e_star);
    Residuals f4(rings, field, 4);
    r.converged = minimise(f4, x4, r.iterations);
    x = x4;
  }
  if (!x.allFinite()) throw InputError(options.source, "", "the pressure-field fit did not converge", "check the presses' profiles");
  const int n = static_cast<int>(x.size());
  Residuals f(rings, field, n);
  const LogisticParams m = params_of(x);
  // Covariance: s²(JᵀJ)⁻¹ in x, through dθ/dx = diag(y_max, 1, w[, E*]); the logistic's block for the calibration.
  Eigen::NumericalDiff<Residuals> nd(f);
  Eigen::MatrixXd jac(rings.size(), n);
  nd.df(x, jac);
  Eigen::VectorXd res(rings.size());
  f(x, res);  // also leaves the drives at the fitted E*
  const double dof = std::max(1.0, double(rings.size()) - n), s2 = res.squaredNorm() / dof;
  Eigen::VectorXd scale(n);
  scale.head(3) = Eigen::Vector3d(m.y_max, 1, m.width_kpa);
  if (n == 4) scale[3] = std::exp(x[3]);
  const Eigen::MatrixXd cov_all = scale.asDiagonal() * (s2 * (jac.transpose() * jac).inverse()) * scale.asDiagonal();
  const Eigen::Matrix3d cov = cov_all.topLeftCorner(3, 3);
  if (hertz) r.e_star_kpa = n == 4 ? std::exp(x[3]) : field.e_star_kpa, r.e_star_se_kpa = n == 4 ? std::sqrt(cov_all(3, 3)) : 0.0;

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
  int in_range = 0;
  for (const Ring& g : rings) {
    const PressureEstimate e = cal.invert(g.signal);
    if (e.status != PressureStatus::ok) continue;
    se += (e.pressure_kpa - g.drive_kpa) * (e.pressure_kpa - g.drive_kpa), ++in_range;
  }
  r.rmse_kpa = in_range ? std::sqrt(se / in_range) : NAN;
  r.rmse_kpa_inliers = r.rmse_kpa;
  r.presses_in_range = in_range;
  cal.rmse_kpa = r.rmse_kpa;
  cal.skin_blur_mm = field.skin_blur_mm;
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
  // The uniform fit's warnings speak of the disc means against F/(πa²): a sphere's contact is not that disc.
  if (hertz) r.warnings.clear();
  std::erase_if(r.warnings, [](const std::string& w) { return w.find("outlier") != std::string::npos; });
  if (!(m.p50_kpa > cal.p_min_kpa && m.p50_kpa < cal.p_max_kpa))
    r.warnings.push_back("p50 = " + fixed_digits(m.p50_kpa, 2) + " kPa lies outside the rings' drive [" + fixed_digits(cal.p_min_kpa, 2) +
                         ", " + fixed_digits(cal.p_max_kpa, 2) + "] kPa");
  std::string e_star_text;
  if (hertz)
    e_star_text = ", E* " + fixed_digits(r.e_star_kpa, 1) + (n == 4 ? " +- " + fixed_digits(r.e_star_se_kpa, 1) + " kPa fitted" : " kPa given");
  r.warnings.push_back(std::string("fitted to ") + std::to_string(rings.size()) + " rings of " + std::to_string(presses.size()) +
                        " presses with the " + to_string(field.field) + " pressure field (blur " +
                       fixed_digits(field.skin_blur_mm, 2) + " mm" + e_star_text + "); per-press residuals are ring means");
  return r;
}

}  // namespace clearfit
