#pragma once
// Exact closed-form traces of one camera ray into the analytic test parts of
// geometry/shapes.hpp, in the same part frame (mm), independent of any mesh:
// references for the mesh trace and the slab fast path.
//
// Model: the ray starts at `origin` in the camera-side medium (n_medium),
// enters the part through its outer surface (refracts, Fresnel at entry),
// runs straight through the part (n_part) and meets the contact surface; the
// skin point is that intersection (skin in optical contact). At the contact the
// angle of incidence and the part→skin Fresnel transmittance are reported; a
// ray beyond the part→skin critical angle there is totally reflected: the
// pixel sees a reflection, not the skin (Reason::contact_tir, not valid).
// Frames follow shapes.hpp: camera on +z looking down (−z), contact surface
// below the outer one.
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/refraction/optics.hpp>

#include <limits>
#include <optional>

namespace clearfit::analytic {

/// Why a trace has no usable skin point.
enum class Reason {
  ok,              ///< skin point found and seen
  miss,            ///< the ray does not enter through the outer surface (passes by, or
                   ///< would first hit a side/rim face or a part of the surface the shape lacks)
  tir,             ///< total internal reflection at entry (needs n_medium > n_part)
  exit_elsewhere,  ///< the refracted ray leaves the part before reaching the contact surface
  contact_tir,     ///< reaches the contact surface beyond the part→skin critical angle
};
/// "ok", "miss", "tir", "exit_elsewhere", "contact_tir".
const char* to_string(Reason reason);

/// One traced ray. Fields not reached by the trace are NaN.
struct SkinHit {
  static constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  bool valid = false;                   ///< reason == ok
  Reason reason = Reason::miss;
  Vec3 entry_point = Vec3::Constant(nan);    ///< on the outer surface, mm
  Vec3 entry_normal = Vec3::Constant(nan);   ///< unit outward normal of the part there
  double incidence_rad = nan;                ///< angle between −dir and entry_normal
  double refraction_rad = nan;               ///< angle between refracted_dir and −entry_normal
  Vec3 refracted_dir = Vec3::Constant(nan);  ///< unit direction inside the part
  Vec3 skin_point = Vec3::Constant(nan);     ///< on the contact surface, mm
  Vec3 contact_normal = Vec3::Constant(nan); ///< unit outward normal of the part there (into the skin)
  double contact_rad = nan;             ///< angle between refracted_dir and contact_normal
  double exit_rad = nan;                ///< angle of the ray continued into the skin (NaN on contact TIR)
  double entry_transmittance = nan;     ///< Fresnel T, medium → part (unpolarised power fraction)
  double contact_transmittance = nan;   ///< Fresnel T, part → skin (0 on contact TIR)
  double transmittance = nan;           ///< product of both
  double optical_path_mm = nan;         ///< n_medium·|entry − origin| + n_part·|skin − entry|
};

/// Flat slab (shapes::slab, unbounded in x and y): contact plane z = 0, outer
/// plane z = thickness, normal +z. `dir` need not be unit (it is normalised;
/// zero/NaN throws). Throws std::invalid_argument unless origin.z > thickness
/// > 0 and the indices are valid. Rays with dir.z >= 0 miss.
SkinHit trace_slab(const Vec3& origin, const Vec3& dir, double thickness,
                   const optics::Indices& n = {});

/// Closed form of the slab for a ray at angle of incidence theta_i.
struct SlabShift {
  double theta_t_rad;  ///< refraction angle, asin(n_medium·sinθ_i / n_part)
  double lateral_mm;   ///< perpendicular distance of the skin point from the undeviated
                       ///< ray: thickness·sin(θ_i − θ_t)/cosθ_t (the textbook shift)
  double offset_mm;    ///< in-plane distance on z = 0 from the undeviated ray's hit back
                       ///< towards the entry point: thickness·(tanθ_i − tanθ_t)
};
/// Slab shift for theta_i in [0, π/2) (radians); std::nullopt on TIR at entry
/// (n_medium·sinθ_i > n_part). Throws std::invalid_argument for thickness <= 0,
/// theta_i outside [0, π/2) or bad indices.
std::optional<SlabShift> slab_shift(double thickness, double theta_i_rad, double n_medium,
                                    double n_part);

/// Wedge (a prism for the TIR boundary): outer plane z = thickness (normal +z)
/// and a contact plane through the origin tilted by tilt_rad about the y axis,
/// {p : sin(tilt)·p.x − cos(tilt)·p.z = 0}, outward normal (sin tilt, 0, −cos tilt);
/// the part lies between them (unbounded otherwise). tilt 0 is the slab.
/// Entry points where the outer plane has no part below it (beyond the ridge
/// where the planes meet) miss. Throws std::invalid_argument unless
/// origin.z > thickness > 0 and |tilt_rad| < π/2.
SkinHit trace_wedge(const Vec3& origin, const Vec3& dir, double thickness, double tilt_rad,
                    const optics::Indices& n = {});

/// Where the wedge's image crosses the part→skin critical angle. A ray in the
/// xz plane with dir = (sinθ, 0, −cosθ) (θ signed, radians, towards +x) reaches
/// the skin for theta_neg < θ < theta_pos and is totally reflected at the
/// contact beyond either bound (or, once |θ_t − tilt| >= 90°, never reach it:
/// exit_elsewhere); θ_t = tilt ± θ_c at the bounds, sinθ = n_part·sinθ_t/n_medium.
/// A bound is std::nullopt when no camera-side ray reaches it (or n_skin >= n_part).
/// A pinhole camera at (x0, 0, H) looking along −z (cam_from_part = diag(1, −1, −1))
/// with focal length f px and principal point cx sees the bound at column
/// u = cx + f·tanθ on the row through the principal point.
struct TirBounds {
  std::optional<double> theta_neg_rad, theta_pos_rad;
};
TirBounds wedge_contact_tir_angles(double tilt_rad, const optics::Indices& n = {});

/// Ball lens of `radius` centred at the origin (shapes::icosphere): enter the
/// sphere, refract, the skin point is where the refracted ray meets the sphere
/// again (the far side is the contact). Throws std::invalid_argument unless
/// |origin| > radius > 0.
SkinHit trace_ball(const Vec3& origin, const Vec3& dir, double radius,
                   const optics::Indices& n = {});

/// Spherical cap shell (shapes::spherical_shell): centred at the origin, cap
/// half-angle cap_deg about +z; enter the outer sphere r_out within the cap,
/// refract, the skin point is the first hit on the inner sphere r_in (contact,
/// normal towards the centre). Misses the inner sphere, or reaches it outside
/// the cap (through the rim) → exit_elsewhere. Throws std::invalid_argument
/// unless 0 < r_in < r_out < |origin| and 0 < cap_deg < 90.
SkinHit trace_spherical_shell(const Vec3& origin, const Vec3& dir, double r_in, double r_out,
                              double cap_deg, const optics::Indices& n = {});

/// Cylindrical shell about the y axis (shapes::cylindrical_shell, a wristband):
/// radii r_in (contact, normal towards the axis) and r_out (outer), the band
/// spanning span_deg symmetric about +z (angle atan2(x, z) within ±span/2;
/// 360 = closed tube), y in [−width/2, width/2]. Same rules as the spherical
/// shell; the in-part segment crossing an end of the band or an edge → exit_elsewhere.
/// Throws std::invalid_argument unless 0 < r_in < r_out < hypot(origin.x, origin.z),
/// 0 < span_deg <= 360 and width > 0.
SkinHit trace_cylindrical_shell(const Vec3& origin, const Vec3& dir, double r_in, double r_out,
                                double span_deg, double width, const optics::Indices& n = {});

}  // namespace clearfit::analytic
