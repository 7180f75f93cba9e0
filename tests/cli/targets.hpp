#pragma once
// Issue 13's targets measured against the simulator's truth, shared by the end-to-end tests:
// the pressure a fitted logistic predicts from the true signal, and the measured hotspot
// nearest a true one.
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>

namespace clearfit::cli_test {

/// RMSE (kPa) of the pressure the fitted logistic (`fitted`: calibration.json's "parameters") predicts
/// from the signal the true person (`truth`: y_max, p50_kpa, width_kpa) gives at 5–60 kPa in 0.25 kPa
/// steps, leaving out signals above 95 % of the fitted y_max (where the fit calls them saturated).
/// `count` receives how many pressures were compared.
inline double predicted_pressure_rmse_kpa(const nlohmann::json& truth, const nlohmann::json& fitted, int& count) {
  const double y_max = fitted.at("y_max"), p50 = fitted.at("p50_kpa"), w = fitted.at("width_kpa");
  const double t_ymax = truth.at("y_max"), t_p50 = truth.at("p50_kpa"), t_w = truth.at("width_kpa");
  auto sig = [](double z) { return 1 / (1 + std::exp(-z)); };
  auto truth_y = [&](double p) { return t_ymax * (sig((p - t_p50) / t_w) - sig(-t_p50 / t_w)) / (1 - sig(-t_p50 / t_w)); };
  double se = 0;
  count = 0;
  for (double p = 5; p <= 60; p += 0.25) {
    const double y = truth_y(p);
    if (y > 0.95 * y_max) continue;
    const double s0 = sig(-p50 / w), s = y / y_max * (1 - s0) + s0;
    const double predicted = p50 + w * std::log(s / (1 - s));
    se += (predicted - p) * (predicted - p), ++count;
  }
  return count ? std::sqrt(se / count) : std::numeric_limits<double>::quiet_NaN();
}

struct NearestHotspot {
  double distance_mm = std::numeric_limits<double>::infinity();  ///< centre of pressure to the true centroid
  double peak_kpa = std::numeric_limits<double>::quiet_NaN();
};

/// The hotspot of report.json (`report`, at `threshold_kpa`) whose centre of pressure is nearest the true
/// hotspot `truth_hotspot` (truth.json's "hotspots" element, part frame).
inline NearestHotspot nearest_hotspot(const nlohmann::json& report, const nlohmann::json& truth_hotspot, double threshold_kpa = 4.3) {
  const auto& tc = truth_hotspot.at("centroid_part_mm");
  const Eigen::Vector3d c(tc[0], tc[1], tc[2]);
  NearestHotspot best;
  for (const auto& h : report.at("hotspots")) {
    if (h.at("threshold_kpa").get<double>() != threshold_kpa) continue;
    const auto& mc = h.at("centre_of_pressure_mm");
    const double d = (Eigen::Vector3d(mc[0], mc[1], mc[2]) - c).norm();
    if (d < best.distance_mm) best = {d, h.at("peak_kpa").get<double>()};
  }
  return best;
}

}  // namespace clearfit::cli_test
