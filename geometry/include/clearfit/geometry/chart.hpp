#pragma once
// A 2D metric chart of the contact surface: texel coordinates in mm, what skin
// images are resampled onto and the heatmap's UVs.
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/mesh.hpp>

namespace clearfit {

enum class ChartMethod {
  automatic,   ///< planar projection when the surface is flat (within tolerance), else lscm
  planar,      ///< exact orthogonal projection onto the best-fit plane (flat surfaces only)
  lscm,        ///< CGAL least-squares conformal map, scaled to preserve area
  arap         ///< CGAL as-rigid-as-possible
};
std::string_view to_string(ChartMethod method);

struct ChartOptions {
  ChartMethod method = ChartMethod::automatic;
  double planar_tolerance_mm = 1e-6;  ///< max distance from the plane to call it flat
  double component_gap_mm = 2.0;      ///< lscm/arap: space between pieces laid side by side
  /// Throws std::invalid_argument naming the field if a value is negative or not finite.
  void validate() const;
};

struct Chart {
  ChartMethod method = ChartMethod::automatic;  ///< the one used
  /// Chart coordinates (mm) per mesh vertex; NaN for vertices not on the contact surface.
  std::vector<Vec2> uv;
  std::vector<int> faces;            ///< contact faces covered
  int components = 0;                ///< edge-connected pieces (charted separately by lscm/arap)
  Vec2 uv_min = Vec2::Zero(), uv_max = Vec2::Zero();
  /// Distortion against the 3D surface, per face then summarised:
  /// area ratio (2D/3D) and angle error (deg).
  double area_ratio_min = 1, area_ratio_max = 1;
  double angle_error_mean_deg = 0, angle_error_max_deg = 0;
  /// For planar charts: part frame = origin + u * axis_u + v * axis_v.
  Vec3 origin = Vec3::Zero(), axis_u = Vec3::UnitX(), axis_v = Vec3::UnitY();
  std::vector<std::string> notes;
};

/// Charts the contact faces. Planar: exact orthogonal projection onto the
/// least-squares plane of the contact vertices (axis_u the main in-plane PCA
/// axis, or the coordinate axis most parallel to the plane when the spread is
/// isotropic; its largest component positive; normal facing like the contact
/// faces; axis_v = normal × axis_u). lscm/arap: CGAL per edge-connected piece,
/// each scaled so its 2D area equals its 3D area, rotated so its main axis is
/// u, laid side by side along u with component_gap_mm between them. In both,
/// faces stay counter-clockwise seen from outside the part (the skin side) and
/// uv_min = (0, 0). Throws InputError when the surface cannot be charted: not
/// flat for planar (or flat but folded over); for lscm/arap a piece that is not
/// a topological disk (checked here: CGAL reports success on closed meshes),
/// non-manifold, inconsistently oriented, or pieces touching at a vertex.
Chart compute_chart(const Mesh& mesh, const ContactSurface& contact, const ChartOptions& options = {});

}  // namespace clearfit
