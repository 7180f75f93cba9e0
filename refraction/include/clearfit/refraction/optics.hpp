#pragma once
// Optics primitives for tracing camera rays through the printed part: vector
// Snell's law, reflection, Fresnel transmittance of unpolarised light, the
// critical angle and optical path lengths (pbrt-v4 style: small maths inline).
//
// Conventions (docs/conventions.md): a direction is a unit vector along which
// light (or the traced camera ray) propagates. The normal `n` given to
// refract()/transmit() points to the side the ray comes FROM (d·n < 0);
// eta_i is the index on that side, eta_t the index on the other side. Angles
// are measured from the normal, in radians.
#include <clearfit/geometry/mesh.hpp>  // Vec3

#include <cmath>
#include <optional>
#include <span>

namespace clearfit::optics {

/// Refractive indices of the three media a camera ray meets (dimensionless).
struct Indices {
  double n_medium = 1.0;  ///< camera side: air 1.0, water 1.333, immersion oil ~1.5
  double n_part = 1.49;   ///< printed part (acrylic 1.49; clear resins 1.49–1.55)
  double n_skin = 1.4;    ///< beyond the contact surface (skin ~1.4; 1.0 for an air gap)
  /// Throws std::invalid_argument naming the field unless every index is finite and >= 1.
  void validate() const;
};

/// Throws std::invalid_argument (naming `where`) unless both indices are finite and > 0.
void check_indices(const char* where, double eta_i, double eta_t);

/// Outcome of Snell's law at one interface.
struct Transmission {
  bool tir = false;              ///< total internal reflection: no transmitted ray
  Vec3 direction = Vec3::Zero(); ///< unit transmitted direction (zero when tir)
  double cos_i = 0;              ///< cosine of the angle of incidence, >= 0
  double cos_t = 0;              ///< cosine of the angle of transmission, >= 0 (0 when tir)
};

/// Vector Snell's law with the cosines kept for Fresnel.
/// d: unit incident direction; n: unit surface normal on the incident side
/// (d·n < 0). If d·n > 0 the normal is flipped, so either orientation of a
/// surface normal works; eta_i is always the index of the side d comes from.
/// Method: t = η·d_tan − cosθ_t·n with η = eta_i/eta_t and d_tan = d + cosθ_i·n
/// (the tangential part of d). sin²θ_i is |d_tan|² rather than 1 − cos²θ_i, so
/// near-normal rays keep full relative precision; the result is unit to
/// rounding (|t|² = sin²θ_t + cos²θ_t) and exactly coplanar with d and n.
/// TIR decision: cos²θ_t = 1 − η²|d_tan|² is compared with 0, deliberately
/// without clamping. Its rounding error is a few ulp of 1, so the decision is
/// right for every ray more than ~1e-15 rad from the critical angle; a ray at
/// exactly cos²θ_t = 0 is transmitted along the surface (cos_t = 0), one
/// beyond is reflected. No NaN is produced for any unit d, n (grazing
/// d·n = 0 included). Throws std::invalid_argument for indices <= 0 or NaN.
inline Transmission transmit(const Vec3& d, const Vec3& n, double eta_i, double eta_t) {
  if (!(eta_i > 0 && eta_t > 0 && std::isfinite(eta_i) && std::isfinite(eta_t)))
    check_indices("clearfit::optics::transmit", eta_i, eta_t);
  double cos_i = -d.dot(n);
  const Vec3 n_in = cos_i < 0 ? Vec3(-n) : n;
  cos_i = std::abs(cos_i);
  const double eta = eta_i / eta_t;
  const Vec3 d_tan = d + cos_i * n_in;
  const double cos2_t = 1.0 - eta * eta * d_tan.squaredNorm();
  Transmission out;
  out.cos_i = cos_i;
  if (cos2_t < 0) {
    out.tir = true;
    return out;
  }
  out.cos_t = std::sqrt(cos2_t);
  out.direction = eta * d_tan - out.cos_t * n_in;
  return out;
}

/// Unit refracted direction for unit incident direction d at a surface with
/// unit normal n (either orientation, see transmit()), going from index eta_i
/// into eta_t; std::nullopt on total internal reflection.
inline std::optional<Vec3> refract(const Vec3& d, const Vec3& n, double eta_i, double eta_t) {
  Transmission t = transmit(d, n, eta_i, eta_t);
  if (t.tir) return std::nullopt;
  return t.direction;
}

/// Mirror reflection of direction d at a surface with unit normal n (either orientation).
inline Vec3 reflect(const Vec3& d, const Vec3& n) { return d - 2.0 * d.dot(n) * n; }

/// Angle between two non-zero vectors in [0, π] (radians), via atan2(|a×b|, a·b):
/// accurate near 0 and π where acos is not.
inline double angle_between(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

/// Fresnel reflectances and transmittance of an interface for unpolarised light
/// (fractions of power, dimensionless).
struct FresnelTerms {
  double R_s = 0;    ///< reflectance, s (TE) polarisation
  double R_p = 0;    ///< reflectance, p (TM) polarisation
  double R = 0;      ///< unpolarised reflectance (R_s + R_p)/2
  double T = 1;      ///< transmittance 1 − R
  bool tir = false;  ///< total internal reflection (then R_s = R_p = R = 1, T = 0)
};

/// Fresnel equations for light meeting an interface from index eta_i into eta_t
/// at an angle whose cosine is cos_i (its sign is ignored: the side is given by
/// eta_i; |cos_i| is clamped to 1 against rounding). Dielectrics, no absorption.
/// Equal indices give R = 0 exactly, also at grazing incidence. At or beyond
/// the critical angle R = 1. Throws std::invalid_argument for bad indices or
/// |cos_i| > 1 + 1e-9 or NaN.
FresnelTerms fresnel(double cos_i, double eta_i, double eta_t);

/// Fresnel terms from both cosines (as returned by transmit()), without
/// recomputing Snell's law. A Transmission with tir gives R = 1.
FresnelTerms fresnel(const Transmission& t, double eta_i, double eta_t);

/// Critical angle (radians) for light going from eta_i into eta_t:
/// asin(eta_t/eta_i); std::nullopt when eta_i <= eta_t (no total internal reflection).
std::optional<double> critical_angle(double eta_i, double eta_t);

/// Optical path length eta·|b − a| of a straight segment (mm when a, b are in mm).
inline double optical_path(const Vec3& a, const Vec3& b, double eta) { return eta * (b - a).norm(); }

/// Optical path length of a polyline: Σ eta[k]·|points[k+1] − points[k]|.
/// Throws std::invalid_argument unless eta.size() + 1 == points.size() (an
/// empty polyline of one point has length 0).
double optical_path(std::span<const Vec3> points, std::span<const double> eta);

}  // namespace clearfit::optics
