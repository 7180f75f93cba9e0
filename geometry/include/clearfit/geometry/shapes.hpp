#pragma once
// Analytic test parts: closed, outward-oriented triangle meshes with named
// groups ("outer", "contact", "side"), for tests, benchmarks and samples.
#include <clearfit/geometry/mesh.hpp>

namespace clearfit::shapes {

/// Axis-aligned box centred at the origin; `n` subdivisions per edge.
/// Groups: "bottom" (z = -size.z/2) ... one per side: "xmin","xmax","ymin","ymax","bottom","top".
Mesh box(const Vec3& size, int n = 1);

/// Sphere of `radius` centred at the origin: subdivided icosahedron with vertices
/// on the sphere (20·4^subdivisions faces). One group "sphere".
Mesh icosphere(double radius, int subdivisions);

/// Flat plate: x in [-sx/2, sx/2], y in [-sy/2, sy/2], z in [0, thickness].
/// Groups: "contact" (z = 0, faces -z, the skin side), "outer" (z = thickness,
/// faces +z, the camera side), "side". Convention for all shapes: the camera
/// is on +z looking down, the skin below the contact surface. `n` quads per edge on the big faces.
Mesh slab(double sx, double sy, double thickness, int n = 1);

/// Segment of a cylindrical shell about the y axis (a wristband): inner radius
/// r_in, outer radius r_out, spanning `span_deg` around the +z axis
/// (symmetric: the middle of the band is at (0, 0, r)), width w along y
/// (y in [-w/2, w/2]). A camera on +z looking down sees the wrist through it. Groups: "contact" (inner surface, the skin
/// side), "outer" (outer surface), "side" (ends and edges).
/// span_deg = 360 gives a closed tube (no end caps).
Mesh cylindrical_shell(double r_in, double r_out, double span_deg, double width,
                       int n_around, int n_width);

/// Spherical cap shell (a dome) about the +z axis, centred at the origin: the inner sphere r_in is
/// the skin side ("contact"), the outer sphere r_out faces the camera
/// ("outer"), the rim is "side". Cap half-angle `cap_deg` (< 90), `n_rings`
/// rings and `n_around` segments.
Mesh spherical_shell(double r_in, double r_out, double cap_deg, int n_rings, int n_around);

/// Freeform plate (a bump field): x in [-sx/2, sx/2], y in [-sy/2, sy/2], flat
/// bottom z = 0 ("contact", faces -z), top ("outer") the height field
/// z = thickness + sum_k a_k exp(-|(x, y) - c_k|^2 / (2 s_k^2)) with `bumps`
/// Gaussian bumps drawn from std::mt19937(seed): centres c_k uniform over the
/// plate, heights a_k uniform in [0.4, 1] * bump_height (bump_height >= 0; all
/// bumps rise, so the plate is at least `thickness` thick), widths s_k uniform
/// in [0.08, 0.16] * min(sx, sy). Walls "side". `n` quads per edge on the big
/// faces (4n^2 + 8n triangles). Same seed, same plate.
Mesh bump_plate(double sx, double sy, double thickness, int n, int bumps, double bump_height, unsigned seed);

/// Random freeform parts nobody tuned on (benchmarks and tests of the
/// refraction map). Over x in [-sx/2, sx/2], y in [-sy/2, sy/2] (sx = 40 mm,
/// sy uniform in [25, 40] mm), the contact surface ("contact", the skin side,
/// facing down) is z = h(x, y) and the outer surface ("outer", facing the
/// camera on +z) lies t(x, y) above it; "side" walls close the part. Both are
/// drawn from std::mt19937(seed) (same seed, same part):
/// - height_field: h is a sum of 6 random plane waves (wavelengths uniform in
///   [0.4, 1.2]·sx, random directions and phases, amplitudes uniform in
///   [0.3, 1]·0.5 mm), the outer surface is h + t straight above;
/// - shell: h is a random quadric k1·x²/2 + k2·y²/2 (|k| uniform in
///   [1/80, 1/25] per mm, each sign random: domes, bowls and saddles; rotated
///   by a random angle) plus waves as above at a fifth of the amplitude, the
///   outer surface offset by t along the contact surface's unit normal.
/// t = 2.5 mm · (1 + 0.25·w) with w a normalised random wave sum in [-1, 1].
/// `n` quads per edge on the big faces (4n² + 8n triangles).
enum class Freeform { height_field, shell };
Mesh random_freeform(Freeform kind, unsigned seed, int n);
const char* to_string(Freeform kind);  ///< "height_field", "shell"

}  // namespace clearfit::shapes
