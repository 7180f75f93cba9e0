#include <clearfit/study/analysis.hpp>
#include <clearfit/format.hpp>
#include <clearfit/study/fingertip_fe.hpp>

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace clearfit::study {
namespace {

/// The profile's value at |s| = r: the mean of both sides where defined (linear interpolation).
double folded(const RadialProfile& p, double r) {
  double sum = 0;
  int n = 0;
  for (double s : {-r, r}) {
    for (std::size_t k = 0; k + 1 < p.position_mm.size(); ++k) {
      if (s < p.position_mm[k] - 1e-9 || s > p.position_mm[k + 1] + 1e-9) continue;
      const double t = (s - p.position_mm[k]) / (p.position_mm[k + 1] - p.position_mm[k]);
      const double v = (1 - t) * p.value[k] + t * p.value[k + 1];
      if (std::isfinite(v)) sum += v, ++n;
      break;
    }
    if (r == 0) break;
  }
  return n > 0 ? sum / n : NAN;
}

}  // namespace

std::string StressPls::important_depths() const {
  std::string out;
  for (std::size_t k = 0; k < vip.size();) {
    if (!(vip[k] > 1)) {
      ++k;
      continue;
    }
    std::size_t e = k;
    while (e + 1 < vip.size() && vip[e + 1] > 1) ++e;
    out +=
        (out.empty() ? "" : ", ") + fixed_digits(depth_mm[k], 2) + "–" + fixed_digits(depth_mm[e], 2) + " mm";
    k = e + 1;
  }
  return out;
}

StressPls stress_profile_pls(const RadialProfile& colour, const PunchStress& stress, int components) {
  std::vector<std::size_t> rows;
  std::vector<double> y;
  for (std::size_t i = 0; i < stress.r_mm.size(); ++i) {
    const double v = folded(colour, stress.r_mm[i]);
    if (std::isfinite(v)) rows.push_back(i), y.push_back(v);
  }
  if (static_cast<int>(rows.size()) < components + 2)
    throw std::invalid_argument("stress_profile_pls: the colour profile is defined at " + std::to_string(rows.size()) +
                                " radii of the stress grid, fewer than components + 2");
  Eigen::MatrixXd x(rows.size(), stress.depth_mm.size());
  for (std::size_t n = 0; n < rows.size(); ++n)
    for (std::size_t k = 0; k < stress.depth_mm.size(); ++k) x(n, k) = stress.vm(k, rows[n]);
  const PlsResult pls = pls_regression(x, Eigen::Map<const Eigen::VectorXd>(y.data(), y.size()), components);
  StressPls s;
  s.components = components;
  s.samples = static_cast<int>(rows.size());
  s.r2 = pls.r2;
  s.depth_mm = stress.depth_mm;
  s.vip.assign(pls.vip.data(), pls.vip.data() + pls.vip.size());
  return s;
}

}  // namespace clearfit::study
