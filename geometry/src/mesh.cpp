#include <clearfit/geometry/mesh.hpp>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace clearfit {

int Mesh::face_from_file_index(int file_index) const {
  // file_face is ascending after import and after repairs that only drop faces,
  // so a binary search finds it; fall back to a scan if someone reordered.
  auto it = std::lower_bound(file_face.begin(), file_face.end(), file_index);
  if (it != file_face.end() && *it == file_index) return static_cast<int>(it - file_face.begin());
  for (int i = 0; i < num_faces(); ++i)
    if (file_face[i] == file_index) return i;
  return -1;
}

void Mesh::check_consistent() const {
  auto fail = [](const std::string& what) { throw std::logic_error("Mesh::check_consistent: " + what); };
  if (file_face.size() != faces.size()) fail("file_face has " + std::to_string(file_face.size()) +
                                             " entries for " + std::to_string(faces.size()) + " faces");
  if (!face_group.empty() && face_group.size() != faces.size()) fail("face_group size differs from faces");
  for (int f = 0; f < num_faces(); ++f)
    for (int v : faces[f])
      if (v < 0 || v >= num_vertices()) fail("face " + std::to_string(f) + " has vertex " + std::to_string(v));
  for (int g : face_group)
    if (g < -1 || g >= static_cast<int>(groups.size())) fail("group index " + std::to_string(g));
}

std::pair<Vec3, Vec3> bounding_box(const Mesh& mesh) {
  if (mesh.vertices.empty()) return {Vec3::Zero(), Vec3::Zero()};
  Vec3 lo = mesh.vertices.front(), hi = lo;
  for (const Vec3& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  return {lo, hi};
}

double surface_area(const Mesh& mesh) {
  double a = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) a += mesh.face_area(f);
  return a;
}

double signed_volume(const Mesh& mesh) {
  // Sum of signed tetrahedra against the bounding-box centre (better
  // conditioned than against the origin for parts far from it).
  auto [lo, hi] = bounding_box(mesh);
  const Vec3 c = 0.5 * (lo + hi);
  double v = 0;
  for (int f = 0; f < mesh.num_faces(); ++f)
    v += (mesh.corner(f, 0) - c).dot((mesh.corner(f, 1) - c).cross(mesh.corner(f, 2) - c));
  return v / 6.0;
}

}  // namespace clearfit
