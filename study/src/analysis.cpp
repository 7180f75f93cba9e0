#include <clearfit/study/analysis.hpp>

#include <Eigen/Dense>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>
#include <stdexcept>

namespace clearfit::study {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void require(bool ok, const std::string& field, double value, const std::string& rule) {
  if (!ok) throw std::invalid_argument(field + " = " + std::to_string(value) + ": " + rule);
}

}  // namespace

void ProfileOptions::validate() const {
  require(std::isfinite(length_mm) && length_mm > 0, "length_mm", length_mm, "must be positive");
  require(std::isfinite(angle_step_deg) && angle_step_deg > 0 && angle_step_deg <= 180, "angle_step_deg", angle_step_deg,
          "must be in (0, 180]");
  require(std::isfinite(sample_mm) && sample_mm > 0 && sample_mm <= length_mm / 2, "sample_mm", sample_mm,
          "must be positive and at most half the length");
}

RadialProfile radial_profile(const ChartField& field, const Vec2& centre_mm, const ProfileOptions& options) {
  options.validate();
  if (!centre_mm.allFinite()) throw std::invalid_argument("radial_profile: the centre is not finite");
  RadialProfile p;
  p.centre_mm = centre_mm;
  const int half = static_cast<int>(std::floor(options.length_mm / 2 / options.sample_mm + 1e-9));
  const int angles = static_cast<int>(std::ceil(180.0 / options.angle_step_deg - 1e-9));
  for (int k = -half; k <= half; ++k) {
    const double s = k * options.sample_mm;
    double sum = 0;
    int count = 0;
    for (int a = 0; a < angles; ++a) {
      const double theta = a * options.angle_step_deg * std::numbers::pi / 180.0;
      const float v = field.sample(centre_mm + s * Vec2(std::cos(theta), std::sin(theta)));
      if (std::isnan(v)) continue;
      sum += v;
      ++count;
    }
    p.position_mm.push_back(s);
    p.value.push_back(count > 0 ? sum / count : kNaN);
    p.segments.push_back(count);
  }
  return p;
}

ChartField plane_field(const ChartField& field, const std::vector<Vec3>& points, double cell_mm) {
  if (points.size() != field.grid.size()) throw std::invalid_argument("plane_field: one point per texel is needed");
  if (!(cell_mm > 0)) throw std::invalid_argument("plane_field: cell_mm must be positive");
  Vec2 lo(INFINITY, INFINITY), hi(-INFINITY, -INFINITY);
  for (std::size_t k = 0; k < points.size(); ++k)
    if (points[k].allFinite() && std::isfinite(field.value[k])) lo = lo.cwiseMin(points[k].head<2>()), hi = hi.cwiseMax(points[k].head<2>());
  ChartField plane;
  if (!(lo.x() <= hi.x())) return plane;
  plane.grid = ChartGrid::covering(lo, hi, cell_mm);
  std::vector<double> sum(plane.grid.size(), 0);
  std::vector<int> count(plane.grid.size(), 0);
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (!points[k].allFinite() || !std::isfinite(field.value[k])) continue;
    const Vec2 f = (points[k].head<2>() - plane.grid.uv_origin) / cell_mm;
    const int i = static_cast<int>(std::lround(f.x())), j = static_cast<int>(std::lround(f.y()));
    if (i < 0 || j < 0 || i >= plane.grid.width || j >= plane.grid.height) continue;
    sum[plane.grid.index(i, j)] += field.value[k];
    ++count[plane.grid.index(i, j)];
  }
  plane.value.resize(plane.grid.size());
  for (std::size_t k = 0; k < sum.size(); ++k) plane.value[k] = count[k] > 0 ? float(sum[k] / count[k]) : NAN;
  return plane;
}

RadialProfile average_profiles(const std::vector<RadialProfile>& profiles) {
  if (profiles.empty()) throw std::invalid_argument("average_profiles: no profiles");
  RadialProfile mean = profiles.front();
  for (std::size_t k = 0; k < mean.position_mm.size(); ++k) {
    double sum = 0;
    int count = 0;
    for (const RadialProfile& p : profiles) {
      if (p.position_mm.size() != mean.position_mm.size() ||
          std::abs(p.position_mm[k] - mean.position_mm[k]) > 1e-9)
        throw std::invalid_argument("average_profiles: profiles sampled at different positions");
      if (p.segments[k] == 0) continue;
      sum += p.value[k] * p.segments[k];
      count += p.segments[k];
    }
    mean.value[k] = count > 0 ? sum / count : kNaN;
    mean.segments[k] = count;
  }
  return mean;
}

std::optional<Vec2> find_profile_centre(const ChartField& field) {
  const ChartGrid& g = field.grid;
  std::vector<float> defined;
  for (float v : field.value)
    if (std::isfinite(v)) defined.push_back(v);
  if (defined.empty()) return std::nullopt;
  const std::size_t q = static_cast<std::size_t>(0.995 * (defined.size() - 1));
  std::nth_element(defined.begin(), defined.begin() + q, defined.end());
  const float top = defined[q];
  if (!(top > 0)) return std::nullopt;
  // Seed: the texel nearest the percentile value from above; grow the 8-connected region ≥ top / 2.
  std::size_t seed = g.size();
  for (std::size_t i = 0; i < g.size(); ++i)
    if (std::isfinite(field.value[i]) && field.value[i] >= top &&
        (seed == g.size() || field.value[i] < field.value[seed]))
      seed = i;
  std::vector<char> in(g.size(), 0);
  std::queue<std::size_t> open;
  open.push(seed);
  in[seed] = 1;
  double wsum = 0;
  Vec2 c = Vec2::Zero();
  while (!open.empty()) {
    const std::size_t k = open.front();
    open.pop();
    const int i = static_cast<int>(k % g.width), j = static_cast<int>(k / g.width);
    wsum += field.value[k];
    c += field.value[k] * g.uv(i, j);
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const int ni = i + di, nj = j + dj;
        if (ni < 0 || nj < 0 || ni >= g.width || nj >= g.height) continue;
        const std::size_t n = g.index(ni, nj);
        if (in[n] || !(field.value[n] >= top / 2)) continue;
        in[n] = 1;
        open.push(n);
      }
  }
  return c / wsum;
}

LinearRegression linear_regression(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) throw std::invalid_argument("linear_regression: x and y differ in length");
  if (x.size() < 3) throw std::invalid_argument("linear_regression: needs at least 3 points, got " + std::to_string(x.size()));
  const Eigen::Map<const Eigen::ArrayXd> xa(x.data(), x.size()), ya(y.data(), y.size());
  if (!xa.allFinite() || !ya.allFinite()) throw std::invalid_argument("linear_regression: a value is not finite");
  LinearRegression r;
  r.n = static_cast<int>(x.size());
  const double mx = xa.mean(), my = ya.mean();
  const double sxx = (xa - mx).square().sum(), sxy = ((xa - mx) * (ya - my)).sum(), syy = (ya - my).square().sum();
  if (!(sxx > 0)) throw std::invalid_argument("linear_regression: all x are equal");
  r.slope = sxy / sxx;
  r.intercept = my - r.slope * mx;
  const double sse = std::max(0.0, (ya - r.intercept - r.slope * xa).square().sum());
  r.r2 = syy > 0 ? 1 - sse / syy : 0;
  const int dof = r.n - 2;
  r.slope_se = std::sqrt(sse / dof / sxx);
  if (r.slope_se > 0) {
    r.t = r.slope / r.slope_se;
    const boost::math::students_t dist(dof);
    r.p_value = 2 * boost::math::cdf(boost::math::complement(dist, std::abs(r.t)));
  } else {
    r.t = r.slope == 0 ? 0 : std::copysign(std::numeric_limits<double>::infinity(), r.slope);
    r.p_value = r.slope == 0 ? 1 : 0;
  }
  return r;
}

Eigen::VectorXd PlsResult::predict(const Eigen::MatrixXd& x) const {
  return ((x.rowwise() - x_mean.transpose()) * coef).array() + y_mean;
}

PlsResult pls_regression(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, int components) {
  const Eigen::Index n = x.rows(), p = x.cols();
  if (y.size() != n) throw std::invalid_argument("pls_regression: x has " + std::to_string(n) + " rows, y " + std::to_string(y.size()));
  if (components < 1 || components > std::min<Eigen::Index>(n - 1, p))
    throw std::invalid_argument("pls_regression: components = " + std::to_string(components) +
                                " must be in [1, min(n - 1, p)] = [1, " + std::to_string(std::min<Eigen::Index>(n - 1, p)) + "]");
  if (!x.allFinite() || !y.allFinite()) throw std::invalid_argument("pls_regression: a value is not finite");
  PlsResult r;
  r.components = components;
  r.x_mean = x.colwise().mean();
  r.x_std = ((x.rowwise() - r.x_mean.transpose()).colwise().squaredNorm() / double(n - 1)).cwiseSqrt();
  for (Eigen::Index j = 0; j < p; ++j)
    if (r.x_std[j] == 0) r.x_std[j] = 1;
  r.y_mean = y.mean();
  r.y_std = std::sqrt((y.array() - r.y_mean).square().sum() / double(n - 1));
  if (!(r.y_std > 0)) throw std::invalid_argument("pls_regression: the response is constant");
  Eigen::MatrixXd xk = (x.rowwise() - r.x_mean.transpose()).array().rowwise() / r.x_std.transpose().array();
  Eigen::VectorXd yk = (y.array() - r.y_mean) / r.y_std;
  r.x_weights.resize(p, components);
  r.x_loadings.resize(p, components);
  r.x_scores.resize(n, components);
  r.y_loadings.resize(components);
  for (int a = 0; a < components; ++a) {
    Eigen::VectorXd w = xk.transpose() * yk;  // PLS1: the power method converges in one step
    const double norm = w.norm();
    if (!(norm > 0)) throw std::invalid_argument("pls_regression: component " + std::to_string(a + 1) + " explains nothing more");
    w /= norm;
    Eigen::Index big = 0;
    w.cwiseAbs().maxCoeff(&big);
    if (w[big] < 0) w = -w;
    const Eigen::VectorXd t = xk * w;
    const double tt = t.squaredNorm();
    const Eigen::VectorXd load = xk.transpose() * t / tt;
    const double q = yk.dot(t) / tt;
    xk -= t * load.transpose();
    yk -= q * t;
    r.x_weights.col(a) = w;
    r.x_loadings.col(a) = load;
    r.x_scores.col(a) = t;
    r.y_loadings[a] = q;
  }
  const Eigen::MatrixXd rotations =
      r.x_weights * (r.x_loadings.transpose() * r.x_weights).completeOrthogonalDecomposition().pseudoInverse();
  r.coef = (rotations * r.y_loadings).array() * r.y_std / r.x_std.array();
  r.intercept = r.y_mean - r.x_mean.dot(r.coef);
  const Eigen::VectorXd fitted = r.predict(x);
  r.r2 = 1 - (y - fitted).squaredNorm() / (y.array() - r.y_mean).square().sum();
  // VIP_j = sqrt(p Σ_a SS_a w_ja² / Σ_a SS_a), SS_a = q_a² t_aᵀt_a (unit-norm weights).
  Eigen::VectorXd ss(components);
  for (int a = 0; a < components; ++a) ss[a] = r.y_loadings[a] * r.y_loadings[a] * r.x_scores.col(a).squaredNorm();
  r.vip = (double(p) * (r.x_weights.array().square().matrix() * ss).array() / ss.sum()).sqrt();
  return r;
}

}  // namespace clearfit::study
