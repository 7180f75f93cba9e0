#pragma once
// Private to geometry: a face's unit normal where its sign is known (normals.cpp, ray_index.cpp).
#include <clearfit/geometry/mesh.hpp>

#include <algorithm>
#include <limits>

namespace clearfit::detail {

/// Unit normal of face f, or zero when the face is degenerate to rounding: its
/// cross product no larger than the error of computing it (a few ulp of the
/// largest coordinate times the longest edge). A vertex computed on an edge in
/// floating point leaves such a "zero-area" triangle whose normal would
/// otherwise be a unit vector of either sign, with an interior angle of up to π
/// to weigh it by.
inline Vec3 reliable_normal(const Mesh& m, int f) {
  const Vec3 cross = m.face_cross(f);
  double coord = 0, edge = 0;
  for (int k = 0; k < 3; ++k) {
    coord = std::max(coord, m.corner(f, k).cwiseAbs().maxCoeff());
    edge = std::max(edge, (m.corner(f, (k + 1) % 3) - m.corner(f, k)).norm());
  }
  const double len = cross.norm();
  return len > 64 * std::numeric_limits<double>::epsilon() * coord * edge ? Vec3(cross / len) : Vec3::Zero();
}

}  // namespace clearfit::detail
