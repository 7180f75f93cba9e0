#include <clearfit/refraction/optics.hpp>

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace clearfit::optics {

void Indices::validate() const {
  const std::pair<const char*, double> fields[] = {
      {"n_medium", n_medium}, {"n_part", n_part}, {"n_skin", n_skin}};
  for (const auto& [name, value] : fields) {
    if (!(std::isfinite(value) && value >= 1.0)) {
      std::ostringstream s;
      s << "clearfit::optics::Indices: " << name << " = " << value
        << " must be a finite refractive index >= 1";
      throw std::invalid_argument(s.str());
    }
  }
}

void check_indices(const char* where, double eta_i, double eta_t) {
  if (eta_i > 0 && eta_t > 0 && std::isfinite(eta_i) && std::isfinite(eta_t)) return;
  std::ostringstream s;
  s << where << ": indices eta_i = " << eta_i << ", eta_t = " << eta_t
    << " must be finite and > 0";
  throw std::invalid_argument(s.str());
}

FresnelTerms fresnel(const Transmission& t, double eta_i, double eta_t) {
  check_indices("clearfit::optics::fresnel", eta_i, eta_t);
  FresnelTerms f;
  if (t.tir) {
    f.R_s = f.R_p = f.R = 1.0;
    f.T = 0.0;
    f.tir = true;
    return f;
  }
  if (eta_i == eta_t) return f;  // no interface; avoids 0/0 at grazing incidence
  const double ci = t.cos_i, ct = t.cos_t;
  // Amplitude coefficients; a denominator is 0 only for ci = ct = 0, which
  // needs eta_i == eta_t (handled above).
  const double r_s = (eta_i * ci - eta_t * ct) / (eta_i * ci + eta_t * ct);
  const double r_p = (eta_t * ci - eta_i * ct) / (eta_t * ci + eta_i * ct);
  f.R_s = r_s * r_s;
  f.R_p = r_p * r_p;
  f.R = 0.5 * (f.R_s + f.R_p);
  f.T = 1.0 - f.R;
  return f;
}

FresnelTerms fresnel(double cos_i, double eta_i, double eta_t) {
  check_indices("clearfit::optics::fresnel", eta_i, eta_t);
  double c = std::abs(cos_i);
  if (!(c <= 1.0 + 1e-9)) {
    std::ostringstream s;
    s << "clearfit::optics::fresnel: cos_i = " << cos_i << " is not a cosine";
    throw std::invalid_argument(s.str());
  }
  c = std::min(c, 1.0);
  const double eta = eta_i / eta_t;
  // sin²θ_i as (1 − c)(1 + c): no cancellation near normal incidence.
  const double cos2_t = 1.0 - eta * eta * ((1.0 - c) * (1.0 + c));
  Transmission t;
  t.cos_i = c;
  if (cos2_t < 0) {
    t.tir = true;
  } else {
    t.cos_t = std::sqrt(cos2_t);
  }
  return fresnel(t, eta_i, eta_t);
}

std::optional<double> critical_angle(double eta_i, double eta_t) {
  check_indices("clearfit::optics::critical_angle", eta_i, eta_t);
  if (eta_i <= eta_t) return std::nullopt;
  return std::asin(eta_t / eta_i);
}

double optical_path(std::span<const Vec3> points, std::span<const double> eta) {
  if (points.empty() || eta.size() + 1 != points.size()) {
    std::ostringstream s;
    s << "clearfit::optics::optical_path: " << points.size() << " points need "
      << (points.empty() ? 0 : points.size() - 1) << " indices, got " << eta.size();
    throw std::invalid_argument(s.str());
  }
  double length = 0;
  for (std::size_t k = 0; k < eta.size(); ++k) length += optical_path(points[k], points[k + 1], eta[k]);
  return length;
}

}  // namespace clearfit::optics
