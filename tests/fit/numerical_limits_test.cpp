// Numerical limits of the pressure calibration (issue 16, section 5): presses
// without noise, at zero force, at one level, with a flat signal, with
// pressures and signals from 1e-9 to 1e9 of the usual; inversion of signals
// at and beyond every bound. Each gives the truth it was made from (finite)
// or an InputError naming the real cause; never a NaN estimate with an ok
// status.
#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

using namespace clearfit;

namespace {

std::vector<CalibrationPress> presses_of(const LogisticParams& truth, const std::vector<double>& pressures,
                                         double noise, std::mt19937_64& rng) {
  std::normal_distribution<double> g(0, 1);
  std::vector<CalibrationPress> out;
  for (double p : pressures) {
    CalibrationPress c;
    c.trial = std::string("t") + std::to_string(out.size());
    c.mean_pressure_kpa = p;
    c.indenter_diameter_mm = 5;
    c.force_n = p * M_PI * 6.25 / 1000;
    c.signal = logistic_signal(truth, p) + noise * g(rng);
    out.push_back(c);
  }
  return out;
}

std::vector<double> levels(double p_max, int n, int repeats) {
  std::vector<double> p;
  for (int k = 0; k < n; ++k)
    for (int r = 0; r < repeats; ++r) p.push_back(p_max * k / (n - 1));
  return p;
}

PressureFitOptions options() {
  PressureFitOptions o;
  o.person = "p";
  o.source = "presses.csv";
  return o;
}

void expect_finite(const PressureFitResult& r, const std::string& what) {
  const PressureCalibration& c = r.calibration;
  EXPECT_TRUE(std::isfinite(c.logistic.y_max) && std::isfinite(c.logistic.p50_kpa) && std::isfinite(c.logistic.width_kpa))
      << what;
  EXPECT_TRUE(c.covariance.allFinite()) << what << "\n" << c.covariance;
  EXPECT_TRUE(std::isfinite(c.noise_sigma) && c.noise_sigma >= 0) << what << ": noise " << c.noise_sigma;
  EXPECT_TRUE(std::isfinite(r.rmse_kpa)) << what;
  EXPECT_TRUE(std::isfinite(c.r2) || c.model == PressureModelKind::linear) << what;
  for (const PressResidual& p : r.residuals) {
    EXPECT_TRUE(std::isfinite(p.residual_signal) && std::isfinite(p.weight)) << what << ", " << p.trial;
    if (p.status == PressureStatus::ok) {
      EXPECT_TRUE(std::isfinite(p.predicted_kpa) && std::isfinite(p.residual_kpa)) << what << ", " << p.trial;
    }
  }
}

// Every inversion: ok means a finite pressure and σ; the flags carry their bound.
void expect_sane_inversions(const PressureCalibration& c, const std::string& what) {
  const double big = std::numeric_limits<double>::max(), tiny = std::numeric_limits<double>::denorm_min();
  const double ys[] = {0, tiny, -tiny, 1e-300, c.detection_signal(), c.saturation_signal(), c.logistic.y_max,
                       0.5 * c.logistic.y_max, 2 * c.logistic.y_max, big, -big, -1, std::nan(""),
                       std::numeric_limits<double>::infinity()};
  for (double y : ys)
    for (double sigma : {std::nan(""), 0.0, 1e-300, 1e300}) {
      const PressureEstimate e = c.invert(y, sigma);
      const std::string at = what + ", y " + std::to_string(y) + ", sigma " + std::to_string(sigma);
      switch (e.status) {
        case PressureStatus::ok:
          EXPECT_TRUE(std::isfinite(e.pressure_kpa) && e.pressure_kpa >= 0) << at << ": " << e.pressure_kpa;
          EXPECT_FALSE(std::isnan(e.sigma_kpa)) << at;
          break;
        case PressureStatus::saturated:
        case PressureStatus::below_detection:
          EXPECT_TRUE(std::isfinite(e.bound_kpa) && e.bound_kpa >= 0) << at << ": bound " << e.bound_kpa;
          break;
        case PressureStatus::invalid: EXPECT_FALSE(std::isfinite(y)) << at; break;
      }
    }
}

}  // namespace

TEST(NumericalLimits, NoiseFreePressesGiveTheTruthAndFiniteUncertainty) {
  // Exactly logistic signals: zero residuals, so the robust scale (a median of
  // absolute residuals) is zero. The fit must still return the truth.
  std::mt19937_64 rng(1605);
  const LogisticParams truth{0.05, 12, 3};
  for (PressureModelKind kind : {PressureModelKind::logistic, PressureModelKind::linear})
    for (RobustLoss loss : {RobustLoss::none, RobustLoss::huber, RobustLoss::tukey}) {
      PressureFitOptions o = options();
      o.model = kind;
      o.loss = loss;
      const std::string what = std::string(to_string(kind)) + ", " + to_string(loss);
      PressureFitResult r;
      ASSERT_NO_THROW(r = fit_pressure_calibration(presses_of(truth, levels(30, 10, 3), 0, rng), o)) << what;
      expect_finite(r, what);
      EXPECT_NEAR(r.logistic.y_max, truth.y_max, 1e-6 * truth.y_max) << what;
      EXPECT_NEAR(r.logistic.p50_kpa, truth.p50_kpa, 1e-5) << what;
      EXPECT_NEAR(r.logistic.width_kpa, truth.width_kpa, 1e-5) << what;
      expect_sane_inversions(r.calibration, what);
    }
}

TEST(NumericalLimits, ZeroForceAndDegeneratePressesAreRefusedNamingTheCause) {
  std::mt19937_64 rng(1606);
  const LogisticParams truth{0.05, 12, 3};
  auto refused = [&](const std::vector<CalibrationPress>& presses, const std::string& expected) {
    try {
      const PressureFitResult r = fit_pressure_calibration(presses, options());
      ADD_FAILURE() << "accepted; expected: " << expected << "; y_max " << r.logistic.y_max << ", p50 "
                    << r.logistic.p50_kpa << ", w " << r.logistic.width_kpa << ", linear slope " << r.linear.slope_per_kpa
                    << " +- " << r.linear.se_slope << ", r2 " << r.r2_logistic << ", warnings "
                    << ::testing::PrintToString(r.warnings);
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("presses.csv"), std::string::npos) << m;
      EXPECT_NE(m.find(expected), std::string::npos) << m;
    }
  };
  // Every press at zero force.
  refused(presses_of(truth, std::vector<double>(12, 0.0), 0, rng), "1 distinct pressure level");
  // Zero force and one other level.
  refused(presses_of(truth, {0, 0, 0, 20, 20, 20}, 0.001, rng), "2 distinct pressure level");
  // A flat signal (nothing blanches), exactly and with noise.
  for (double noise : {0.0, 1e-3}) {
    auto flat = presses_of(truth, levels(30, 8, 3), noise, rng);
    for (CalibrationPress& c : flat) c.signal = 0.02 + (noise > 0 ? c.signal - logistic_signal(truth, c.mean_pressure_kpa) : 0);
    refused(flat, noise > 0 ? "does not rise with pressure beyond its noise" : "is the same");
  }
  // A falling signal.
  auto falling = presses_of(truth, levels(30, 8, 3), 0.001, rng);
  for (CalibrationPress& c : falling) c.signal = -c.signal;
  refused(falling, "does not rise with pressure");
  // All signals zero.
  auto zero = presses_of(truth, levels(30, 8, 3), 0, rng);
  for (CalibrationPress& c : zero) c.signal = 0;
  refused(zero, "is the same (0) at every press");
}

TEST(NumericalLimits, ZeroForcePressesAmongOthersAreUsed) {
  // Rest presses (0 N, signal 0 plus noise) are part of the protocol.
  std::mt19937_64 rng(1607);
  const LogisticParams truth{0.05, 12, 3};
  std::vector<double> p = levels(30, 9, 3);
  for (int k = 0; k < 6; ++k) p.push_back(0);
  const PressureFitResult r = fit_pressure_calibration(presses_of(truth, p, 0.001, rng), options());
  expect_finite(r, "zero-force presses");
  EXPECT_NEAR(r.logistic.p50_kpa, truth.p50_kpa, 1.0);
  expect_sane_inversions(r.calibration, "zero-force presses");
}

TEST(NumericalLimits, PressuresAndSignalsOfAnyMagnitudeGiveTheScaledFit) {
  // The same presses with pressures in Pa or MPa by mistake (×1e-3 .. ×1e3
  // and beyond) and signals from 1e-9 to 1e3: the fit scales with them, or
  // refuses with the real cause (too few levels when a level gap falls below
  // the 0.5 kPa that tells levels apart).
  std::mt19937_64 rng(1608);
  const LogisticParams truth{0.05, 12, 3};
  for (double ps : {1e-6, 1e-3, 1.0, 1e3, 1e6})
    for (double ys : {1e-9, 1e-3, 1.0, 1e3}) {
      const LogisticParams scaled{truth.y_max * ys, truth.p50_kpa * ps, truth.width_kpa * ps};
      const auto presses = presses_of(scaled, levels(30 * ps, 10, 3), 1e-3 * truth.y_max * ys, rng);
      const std::string what = "pressure x" + std::to_string(ps) + ", signal x" + std::to_string(ys);
      try {
        const PressureFitResult r = fit_pressure_calibration(presses, options());
        expect_finite(r, what);
        EXPECT_NEAR(r.logistic.p50_kpa / ps, truth.p50_kpa, 0.5) << what;
        EXPECT_NEAR(r.logistic.y_max / ys, truth.y_max, 0.005) << what;
        expect_sane_inversions(r.calibration, what);
      } catch (const InputError& e) {
        EXPECT_LT(30 * ps / 9, 0.5) << what << ": refused although its levels are " << 30 * ps / 9
                                    << " kPa apart: " << e.what();
      }
    }
}

TEST(NumericalLimits, LogisticAtExtremePressuresIsFinite) {
  const LogisticParams m{0.05, 12, 3};
  for (double p : {0.0, 1e-300, 1e-9, 1e3, 1e9, 1e300, std::numeric_limits<double>::max()}) {
    EXPECT_TRUE(std::isfinite(logistic_signal(m, p))) << p;
    EXPECT_TRUE(logistic_gradient(m, p).allFinite()) << p << ": " << logistic_gradient(m, p).transpose();
  }
  // Very narrow and very wide logistics.
  for (double w : {1e-12, 1e-3, 1e3, 1e12}) {
    const LogisticParams n{0.05, 12, w};
    for (double p : {0.0, 11.0, 12.0, 13.0, 1e6}) {
      EXPECT_TRUE(std::isfinite(logistic_signal(n, p))) << "w " << w << ", p " << p;
      EXPECT_TRUE(logistic_gradient(n, p).allFinite()) << "w " << w << ", p " << p;
    }
  }
}
