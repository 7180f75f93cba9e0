// The per-person pressure calibration: forward model, robust fit, closed-form
// inverse with flags and uncertainty, calibration file and presses CSV.
// Independent checks: finite differences, Monte Carlo over seeds, a brute-force
// grid search with y_max solved linearly, the squared Pearson correlation.
#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <unistd.h>

namespace clearfit {
namespace {

namespace fs = std::filesystem;
const LogisticParams kTruth{0.05, 8.0, 2.0};  // y_max, p50 kPa, w kPa (SKIN.md's typical person)
constexpr double kNoise = 0.002;              // σ of one press's signal
const std::vector<double> kLevels{0, 2, 4, 6, 8, 10, 12, 15, 20, 25, 30};  // kPa, the protocol's 0-30 kPa

// 3 repetitions per level, pressure jittered ±2 % (load-cell readings), signal with Gaussian noise.
std::vector<CalibrationPress> simulate(unsigned seed, const LogisticParams& truth = kTruth, double noise = kNoise,
                                       const std::vector<double>& levels = kLevels, int reps = 3) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<CalibrationPress> out;
  for (double level : levels)
    for (int r = 0; r < reps; ++r) {
      CalibrationPress c;
      c.trial = std::to_string(out.size() + 1);
      c.mean_pressure_kpa = level * (1 + 0.02 * n01(rng));
      c.signal = logistic_signal(truth, c.mean_pressure_kpa) + noise * n01(rng);
      out.push_back(c);
    }
  return out;
}

PressureFitOptions options(RobustLoss loss = RobustLoss::tukey, PressureModelKind model = PressureModelKind::logistic) {
  PressureFitOptions o;
  o.person = "P01";
  o.loss = loss;
  o.model = model;
  o.source = "presses.csv";
  return o;
}

Eigen::Vector3d as_vec(const LogisticParams& m) { return {m.y_max, m.p50_kpa, m.width_kpa}; }

TEST(PressureModel, ForwardStartsAtZeroAndSaturates) {
  for (const LogisticParams m : {kTruth, LogisticParams{0.1, 3, 0.5}, LogisticParams{0.02, 12, 3}}) {
    EXPECT_EQ(logistic_signal(m, 0.0), 0.0);
    EXPECT_NEAR(logistic_signal(m, m.p50_kpa + 40 * m.width_kpa), m.y_max, 1e-12 * m.y_max);
    double prev = -1;
    for (double p = 0; p < 40; p += 0.25) {
      const double y = logistic_signal(m, p);
      if (p < m.p50_kpa + 10 * m.width_kpa) EXPECT_GT(y, prev) << p;  // beyond, y == y_max in double
      else EXPECT_GE(y, prev) << p;
      prev = y;
    }
  }
}

TEST(PressureModel, GradientMatchesFiniteDifferences) {
  for (double p : {0.0, 1.0, 5.0, 8.0, 11.0, 25.0}) {
    const Eigen::Vector3d g = logistic_gradient(kTruth, p);
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d th = as_vec(kTruth);
      const double h = 1e-6 * std::max(1.0, std::abs(th[k]));
      auto f = [&](double d) {
        Eigen::Vector3d t = th;
        t[k] += d;
        return logistic_signal({t[0], t[1], t[2]}, p);
      };
      EXPECT_NEAR(g[k], (f(h) - f(-h)) / (2 * h), 1e-7) << "p " << p << " parameter " << k;
    }
  }
}

TEST(PressureFit, RecoversParametersWithinReportedStandardErrors) {
  const unsigned seed = 1234;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const PressureFitResult r = fit_pressure_calibration(simulate(seed), options());
  EXPECT_TRUE(r.converged);
  const Eigen::Vector3d err = as_vec(r.logistic) - as_vec(kTruth);
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(r.logistic_se[k], 0);
    EXPECT_LT(std::abs(err[k]), 3 * r.logistic_se[k]) << "parameter " << k;
  }
  // The calibration stores the same model and a noise estimate near the truth.
  EXPECT_EQ(as_vec(r.calibration.logistic), as_vec(r.logistic));
  EXPECT_NEAR(r.calibration.noise_sigma, kNoise, 0.4 * kNoise);
  EXPECT_EQ(r.calibration.person, "P01");
  EXPECT_EQ(r.levels, static_cast<int>(kLevels.size()));
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
}

// Over many seeds: the reported SE is calibrated (coverage of 1 and 2 SE near
// 68 % and 95 %), and the parameter part of the inverse's σ matches the spread
// of the inverse of one fixed signal across refits.
TEST(PressureFit, StandardErrorsMatchMonteCarlo) {
  const int runs = 120;
  Eigen::Vector3i within1 = Eigen::Vector3i::Zero(), within2 = Eigen::Vector3i::Zero();
  const double y_fixed = logistic_signal(kTruth, 10.0);
  std::vector<double> p_hat;
  double sigma_param_sum = 0;
  for (int s = 0; s < runs; ++s) {
    const PressureFitResult r = fit_pressure_calibration(simulate(1000 + s), options());
    const Eigen::Vector3d err = (as_vec(r.logistic) - as_vec(kTruth)).cwiseAbs();
    for (int k = 0; k < 3; ++k) {
      within1[k] += err[k] < r.logistic_se[k];
      within2[k] += err[k] < 2 * r.logistic_se[k];
    }
    const PressureEstimate e = r.calibration.invert(y_fixed, 0.0);  // σ_y = 0: parameter part only
    ASSERT_EQ(e.status, PressureStatus::ok);
    p_hat.push_back(e.pressure_kpa);
    sigma_param_sum += e.sigma_kpa;
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(within2[k], 0.85 * runs) << "parameter " << k << " (seeds 1000..)";
    EXPECT_GT(within1[k], 0.50 * runs) << "parameter " << k;
    EXPECT_LT(within1[k], 0.86 * runs) << "parameter " << k << ": SE too large";
  }
  double mean = 0, var = 0;
  for (double v : p_hat) mean += v / runs;
  for (double v : p_hat) var += (v - mean) * (v - mean) / (runs - 1);
  EXPECT_NEAR(sigma_param_sum / runs, std::sqrt(var), 0.25 * std::sqrt(var));
  EXPECT_NEAR(mean, 10.0, 3 * std::sqrt(var / runs) + 0.05);
}

// Where the curve is steep (5-11 kPa) the inverse is nearly linear in the
// noise, so the RMS kPa error there must match σ_y / (dy/dp) of the true model.
// Towards saturation flagged presses are left out, which can only lower the
// overall RMSE.
TEST(PressureFit, RmseMatchesPropagatedNoise) {
  double central_sum = 0, expected_sum = 0, all_ratio_min = 1e9, all_ratio_max = 0;
  for (unsigned seed = 200; seed < 220; ++seed) {
    const PressureFitResult r = fit_pressure_calibration(simulate(seed), options());
    double s2 = 0, e2 = 0, e2_all = 0, s2_all = 0;
    int n = 0, n_all = 0;
    for (const PressResidual& pr : r.residuals) {
      if (pr.status != PressureStatus::ok) continue;
      const double dy_dp = (logistic_signal(kTruth, pr.pressure_kpa + 1e-4) - logistic_signal(kTruth, pr.pressure_kpa - 1e-4)) / 2e-4;
      const double propagated2 = std::pow(kNoise / dy_dp, 2);
      if (pr.pressure_kpa >= 5 && pr.pressure_kpa <= 11) {
        s2 += propagated2;
        e2 += pr.residual_kpa * pr.residual_kpa;
        ++n;
      }
      const double p_lo = r.calibration.invert(r.calibration.detection_signal(), 0).pressure_kpa;
      const double p_hi = r.calibration.invert(1e9).bound_kpa;
      if (pr.pressure_kpa >= p_lo && pr.pressure_kpa <= p_hi) {
        e2_all += pr.residual_kpa * pr.residual_kpa;
        s2_all += propagated2;
        ++n_all;
      }
    }
    ASSERT_GE(n, 8);
    // The reported RMSE is the RMS over the presses inside the invertible range.
    ASSERT_EQ(n_all, r.presses_in_range);
    EXPECT_NEAR(r.rmse_kpa, std::sqrt(e2_all / n_all), 1e-12);
    all_ratio_min = std::min(all_ratio_min, r.rmse_kpa / std::sqrt(s2_all / n_all));
    all_ratio_max = std::max(all_ratio_max, r.rmse_kpa / std::sqrt(s2_all / n_all));
    central_sum += std::sqrt(e2 / n);
    expected_sum += std::sqrt(s2 / n);
  }
  EXPECT_NEAR(central_sum / expected_sum, 1.0, 0.15) << "fitted " << central_sum / 20 << " kPa, propagated " << expected_sum / 20;
  EXPECT_GT(all_ratio_min, 0.3);
  EXPECT_LT(all_ratio_max, 1.6);
}

TEST(PressureFit, RobustFitResistsOutliersThatMoveLeastSquares) {
  const unsigned seed = 77;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto clean = simulate(seed);
  auto bad = clean, removed = clean;
  // Three corrupted trials: a reflection or a twitch adds a large signal at low pressure.
  const std::vector<int> corrupted{4, 7, 10};
  for (int i : corrupted) bad[i].signal += 0.03;
  for (auto it = corrupted.rbegin(); it != corrupted.rend(); ++it) removed.erase(removed.begin() + *it);
  // The reference: least squares on the good presses only (what an oracle would do).
  const PressureFitResult ref = fit_pressure_calibration(removed, options(RobustLoss::none));
  const PressureFitResult robust = fit_pressure_calibration(bad, options());
  const PressureFitResult huber = fit_pressure_calibration(bad, options(RobustLoss::huber));
  const PressureFitResult plain = fit_pressure_calibration(bad, options(RobustLoss::none));
  const Eigen::Vector3d se = ref.logistic_se;
  auto moved = [&](const PressureFitResult& r) {
    return Eigen::Vector3d((as_vec(r.logistic) - as_vec(ref.logistic)).cwiseQuotient(se).cwiseAbs());
  };
  EXPECT_LT(moved(robust).maxCoeff(), 0.3) << moved(robust).transpose();
  EXPECT_LT(moved(huber).maxCoeff(), 2.5) << moved(huber).transpose();
  EXPECT_GT(moved(plain).maxCoeff(), 3.0) << moved(plain).transpose();
  EXPECT_GT(plain.calibration.noise_sigma, 2 * robust.calibration.noise_sigma);
  // The outliers are named.
  bool named = false;
  for (const auto& w : robust.warnings) named |= w.find("outlier") != std::string::npos && w.find("5, 8, 11") != std::string::npos;
  EXPECT_TRUE(named);
  EXPECT_LT(robust.residuals[4].weight, 0.5);
  EXPECT_GT(robust.residuals[5].weight, 0.5);
}

// A second method: brute-force grid over (p50, w) with y_max solved linearly
// (least squares), against LM with the plain least-squares loss.
TEST(PressureFit, AgreesWithBruteForceGridSearch) {
  const auto presses = simulate(31);
  const PressureFitResult r = fit_pressure_calibration(presses, options(RobustLoss::none));
  double best = 1e300;
  LogisticParams g{};
  auto sse_of = [&](const LogisticParams& q) {
    double s = 0;
    for (const auto& c : presses) s += std::pow(c.signal - logistic_signal(q, c.mean_pressure_kpa), 2);
    return s;
  };
  const double step = 0.01;
  for (double p50 = 5.0; p50 <= 11.0; p50 += step)
    for (double w = 1.0; w <= 3.5; w += step) {
      double num = 0, den = 0;
      for (const auto& c : presses) {
        const double psi = logistic_signal({1.0, p50, w}, c.mean_pressure_kpa);
        num += psi * c.signal;
        den += psi * psi;
      }
      const LogisticParams q{num / den, p50, w};
      const double s = sse_of(q);
      if (s < best) best = s, g = q;
    }
  EXPECT_NEAR(r.logistic.p50_kpa, g.p50_kpa, 1.5 * step);
  EXPECT_NEAR(r.logistic.width_kpa, g.width_kpa, 1.5 * step);
  EXPECT_NEAR(r.logistic.y_max, g.y_max, 2e-3 * g.y_max);
  EXPECT_LE(sse_of(r.logistic), best * (1 + 1e-9));
}

TEST(PressureFit, LinearModelIsWorseOnSigmoidDataAndMatchesPearson) {
  const auto presses = simulate(5);
  const PressureFitResult r = fit_pressure_calibration(presses, options());
  EXPECT_LT(r.linear.r2, r.r2_logistic - 0.05);
  EXPECT_GT(r.r2_logistic, 0.95);
  // OLS R² = squared Pearson correlation (independent formula).
  double mp = 0, my = 0;
  for (const auto& c : presses) mp += c.mean_pressure_kpa / presses.size(), my += c.signal / presses.size();
  double sxy = 0, sxx = 0, syy = 0;
  for (const auto& c : presses) {
    sxy += (c.mean_pressure_kpa - mp) * (c.signal - my);
    sxx += std::pow(c.mean_pressure_kpa - mp, 2);
    syy += std::pow(c.signal - my, 2);
  }
  EXPECT_NEAR(r.linear.r2, sxy * sxy / (sxx * syy), 1e-12);
  EXPECT_NEAR(r.linear.slope_per_kpa, sxy / sxx, 1e-12);
  EXPECT_NEAR(r.linear.intercept, my - sxy / sxx * mp, 1e-12);
  // The linear model as the stored calibration.
  const PressureFitResult lin = fit_pressure_calibration(presses, options(RobustLoss::tukey, PressureModelKind::linear));
  EXPECT_EQ(lin.calibration.model, PressureModelKind::linear);
  EXPECT_DOUBLE_EQ(lin.calibration.r2, r.linear.r2);
  EXPECT_GT(lin.rmse_kpa, r.rmse_kpa);
  EXPECT_NEAR(std::sqrt(lin.calibration.covariance(1, 1)), r.linear.se_slope, 1e-15);
}

TEST(PressureFit, WarnsAboutPoorDesigns) {
  auto has = [](const PressureFitResult& r, const std::string& what) {
    for (const auto& w : r.warnings)
      if (w.find(what) != std::string::npos) return true;
    return false;
  };
  const auto few = fit_pressure_calibration(simulate(3, kTruth, kNoise, {0, 5, 8, 12, 30}), options());
  EXPECT_TRUE(has(few, "too few pressure levels")) << few.warnings.size();
  const auto low = fit_pressure_calibration(simulate(3, kTruth, kNoise, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}), options());
  EXPECT_TRUE(has(low, "saturation not reached"));
  const auto gap = fit_pressure_calibration(simulate(3, kTruth, 0.0005, {0, 1, 2, 3, 14, 16, 20, 25, 30}), options());
  EXPECT_TRUE(has(gap, "not pinned")) << gap.logistic.p50_kpa << " " << gap.logistic.width_kpa;
  auto presses = simulate(3);
  for (auto& c : presses)
    if (c.mean_pressure_kpa > 22 && c.mean_pressure_kpa < 28) c.signal -= 0.02;
  EXPECT_TRUE(has(fit_pressure_calibration(presses, options(RobustLoss::none)), "non-monotone"));
  const auto good = fit_pressure_calibration(simulate(3), options());
  EXPECT_TRUE(good.warnings.empty());
}

TEST(PressureFit, RefusesUnusableData) {
  auto presses = simulate(9);
  EXPECT_THROW(fit_pressure_calibration({presses.begin(), presses.begin() + 3}, options()), InputError);
  EXPECT_THROW(fit_pressure_calibration(simulate(9, kTruth, kNoise, {0, 10}), options()), InputError);
  for (auto& c : presses) c.signal = -c.signal;
  try {
    fit_pressure_calibration(presses, options());
    ADD_FAILURE() << "a falling signal was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not rise"), std::string::npos) << e.what();
    EXPECT_EQ(e.file(), "presses.csv");
  }
  PressureFitOptions no_person = options();
  no_person.person.clear();
  EXPECT_THROW(fit_pressure_calibration(simulate(9), no_person), std::invalid_argument);
}

PressureCalibration truth_calibration(double p_max = 30) {
  PressureCalibration c;
  c.logistic = kTruth;
  c.noise_sigma = kNoise;
  c.person = "P01";
  c.p_min_kpa = 0;
  c.p_max_kpa = p_max;
  c.covariance = Eigen::Vector3d(1e-6, 0.04, 0.01).asDiagonal();
  c.covariance(1, 2) = c.covariance(2, 1) = 0.01;
  return c;
}

TEST(PressureInverse, InverseOfForwardIsIdentityInsideRange) {
  const PressureCalibration cal = truth_calibration();
  std::vector<float> ys;
  std::vector<double> ps;
  for (double p = 0; p <= 30; p += 0.05) {
    const double y = cal.signal(p);
    const PressureEstimate e = cal.invert(y);
    if (y < cal.detection_signal() || y > cal.saturation_signal()) {
      EXPECT_NE(e.status, PressureStatus::ok) << p;
      continue;
    }
    ASSERT_EQ(e.status, PressureStatus::ok) << p;
    EXPECT_NEAR(e.pressure_kpa, p, 1e-9 * std::max(1.0, p));
    ys.push_back(static_cast<float>(y));
    ps.push_back(p);
  }
  ASSERT_GT(ys.size(), 150u);
  std::vector<float> out(ys.size()), sig(ys.size());
  std::vector<std::uint8_t> st(ys.size());
  cal.invert(ys, {}, out, sig, st);
  for (std::size_t i = 0; i < ys.size(); ++i) {
    const PressureEstimate e = cal.invert(static_cast<double>(ys[i]));
    EXPECT_EQ(st[i], static_cast<std::uint8_t>(e.status));
    if (e.status != PressureStatus::ok) continue;  // float rounding at the very edges
    EXPECT_NEAR(out[i], e.pressure_kpa, 1e-5 * e.pressure_kpa);
    EXPECT_NEAR(sig[i], e.sigma_kpa, 1e-5 * e.sigma_kpa);
    EXPECT_NEAR(out[i], ps[i], 2e-3);  // the float signal's rounding, through the slope
  }
}

TEST(PressureInverse, FlagsAtTheBoundaries) {
  const PressureCalibration cal = truth_calibration();
  const double y_det = 3 * kNoise, y_sat = 0.95 * kTruth.y_max;
  EXPECT_DOUBLE_EQ(cal.detection_signal(), y_det);
  EXPECT_DOUBLE_EQ(cal.saturation_signal(), y_sat);
  // Closed forms of the limits' pressures: p = p50 + w·logit(s0 + (1 − s0)·u).
  auto p_at = [](double u) {
    const double s0 = 1 / (1 + std::exp(kTruth.p50_kpa / kTruth.width_kpa));
    const double s = s0 + (1 - s0) * u;
    return kTruth.p50_kpa + kTruth.width_kpa * std::log(s / (1 - s));
  };
  const PressureEstimate below = cal.invert(y_det * (1 - 1e-9));
  EXPECT_EQ(below.status, PressureStatus::below_detection);
  EXPECT_TRUE(std::isnan(below.pressure_kpa));
  EXPECT_TRUE(std::isnan(below.sigma_kpa));
  EXPECT_NEAR(below.bound_kpa, p_at(y_det / kTruth.y_max), 1e-6);
  EXPECT_EQ(cal.invert(-0.01).status, PressureStatus::below_detection);
  const PressureEstimate above_det = cal.invert(y_det * (1 + 1e-9));
  EXPECT_EQ(above_det.status, PressureStatus::ok);
  EXPECT_NEAR(above_det.pressure_kpa, p_at(y_det / kTruth.y_max), 1e-6);
  const PressureEstimate sat = cal.invert(y_sat * (1 + 1e-9));
  EXPECT_EQ(sat.status, PressureStatus::saturated);
  EXPECT_NEAR(sat.pressure_kpa, p_at(0.95), 1e-9);
  EXPECT_EQ(sat.bound_kpa, sat.pressure_kpa);
  EXPECT_EQ(cal.invert(kTruth.y_max * 3).status, PressureStatus::saturated);
  const PressureEstimate below_sat = cal.invert(y_sat * (1 - 1e-9));
  EXPECT_EQ(below_sat.status, PressureStatus::ok);
  EXPECT_NEAR(below_sat.pressure_kpa, p_at(0.95), 1e-5);
  for (double bad : {std::nan(""), double(INFINITY), -double(INFINITY)}) {
    const PressureEstimate e = cal.invert(bad);
    EXPECT_EQ(e.status, PressureStatus::invalid);
    EXPECT_TRUE(std::isnan(e.pressure_kpa));
  }
  // Data that stopped at 10 kPa: nothing above the signal at 10 kPa is inverted.
  const PressureCalibration short_range = truth_calibration(10.0);
  EXPECT_DOUBLE_EQ(short_range.saturation_signal(), logistic_signal(kTruth, 10.0));
  const PressureEstimate capped = short_range.invert(logistic_signal(kTruth, 12.0));
  EXPECT_EQ(capped.status, PressureStatus::saturated);
  EXPECT_NEAR(capped.pressure_kpa, 10.0, 1e-9);
  // The vectorised inverse flags the same.
  const std::vector<float> ys{float(y_det * 0.99), float(y_det * 1.01), float(y_sat * 1.01), float(y_sat * 0.99), NAN, -1.f};
  std::vector<float> p(ys.size()), s(ys.size());
  std::vector<std::uint8_t> st(ys.size());
  cal.invert(ys, {}, p, s, st);
  const std::vector<PressureStatus> expected{PressureStatus::below_detection, PressureStatus::ok, PressureStatus::saturated,
                                             PressureStatus::ok, PressureStatus::invalid, PressureStatus::below_detection};
  for (std::size_t i = 0; i < ys.size(); ++i) EXPECT_EQ(st[i], static_cast<std::uint8_t>(expected[i])) << i;
  EXPECT_TRUE(std::isnan(p[0]) && std::isnan(s[0]) && std::isnan(p[4]) && std::isnan(s[2]));
  EXPECT_NEAR(p[2], p_at(0.95), 1e-4);
  std::vector<float> wrong(2);
  EXPECT_THROW(cal.invert(ys, {}, wrong, s, st), std::invalid_argument);
}

// σ_p² = (dp/dy)² σ_y² + gᵀ C g, checked with finite differences of the inverse itself.
TEST(PressureInverse, UncertaintyMatchesFiniteDifferences) {
  const PressureCalibration cal = truth_calibration();
  for (double p : {5.0, 8.0, 11.0}) {
    const double y = cal.signal(p), sigma_y = 0.0015;
    const PressureEstimate e = cal.invert(y, sigma_y);
    const double h = 1e-7;
    const double dp_dy = (cal.invert(y + h, 0).pressure_kpa - cal.invert(y - h, 0).pressure_kpa) / (2 * h);
    Eigen::Vector3d g;
    for (int k = 0; k < 3; ++k) {
      auto shifted = [&](double d) {
        PressureCalibration c = cal;
        Eigen::Vector3d t = as_vec(cal.logistic);
        t[k] += d;
        c.logistic = {t[0], t[1], t[2]};
        return c.invert(y, 0).pressure_kpa;
      };
      const double hk = 1e-6 * std::max(1.0, std::abs(as_vec(cal.logistic)[k]));
      g[k] = (shifted(hk) - shifted(-hk)) / (2 * hk);
    }
    const double expected = std::sqrt(dp_dy * dp_dy * sigma_y * sigma_y + g.dot(cal.covariance * g));
    EXPECT_NEAR(e.sigma_kpa, expected, 1e-5 * expected) << p;
  }
}

TEST(PressureInverse, MegatexelFieldIsFast) {
  const PressureCalibration cal = truth_calibration();
  const std::size_t n = 1 << 20;
  std::vector<float> y(n), p(n), s(n);
  std::vector<std::uint8_t> st(n);
  for (std::size_t i = 0; i < n; ++i) y[i] = static_cast<float>(0.06 * (i % 1000) / 1000.0 - 0.005);
  double ms = 1e300;
  for (int rep = 0; rep < 5; ++rep) {  // the best of 5 (the first also warms up the thread pool)
    const auto t0 = std::chrono::steady_clock::now();
    cal.invert(y, {}, p, s, st);
    ms = std::min(ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::printf("inverse of %zu texels: %.2f ms (best of 5)\n", n, ms);  // printed, not asserted
  for (std::size_t i = 0; i < 1000; i += 37) {
    const PressureEstimate e = cal.invert(static_cast<double>(y[i]));
    EXPECT_EQ(st[i], static_cast<std::uint8_t>(e.status));
  }
}

// ---------------------------------------------------------------- files

struct TempDir {
  fs::path path;
  TempDir() {
    std::string t = (fs::temp_directory_path() / "clearfit_pressure_XXXXXX").string();
    if (!mkdtemp(t.data())) throw std::runtime_error("mkdtemp");
    path = t;
  }
  ~TempDir() { fs::remove_all(path); }
  fs::path write(const std::string& name, const std::string& text) const {
    std::ofstream(path / name, std::ios::binary) << text;
    return path / name;
  }
};

TEST(CalibrationFile, RoundTrip) {
  TempDir dir;
  for (PressureModelKind kind : {PressureModelKind::logistic, PressureModelKind::linear}) {
    PressureFitOptions o = options(RobustLoss::tukey, kind);
    o.camera_hash = "0123456789abcdef";
    const PressureCalibration cal = fit_pressure_calibration(simulate(8), o).calibration;
    const fs::path file = dir.path / "cal.json";
    write_pressure_calibration(cal, file);
    const PressureCalibration back = read_pressure_calibration(file);
    EXPECT_EQ(back.model, kind);
    EXPECT_EQ(as_vec(back.logistic), as_vec(cal.logistic));
    EXPECT_EQ(back.intercept, cal.intercept);
    EXPECT_EQ(back.slope_per_kpa, cal.slope_per_kpa);
    EXPECT_EQ(back.covariance, cal.covariance);
    EXPECT_EQ(back.noise_sigma, cal.noise_sigma);
    EXPECT_EQ(back.person, "P01");
    EXPECT_EQ(back.camera_hash, "0123456789abcdef");
    EXPECT_EQ(back.created, cal.created);
    EXPECT_EQ(back.p_min_kpa, cal.p_min_kpa);
    EXPECT_EQ(back.p_max_kpa, cal.p_max_kpa);
    EXPECT_EQ(back.rmse_kpa, cal.rmse_kpa);
    EXPECT_EQ(back.presses, cal.presses);
    EXPECT_TRUE(std::isnan(back.skin_blur_mm));  // the uniform fit models no blur: null
    EXPECT_EQ(back.path, file);
    for (double y : {0.0, 0.01, 0.02, 0.03, 0.045, 0.06}) {
      const PressureEstimate a = back.invert(y), b = cal.invert(y);
      EXPECT_EQ(a.status, b.status) << y;
      for (auto [u, v] : {std::pair{a.pressure_kpa, b.pressure_kpa}, {a.sigma_kpa, b.sigma_kpa}, {a.bound_kpa, b.bound_kpa}})
        EXPECT_TRUE(u == v || (std::isnan(u) && std::isnan(v))) << y << ": " << u << " vs " << v;
    }
    const auto j = nlohmann::json::parse(std::ifstream(file));
    EXPECT_EQ(j.at("schema"), "clearfit.pressure-calibration/1");
  }
  EXPECT_EQ(format_intrinsics_hash(0xabcULL), "0000000000000abc");
  // The skin blur a field fit assumed is kept; a file without the key (written before it was recorded) reads NaN.
  PressureCalibration blurred = fit_pressure_calibration(simulate(8), options()).calibration;
  blurred.skin_blur_mm = 0.45;
  const fs::path file = dir.path / "blurred.json";
  write_pressure_calibration(blurred, file);
  EXPECT_EQ(read_pressure_calibration(file).skin_blur_mm, 0.45);
  auto j = nlohmann::json::parse(std::ifstream(file));
  EXPECT_EQ(j.at("skin_blur_mm"), 0.45);
  j.erase("skin_blur_mm");
  std::ofstream(file, std::ios::trunc) << j.dump(2);
  EXPECT_TRUE(std::isnan(read_pressure_calibration(file).skin_blur_mm));
}

TEST(CalibrationFile, RefusesWrongSchemaMissingKeysAndBadValues) {
  TempDir dir;
  const fs::path good = dir.path / "cal.json";
  write_pressure_calibration(fit_pressure_calibration(simulate(8), options()).calibration, good);
  const auto j = nlohmann::json::parse(std::ifstream(good));
  auto expect_error = [&](nlohmann::json changed, const std::string& must_name) {
    const fs::path f = dir.write("bad.json", changed.dump(2));
    try {
      read_pressure_calibration(f);
      ADD_FAILURE() << "accepted a file that should name " << must_name;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), f.string());
      EXPECT_NE(std::string(e.what()).find(must_name), std::string::npos) << e.what();
    }
  };
  auto c = j;
  c["schema"] = "clearfit.pressure-calibration/2";
  expect_error(c, "key 'schema'");
  c = j;
  c["parameters"].erase("p50_kpa");
  expect_error(c, "key 'parameters.p50_kpa'");
  c = j;
  c["parameters"]["width_kpa"] = -1.0;
  expect_error(c, "parameters.width_kpa");
  c = j;
  c["noise_sigma"] = "small";
  expect_error(c, "key 'noise_sigma'");
  c = j;
  c.erase("person");
  expect_error(c, "key 'person'");
  c = j;
  c["covariance"][0] = {1.0, 2.0};
  expect_error(c, "covariance");
  c = j;
  c["model"] = "cubic";
  expect_error(c, "key 'model'");
  for (const nlohmann::json& blur : {nlohmann::json(-0.1), nlohmann::json(6.0), nlohmann::json("0.3")}) {
    c = j;
    c["skin_blur_mm"] = blur;
    expect_error(c, "key 'skin_blur_mm'");
  }
  const fs::path broken = dir.write("broken.json", "{\n  \"schema\": \"clearfit.pressure-calibration/1\",\n  oops\n}");
  try {
    read_pressure_calibration(broken);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_pressure_calibration(dir.path / "missing.json"), InputError);
}

TEST(CalibrationFile, WrongPersonOrCameraRefused) {
  PressureCalibration cal = truth_calibration();
  cal.camera_hash = "00000000000000aa";
  cal.path = "cal.json";
  EXPECT_TRUE(check_calibration_matches(cal, "P01", "00000000000000aa").empty());
  try {
    check_calibration_matches(cal, "P02", "00000000000000aa");
    ADD_FAILURE();
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("'P01'"), std::string::npos) << m;
    EXPECT_NE(m.find("'P02'"), std::string::npos) << m;
    EXPECT_NE(m.find("cal.json"), std::string::npos) << m;
  }
  try {
    check_calibration_matches(cal, "P01", "00000000000000bb");
    ADD_FAILURE();
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("00000000000000aa"), std::string::npos) << m;
    EXPECT_NE(m.find("00000000000000bb"), std::string::npos) << m;
  }
  cal.camera_hash.clear();
  EXPECT_EQ(check_calibration_matches(cal, "P01", "00000000000000bb").size(), 1u);
}

TEST(PressesCsv, ReadsPressuresGivenOrComputedFromForce) {
  TempDir dir;
  const fs::path f = dir.write("presses.csv",
                               "# calibration presses\r\n"
                               "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal,notes\r\n"
                               "1,3,0.1,14.147106,0.031,x\r\n"
                               "\r\n"
                               "2,4,0.2,,0.02,y\r\n"
                               "3,,,5.5,0.004,\r\n");
  std::vector<std::string> notes;
  const auto presses = read_presses_csv(f, &notes);
  ASSERT_EQ(presses.size(), 3u);
  EXPECT_EQ(presses[0].trial, "1");
  EXPECT_EQ(presses[0].line, 3);
  EXPECT_DOUBLE_EQ(presses[0].mean_pressure_kpa, 14.147106);
  EXPECT_NEAR(presses[1].mean_pressure_kpa, 1000 * 0.2 / (M_PI * 4), 1e-12);  // F / (π r²), r = 2 mm
  EXPECT_EQ(presses[1].line, 5);
  EXPECT_DOUBLE_EQ(presses[2].mean_pressure_kpa, 5.5);
  EXPECT_TRUE(std::isnan(presses[2].force_n));
  EXPECT_DOUBLE_EQ(presses[2].signal, 0.004);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("notes"), std::string::npos);
}

TEST(PressesCsv, RefusesBadFieldsWithTheirLine) {
  TempDir dir;
  const std::string header = "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal\n";
  auto expect_error = [&](const std::string& text, const std::vector<std::string>& must_name) {
    const fs::path f = dir.write("p.csv", text);
    try {
      read_presses_csv(f);
      ADD_FAILURE() << "accepted:\n" << text;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), f.string());
      for (const auto& s : must_name) EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what();
    }
  };
  expect_error("trial,force_n,signal\n1,0.1,0.01\n", {"line 1", "mean_pressure_kpa"});
  expect_error("trial,mean_pressure_kpa\n1,3\n", {"missing column 'signal'"});
  expect_error(header + "1,3,0.1,14.147,0.01\n2,3,abc,,0.01\n", {"line 3", "force_n", "'abc'"});
  expect_error(header + "1,3,0.1,14.147,0.01x\n", {"line 2", "signal"});
  expect_error(header + "1,3,-0.1,,0.01\n", {"line 2", "negative"});
  expect_error(header + "1,0,0.1,,0.01\n", {"line 2", "indenter_diameter_mm"});
  expect_error(header + "1,3,0.1,20,0.01\n", {"line 2", "disagrees"});
  expect_error(header + "1,3,0.1,14.147\n", {"line 2", "4 fields"});
  expect_error(header + "1,3,,,0.01\n", {"line 2", "no pressure"});
  expect_error(header + "1,3,0.1,,nan\n", {"line 2", "finite"});
  expect_error(header, {"no data rows"});
  expect_error("", {"empty"});
  EXPECT_THROW(read_presses_csv(dir.path / "none.csv"), InputError);
}

}  // namespace
}  // namespace clearfit
