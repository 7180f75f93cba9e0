// The study's analyses against closed forms and against scikit-learn / SciPy
// (tests/tools/pls_reference.py through /usr/bin/python3; the test fails when
// they are missing: scripts/bootstrap.sh installs python3-sklearn).
#include <clearfit/study/analysis.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace clearfit::study {
namespace {

ChartField gaussian_field(const Vec2& centre, double sigma_mm, double texel = 0.05, int size = 400) {
  ChartField f;
  f.grid.width = f.grid.height = size;
  f.grid.texel_mm = texel;
  f.grid.uv_origin = Vec2(-size * texel / 2, -size * texel / 2);
  f.value.resize(f.grid.size());
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i)
      f.value[f.grid.index(i, j)] = float(std::exp(-(f.grid.uv(i, j) - centre).squaredNorm() / (2 * sigma_mm * sigma_mm)));
  return f;
}

TEST(RadialProfile, OfARadialFieldIsItsRadialFunction) {
  const Vec2 c(0.37, -0.81);
  const ChartField f = gaussian_field(c, 1.5);
  const RadialProfile p = radial_profile(f, c);
  ASSERT_EQ(p.position_mm.size(), 281u);  // ±7 mm every 0.05 mm
  EXPECT_NEAR(p.position_mm.front(), -7.0, 1e-12);
  for (std::size_t k = 0; k < p.position_mm.size(); ++k) {
    const double r = std::abs(p.position_mm[k]);
    // Bilinear interpolation's bound: h²/8 · (|f_uu| + |f_vv|) ≤ 0.05²/8 · 2/σ² = 2.8e-4.
    EXPECT_NEAR(p.value[k], std::exp(-r * r / (2 * 1.5 * 1.5)), 2.8e-4) << "at s = " << p.position_mm[k];
    EXPECT_EQ(p.segments[k], 9);  // 0, 20, ..., 160 degrees
  }
}

TEST(RadialProfile, LeavesUndefinedTexelsOutAndCountsSegments) {
  ChartField f = gaussian_field(Vec2::Zero(), 1.0);
  for (int j = 0; j < f.grid.height; ++j)  // the half plane u > 2 mm is unseen
    for (int i = 0; i < f.grid.width; ++i)
      if (f.grid.uv(i, j).x() > 2.0) f.value[f.grid.index(i, j)] = NAN;
  const RadialProfile p = radial_profile(f, Vec2::Zero());
  // At s = +5 mm the segments at 0..20 deg (cos θ · 5 > 2.05 ⇒ θ < 65.8°: 0, 20, 40, 60) reach u > 2: 5 left.
  const std::size_t k = 240;  // s = +5
  ASSERT_NEAR(p.position_mm[k], 5.0, 1e-12);
  EXPECT_EQ(p.segments[k], 5);
  EXPECT_NEAR(p.value[k], std::exp(-12.5), 1e-5);
  EXPECT_EQ(p.segments[140], 9);  // s = 0
}

TEST(RadialProfile, FindsTheCentreOfABlanchedDisc) {
  const Vec2 c(1.234, -0.567);
  const auto found = find_profile_centre(gaussian_field(c, 0.8));
  ASSERT_TRUE(found);
  EXPECT_LT((*found - c).norm(), 0.01);
  ChartField flat = gaussian_field(c, 0.8);
  for (float& v : flat.value) v = -v;
  EXPECT_FALSE(find_profile_centre(flat));
}

TEST(RadialProfile, AverageWeightsBySegments) {
  const ChartField f = gaussian_field(Vec2::Zero(), 1.0);
  RadialProfile a = radial_profile(f, Vec2::Zero()), b = a;
  for (double& v : b.value) v += 1.0;
  for (int& s : b.segments) s = 3;
  const RadialProfile m = average_profiles({a, b});
  EXPECT_NEAR(m.value[140], (9 * a.value[140] + 3 * (a.value[140] + 1)) / 12, 1e-12);
  b.position_mm.pop_back();
  EXPECT_THROW(average_profiles({a, b}), std::invalid_argument);
}

TEST(PlaneField, IdentityChartAndAWallSeenEdgeOn) {
  ChartField f = gaussian_field(Vec2::Zero(), 1.0, 0.05, 40);
  std::vector<Vec3> points(f.grid.size());
  for (int j = 0; j < f.grid.height; ++j)
    for (int i = 0; i < f.grid.width; ++i) points[f.grid.index(i, j)] = Vec3(f.grid.uv(i, j).x(), f.grid.uv(i, j).y(), 0);
  const ChartField same = plane_field(f, points, 0.05);
  for (int j = 0; j < f.grid.height; ++j)
    for (int i = 0; i < f.grid.width; ++i) EXPECT_NEAR(same.sample(f.grid.uv(i, j)), f.value[f.grid.index(i, j)], 1e-6);
  // Fold row j = 39 onto row 38 (a wall: two heights over one x-y cell): their values are averaged.
  for (int i = 0; i < f.grid.width; ++i) points[f.grid.index(i, 39)] = points[f.grid.index(i, 38)] + Vec3(0, 0, -1);
  const ChartField folded = plane_field(f, points, 0.05);
  EXPECT_NEAR(folded.sample(f.grid.uv(7, 38)), 0.5 * (f.value[f.grid.index(7, 38)] + f.value[f.grid.index(7, 39)]), 1e-6);
  points[0] = Vec3(NAN, NAN, NAN);
  EXPECT_TRUE(std::isnan(plane_field(f, points, 0.05).value[0]));
  EXPECT_THROW(plane_field(f, std::vector<Vec3>(3), 0.05), std::invalid_argument);
}

TEST(LinearRegression, ExactLineAndBadInput) {
  const LinearRegression r = linear_regression({1, 2, 3, 4}, {3, 5, 7, 9});
  EXPECT_NEAR(r.slope, 2, 1e-12);
  EXPECT_NEAR(r.intercept, 1, 1e-12);
  EXPECT_NEAR(r.r2, 1, 1e-12);
  EXPECT_EQ(r.p_value, 0);
  EXPECT_THROW(linear_regression({1, 2}, {1, 2}), std::invalid_argument);
  EXPECT_THROW(linear_regression({1, 1, 1}, {1, 2, 3}), std::invalid_argument);
  EXPECT_THROW(linear_regression({1, NAN, 3}, {1, 2, 3}), std::invalid_argument);
}

/// Stress-by-depth-like predictors: smooth, highly collinear columns.
void collinear_data(Eigen::MatrixXd& x, Eigen::VectorXd& y, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  const int n = 40, p = 20;
  x.resize(n, p);
  y.resize(n);
  for (int i = 0; i < n; ++i) {
    const double a = 1 + 0.5 * noise(rng), b = 0.3 * noise(rng);
    for (int j = 0; j < p; ++j) {
      const double depth = 0.1 * j;
      x(i, j) = a * std::exp(-depth / 0.4) + b * depth + 0.01 * noise(rng);
    }
    y[i] = 2.0 * x(i, 1) + 0.5 * x(i, 2) - 0.3 * x(i, 15) + 0.05 * noise(rng);
  }
}

nlohmann::json reference(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, int components) {
  const auto dir = std::filesystem::temp_directory_path() / ("clearfit_pls_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream out(dir / "data.csv");
    out.precision(17);
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
      for (Eigen::Index j = 0; j < x.cols(); ++j) out << x(i, j) << ",";
      out << y[i] << "\n";
    }
  }
  const std::string cmd = "/usr/bin/python3 " + std::string(CLEARFIT_TOOLS_DIR) + "/pls_reference.py " +
                          (dir / "data.csv").string() + " " + std::to_string(components) + " > " + (dir / "ref.json").string();
  const int rc = std::system(cmd.c_str());
  std::ifstream in(dir / "ref.json");
  nlohmann::json j;
  if (rc == 0) j = nlohmann::json::parse(in);
  std::filesystem::remove_all(dir);
  if (rc != 0) ADD_FAILURE() << "the reference (scikit-learn, SciPy) could not run: install python3-sklearn (scripts/bootstrap.sh does)";
  return j;
}

TEST(PlsRegression, MatchesScikitLearnOnCollinearPredictors) {
  Eigen::MatrixXd x;
  Eigen::VectorXd y;
  collinear_data(x, y, 20261125);
  for (int components : {1, 2, 3}) {
    const PlsResult r = pls_regression(x, y, components);
    const nlohmann::json ref = reference(x, y, components);
    if (ref.is_null()) return;
    const Eigen::VectorXd pred = r.predict(x);
    for (Eigen::Index i = 0; i < x.rows(); ++i) EXPECT_NEAR(pred[i], ref["predict"][i].get<double>(), 1e-8) << i;
    for (int a = 0; a < components; ++a)
      for (Eigen::Index j = 0; j < x.cols(); ++j)
        EXPECT_NEAR(r.x_weights(j, a), ref["x_weights"][a][j].get<double>(), 1e-8) << "component " << a << ", " << j;
    for (Eigen::Index j = 0; j < x.cols(); ++j) EXPECT_NEAR(r.vip[j], ref["vip"][j].get<double>(), 1e-8) << j;
    EXPECT_NEAR(r.r2, ref["r2"].get<double>(), 1e-10);
    EXPECT_NEAR(r.vip.squaredNorm(), double(x.cols()), 1e-8);  // Σ VIP² = p by construction
  }
}

TEST(LinearRegression, MatchesSciPyLinregress) {
  Eigen::MatrixXd x;
  Eigen::VectorXd y;
  collinear_data(x, y, 7);
  const nlohmann::json ref = reference(x, y, 1);
  if (ref.is_null()) return;
  const std::vector<double> xs(x.col(0).data(), x.col(0).data() + x.rows()), ys(y.data(), y.data() + y.size());
  const LinearRegression r = linear_regression(xs, ys);
  const auto& l = ref["linregress"];
  EXPECT_NEAR(r.slope, l["slope"].get<double>(), 1e-10);
  EXPECT_NEAR(r.intercept, l["intercept"].get<double>(), 1e-10);
  EXPECT_NEAR(r.r2, l["r2"].get<double>(), 1e-12);
  EXPECT_NEAR(r.slope_se, l["slope_se"].get<double>(), 1e-10);
  EXPECT_NEAR(r.p_value, l["p"].get<double>(), 1e-9 + 1e-6 * l["p"].get<double>());
}

TEST(PlsRegression, RefusesWhatItCannotFit) {
  Eigen::MatrixXd x;
  Eigen::VectorXd y;
  collinear_data(x, y, 3);
  EXPECT_THROW(pls_regression(x, y, 0), std::invalid_argument);
  EXPECT_THROW(pls_regression(x, y, 21), std::invalid_argument);
  EXPECT_THROW(pls_regression(x, Eigen::VectorXd::Constant(x.rows(), 2.0), 1), std::invalid_argument);
  EXPECT_THROW(pls_regression(x, y.head(10), 1), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit::study
