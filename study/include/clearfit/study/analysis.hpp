#pragma once
// The seed study's analyses (PAPER.md, "Analysis pipeline" and "Simulation and
// regression"): radial profiles of the colour change through a bump centre,
// per-participant regressions of colour change on pressure, and partial least
// squares of a 1D colour profile on subsurface stress by depth with VIP.
#include <clearfit/fit/chart_field.hpp>

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace clearfit::study {

/// Radial profile of a field on a 2-D grid (the chart, or the part's x–y plane:
/// see plane_field): segments of `length_mm` through `centre` every `angle_step_deg`
/// (0 ≤ angle < 180°, so each segment is a full diameter), sampled every
/// `sample_mm` by bilinear interpolation over the defined texels, then averaged
/// over the segments at each position (undefined samples left out). The study:
/// 14 mm segments every 20°.
struct ProfileOptions {
  double length_mm = 14.0;
  double angle_step_deg = 20.0;
  double sample_mm = 0.05;
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

struct RadialProfile {
  std::vector<double> position_mm;  ///< −length/2 … +length/2
  std::vector<double> value;        ///< mean over the segments; NaN where no segment is defined
  std::vector<int> segments;        ///< segments defined at each position
  Vec2 centre_mm = Vec2::Zero();  ///< in the grid's coordinates
};

RadialProfile radial_profile(const ChartField& field, const Vec2& centre_mm, const ProfileOptions& options = {});

/// A chart field seen along the part frame's z axis (the study's plates lie in
/// x–y; the camera looks down z): the mean of the defined texels whose part
/// point (`points`: x, y, z per texel of the field's grid, NaN outside) falls
/// in each `cell_mm` cell of an x–y grid; NaN where none does. Radial profiles
/// and contact discs are then in millimetres of the part, whatever the chart's
/// distortion (an LSCM chart of a bump's face, wall and plate stretches the wall).
ChartField plane_field(const ChartField& field, const std::vector<Vec3>& points, double cell_mm);

/// Averages profiles sampled at the same positions (NaN-aware, weighted by
/// their segment counts). Throws std::invalid_argument when the positions differ.
RadialProfile average_profiles(const std::vector<RadialProfile>& profiles);

/// Centre of a blanching region when none is given: the value-weighted centroid
/// of the texels above half the field's maximum (the 99.5th percentile, so one
/// hot texel does not decide), in the 8-connected region holding that maximum.
/// None when the field has no positive values.
std::optional<Vec2> find_profile_centre(const ChartField& field);

/// Ordinary least squares y = a + b x with the t-test of b ≠ 0 (two-sided,
/// n − 2 degrees of freedom; Student's t from Boost.Math), as in the study.
struct LinearRegression {
  int n = 0;
  double intercept = 0, slope = 0, slope_se = 0, r2 = 0;
  double t = 0, p_value = 1;
};
/// Throws std::invalid_argument for fewer than 3 points, different lengths,
/// non-finite values or all x equal.
LinearRegression linear_regression(const std::vector<double>& x, const std::vector<double>& y);

/// Partial least squares regression of one response on collinear predictors
/// (PLS1, NIPALS, with predictors and response centred and scaled to unit
/// variance as scikit-learn's PLSRegression(scale=True) does).
struct PlsResult {
  int components = 0;
  Eigen::MatrixXd x_weights;    ///< p × A (unit columns; sign: largest |w| positive, as scikit-learn)
  Eigen::MatrixXd x_loadings;   ///< p × A
  Eigen::MatrixXd x_scores;     ///< n × A
  Eigen::VectorXd y_loadings;   ///< A
  Eigen::VectorXd coef;         ///< p: y ≈ y_mean + Σ coef_j (x_j − x_mean_j) (original units)
  double intercept = 0;
  Eigen::VectorXd x_mean, x_std;
  double y_mean = 0, y_std = 1;
  double r2 = 0;                ///< of the fitted values
  Eigen::VectorXd vip;          ///< variable importance in projection per predictor
  Eigen::VectorXd predict(const Eigen::MatrixXd& x) const;
};
/// Throws std::invalid_argument when components < 1 or > min(n − 1, p), the
/// sizes differ, a value is not finite or the response is constant. Constant
/// predictors are kept with unit scale (as scikit-learn does).
PlsResult pls_regression(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, int components);

}  // namespace clearfit::study
