#pragma once
// Vertex normals for smooth shading, split at creases.
#include <clearfit/geometry/mesh.hpp>

namespace clearfit {

struct NormalOptions {
  /// Faces meeting at a dihedral angle above this do not share a normal.
  double crease_angle_deg = 60.0;
  enum class Weighting { angle, area } weighting = Weighting::angle;
  /// Throws std::invalid_argument naming the field if a value is out of range.
  void validate() const;
};

/// One unit normal per face corner: corner[f][k] is the shading normal at
/// vertex faces[f][k] as seen from face f. It is the weighted mean of the unit
/// normals of the faces around that vertex that are reachable from f without
/// crossing a crease (dihedral angle > crease_angle_deg) or a boundary, so the
/// outer surface, the contact surface and the side walls each keep their own.
/// A degenerate face (zero area to rounding: its cross product within the
/// error of computing it) takes one neighbour's normal across an edge, or
/// zero if it has none; it never joins the faces on its two sides, so a
/// zero-area triangle along a crease does not smooth the crease away.
struct CornerNormals {
  std::vector<std::array<Vec3, 3>> corner;
  /// Interpolates the unit shading normal inside face f at barycentrics
  /// (b0, b1, b2) for corners (0, 1, 2).
  Vec3 interpolate(int face, double b0, double b1, double b2) const;
};

CornerNormals compute_corner_normals(const Mesh& mesh, const NormalOptions& options = {});

}  // namespace clearfit
