#include <clearfit/refraction/analytic.hpp>

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace clearfit::analytic {

const char* to_string(Reason reason) {
  switch (reason) {
    case Reason::ok: return "ok";
    case Reason::miss: return "miss";
    case Reason::tir: return "tir";
    case Reason::exit_elsewhere: return "exit_elsewhere";
    case Reason::contact_tir: return "contact_tir";
  }
  return "unknown";
}

namespace {

using optics::Indices;
constexpr double kDeg = std::numbers::pi / 180.0;

[[noreturn]] void fail(const char* fn, const std::string& what) {
  throw std::invalid_argument(std::string("clearfit::analytic::") + fn + ": " + what);
}

void require(bool ok, const char* fn, const char* name, double value, const char* rule) {
  if (ok) return;
  std::ostringstream s;
  s << name << " = " << value << " " << rule;
  fail(fn, s.str());
}

// Validates the common inputs and returns the unit direction.
Vec3 prepare(const char* fn, const Vec3& origin, const Vec3& dir, const Indices& n) {
  n.validate();
  if (!origin.allFinite()) fail(fn, "origin must be finite");
  const double len = dir.norm();
  if (!(len > 0) || !std::isfinite(len)) fail(fn, "direction must be finite and non-zero");
  return dir / len;
}

Vec3 in_xz(const Vec3& v) { return {v.x(), 0.0, v.z()}; }

// Parameters t of the line o + t·u meeting the sphere |x| = r (centre 0);
// pass o, u with y zeroed for the cylinder about y. Robust form: the closest
// approach is computed directly and the root with cancellation comes from the
// product of the roots (Vieta), so a nearly tangent or nearby hit keeps its
// precision.
struct Roots {
  double near, far;
};
std::optional<Roots> circle_roots(const Vec3& o, const Vec3& u, double r) {
  const double a = u.squaredNorm();
  if (!(a > 0)) return std::nullopt;
  const double tc = -o.dot(u) / a;
  const double dist = (o + tc * u).norm();
  const double h = (r - dist) * (r + dist);
  if (h < 0) return std::nullopt;
  const double s = std::sqrt(h / a);
  const double on = o.norm();
  const double product = (on - r) * (on + r) / a;
  Roots roots;
  if (tc >= 0) {
    roots.far = tc + s;
    roots.near = roots.far > 0 ? product / roots.far : 0.0;
  } else {
    roots.near = tc - s;
    roots.far = product / roots.near;
  }
  return roots;
}

// Refraction at the entry point; false (reason set) when the ray only grazes
// the surface (miss) or is totally reflected (tir).
bool enter(SkinHit& hit, const Vec3& d, const Vec3& entry, const Vec3& normal, const Indices& n) {
  if (d.dot(normal) > 0) return false;  // tangent within rounding: does not enter
  hit.entry_point = entry;
  hit.entry_normal = normal;
  hit.incidence_rad = optics::angle_between(-d, normal);
  const optics::Transmission tr = optics::transmit(d, normal, n.n_medium, n.n_part);
  if (tr.tir) {
    hit.reason = Reason::tir;
    return false;
  }
  hit.refracted_dir = tr.direction;
  hit.refraction_rad = optics::angle_between(tr.direction, -normal);
  hit.entry_transmittance = optics::fresnel(tr, n.n_medium, n.n_part).T;
  hit.reason = Reason::exit_elsewhere;  // until the contact is reached
  return true;
}

// Completes a hit whose refracted ray meets the contact surface at `skin`
// with outward (into the skin) normal `normal`.
SkinHit& reach_contact(SkinHit& hit, const Vec3& origin, const Vec3& skin, const Vec3& normal,
                       const Indices& n) {
  const Vec3& dt = hit.refracted_dir;
  if (!(dt.dot(normal) > 0)) return hit;  // only touches the contact surface
  hit.skin_point = skin;
  hit.contact_normal = normal;
  hit.contact_rad = optics::angle_between(dt, normal);
  hit.optical_path_mm = optics::optical_path(origin, hit.entry_point, n.n_medium) +
                        optics::optical_path(hit.entry_point, skin, n.n_part);
  const optics::Transmission tr = optics::transmit(dt, -normal, n.n_part, n.n_skin);
  hit.contact_transmittance = optics::fresnel(tr, n.n_part, n.n_skin).T;
  hit.transmittance = hit.entry_transmittance * hit.contact_transmittance;
  if (tr.tir) {
    hit.reason = Reason::contact_tir;
    return hit;
  }
  hit.exit_rad = optics::angle_between(tr.direction, normal);
  hit.reason = Reason::ok;
  hit.valid = true;
  return hit;
}

// Entry point of a ray on the plane z = h from above (nullopt if it does not go down).
std::optional<Vec3> enter_plane(const Vec3& origin, const Vec3& d, double h) {
  if (!(d.z() < 0)) return std::nullopt;
  Vec3 entry = origin + ((h - origin.z()) / d.z()) * d;
  entry.z() = h;
  return entry;
}

}  // namespace

SkinHit trace_slab(const Vec3& origin, const Vec3& dir, double thickness, const Indices& n) {
  const char* fn = "trace_slab";
  require(thickness > 0 && std::isfinite(thickness), fn, "thickness", thickness, "must be > 0");
  const Vec3 d = prepare(fn, origin, dir, n);
  require(origin.z() > thickness, fn, "origin.z", origin.z(), "must be above the outer plane");
  SkinHit hit;
  const auto entry = enter_plane(origin, d, thickness);
  if (!entry || !enter(hit, d, *entry, Vec3::UnitZ(), n)) return hit;
  const Vec3& dt = hit.refracted_dir;
  if (!(dt.z() < 0)) return hit;  // runs along the outer plane (cos θ_t = 0)
  Vec3 skin = *entry + (-thickness / dt.z()) * dt;
  skin.z() = 0.0;
  return reach_contact(hit, origin, skin, -Vec3::UnitZ(), n);
}

std::optional<SlabShift> slab_shift(double thickness, double theta_i_rad, double n_medium,
                                    double n_part) {
  const char* fn = "slab_shift";
  require(thickness > 0 && std::isfinite(thickness), fn, "thickness", thickness, "must be > 0");
  require(theta_i_rad >= 0 && theta_i_rad < std::numbers::pi / 2, fn, "theta_i_rad",
          theta_i_rad, "must be in [0, pi/2)");
  optics::check_indices("clearfit::analytic::slab_shift", n_medium, n_part);
  const double sin_t = n_medium * std::sin(theta_i_rad) / n_part;
  if (sin_t > 1.0) return std::nullopt;
  const double theta_t = std::asin(sin_t);
  return SlabShift{theta_t, thickness * std::sin(theta_i_rad - theta_t) / std::cos(theta_t),
                   thickness * (std::tan(theta_i_rad) - std::tan(theta_t))};
}

SkinHit trace_wedge(const Vec3& origin, const Vec3& dir, double thickness, double tilt_rad,
                    const Indices& n) {
  const char* fn = "trace_wedge";
  require(thickness > 0 && std::isfinite(thickness), fn, "thickness", thickness, "must be > 0");
  require(std::abs(tilt_rad) < std::numbers::pi / 2, fn, "tilt_rad", tilt_rad,
          "must be in (-pi/2, pi/2)");
  const Vec3 d = prepare(fn, origin, dir, n);
  require(origin.z() > thickness, fn, "origin.z", origin.z(), "must be above the outer plane");
  const Vec3 normal(std::sin(tilt_rad), 0.0, -std::cos(tilt_rad));
  SkinHit hit;
  const auto entry = enter_plane(origin, d, thickness);
  if (!entry || !(normal.dot(*entry) < 0)) return hit;  // no part below this entry point
  if (!enter(hit, d, *entry, Vec3::UnitZ(), n)) return hit;
  const Vec3& dt = hit.refracted_dir;
  const double approach = normal.dot(dt);
  if (!(dt.z() < 0) || !(approach > 0)) return hit;  // never reaches the contact plane
  const Vec3 skin = *entry + (-normal.dot(*entry) / approach) * dt;
  return reach_contact(hit, origin, skin, normal, n);
}

TirBounds wedge_contact_tir_angles(double tilt_rad, const Indices& n) {
  require(std::abs(tilt_rad) < std::numbers::pi / 2, "wedge_contact_tir_angles", "tilt_rad",
          tilt_rad, "must be in (-pi/2, pi/2)");
  n.validate();
  TirBounds bounds;
  const auto theta_c = optics::critical_angle(n.n_part, n.n_skin);
  if (!theta_c) return bounds;
  auto camera_angle = [&](double theta_t) -> std::optional<double> {
    if (std::abs(theta_t) >= std::numbers::pi / 2) return std::nullopt;
    const double s = n.n_part * std::sin(theta_t) / n.n_medium;
    if (std::abs(s) > 1.0) return std::nullopt;
    return std::asin(s);
  };
  bounds.theta_neg_rad = camera_angle(tilt_rad - *theta_c);
  bounds.theta_pos_rad = camera_angle(tilt_rad + *theta_c);
  return bounds;
}

SkinHit trace_ball(const Vec3& origin, const Vec3& dir, double radius, const Indices& n) {
  const char* fn = "trace_ball";
  require(radius > 0 && std::isfinite(radius), fn, "radius", radius, "must be > 0");
  const Vec3 d = prepare(fn, origin, dir, n);
  require(origin.norm() > radius, fn, "|origin|", origin.norm(), "must be outside the ball");
  SkinHit hit;
  const auto in = circle_roots(origin, d, radius);
  if (!in || !(in->near > 0)) return hit;
  const Vec3 entry = origin + in->near * d;
  if (!enter(hit, d, entry, entry.normalized(), n)) return hit;
  const auto out = circle_roots(entry, hit.refracted_dir, radius);
  if (!out || !(out->far > 0)) return hit;
  const Vec3 skin = entry + out->far * hit.refracted_dir;
  return reach_contact(hit, origin, skin, skin.normalized(), n);
}

SkinHit trace_spherical_shell(const Vec3& origin, const Vec3& dir, double r_in, double r_out,
                              double cap_deg, const Indices& n) {
  const char* fn = "trace_spherical_shell";
  require(r_in > 0 && std::isfinite(r_in), fn, "r_in", r_in, "must be > 0");
  require(r_out > r_in && std::isfinite(r_out), fn, "r_out", r_out, "must be > r_in");
  require(cap_deg > 0 && cap_deg < 90, fn, "cap_deg", cap_deg, "must be in (0, 90)");
  const Vec3 d = prepare(fn, origin, dir, n);
  require(origin.norm() > r_out, fn, "|origin|", origin.norm(), "must be outside r_out");
  const double cos_cap = std::cos(cap_deg * kDeg);
  auto in_cap = [&](const Vec3& p) { return p.z() >= cos_cap * p.norm(); };
  SkinHit hit;
  const auto in = circle_roots(origin, d, r_out);
  if (!in || !(in->near > 0)) return hit;
  const Vec3 entry = origin + in->near * d;
  if (!in_cap(entry) || !enter(hit, d, entry, entry.normalized(), n)) return hit;
  const auto inner = circle_roots(entry, hit.refracted_dir, r_in);
  if (!inner || !(inner->near > 0)) return hit;  // passes the inner sphere: leaves elsewhere
  const Vec3 skin = entry + inner->near * hit.refracted_dir;
  if (!in_cap(skin)) return hit;  // the cone is convex: the segment left through the rim
  return reach_contact(hit, origin, skin, -skin.normalized(), n);
}

SkinHit trace_cylindrical_shell(const Vec3& origin, const Vec3& dir, double r_in, double r_out,
                                double span_deg, double width, const Indices& n) {
  const char* fn = "trace_cylindrical_shell";
  require(r_in > 0 && std::isfinite(r_in), fn, "r_in", r_in, "must be > 0");
  require(r_out > r_in && std::isfinite(r_out), fn, "r_out", r_out, "must be > r_in");
  require(span_deg > 0 && span_deg <= 360, fn, "span_deg", span_deg, "must be in (0, 360]");
  require(width > 0 && std::isfinite(width), fn, "width", width, "must be > 0");
  const Vec3 d = prepare(fn, origin, dir, n);
  require(in_xz(origin).norm() > r_out, fn, "hypot(origin.x, origin.z)", in_xz(origin).norm(),
          "must be outside r_out");
  const bool closed = span_deg >= 360;
  const double half = 0.5 * span_deg * kDeg;
  auto in_band = [&](const Vec3& p) {
    return std::abs(p.y()) <= 0.5 * width &&
           (closed || std::abs(std::atan2(p.x(), p.z())) <= half);
  };
  // Does the segment a→b (both in the band) cross an end of the band? Needed
  // for spans over 180° where the band is not convex.
  auto crosses_end = [&](const Vec3& a, const Vec3& b) {
    if (closed) return false;
    const Vec3 e = in_xz(b - a);
    for (double phi : {-half, half}) {
      const Vec3 end(std::sin(phi), 0.0, std::cos(phi));
      const double denom = e.x() * end.z() - e.z() * end.x();
      if (denom == 0) continue;
      const double lambda = -(a.x() * end.z() - a.z() * end.x()) / denom;
      if (lambda > 0 && lambda < 1 && in_xz(a + lambda * (b - a)).dot(end) > 0) return true;
    }
    return false;
  };
  SkinHit hit;
  const auto in = circle_roots(in_xz(origin), in_xz(d), r_out);
  if (!in || !(in->near > 0)) return hit;
  const Vec3 entry = origin + in->near * d;
  if (!in_band(entry) || !enter(hit, d, entry, in_xz(entry).normalized(), n)) return hit;
  const Vec3& dt = hit.refracted_dir;
  const auto inner = circle_roots(in_xz(entry), in_xz(dt), r_in);
  if (!inner || !(inner->near > 0)) return hit;
  const Vec3 skin = entry + inner->near * dt;
  if (!in_band(skin) || crosses_end(entry, skin)) return hit;
  return reach_contact(hit, origin, skin, -in_xz(skin).normalized(), n);
}

}  // namespace clearfit::analytic
