#pragma once
// The triangle mesh every module works on: the part's CAD surface in the part
// frame, lengths in millimetres.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

namespace clearfit {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

/// A triangle mesh as read from a file.
/// Faces are counter-clockwise seen from outside the part (the right-hand
/// normal points out of the material) once the mesh is oriented.
/// `faces[i]` is triangle `file_face[i]` of the input file: face indices that
/// users and tools name always refer to the file's triangle order, also after
/// repairs drop faces.
struct Mesh {
  std::vector<Vec3> vertices;              ///< part frame, mm
  std::vector<std::array<int, 3>> faces;   ///< vertex indices
  std::vector<int> file_face;              ///< input-file triangle index of each face
  std::vector<int> face_group;             ///< group of each face (-1: none); empty if the file has no groups
  std::vector<std::string> groups;         ///< group / object names (OBJ g/o, 3MF object, glTF mesh or node)
  std::string source;                      ///< the file it came from
  std::string source_units = "mm";         ///< the unit the file's numbers were in
  std::vector<std::string> import_notes;   ///< what the importer had to do (merged vertices, ...)

  int num_vertices() const { return static_cast<int>(vertices.size()); }
  int num_faces() const { return static_cast<int>(faces.size()); }

  const Vec3& corner(int face, int k) const { return vertices[faces[face][k]]; }
  /// Right-hand (unnormalised) face normal; its length is twice the area.
  Vec3 face_cross(int face) const {
    return (corner(face, 1) - corner(face, 0)).cross(corner(face, 2) - corner(face, 0));
  }
  /// Unit normal (zero vector for a degenerate face).
  Vec3 face_normal(int face) const {
    Vec3 n = face_cross(face);
    double len = n.norm();
    return len > 0 ? Vec3(n / len) : Vec3::Zero();
  }
  double face_area(int face) const { return 0.5 * face_cross(face).norm(); }
  /// Index of the face whose file index is `file_index`, or -1.
  int face_from_file_index(int file_index) const;
  /// Throws std::logic_error if the arrays disagree (sizes, indices in range).
  void check_consistent() const;
};

/// Axis-aligned bounds of the vertices (min, max); zeros for an empty mesh.
std::pair<Vec3, Vec3> bounding_box(const Mesh& mesh);
/// Total area (mm²).
double surface_area(const Mesh& mesh);
/// Signed volume by the divergence theorem (mm³); positive for a closed,
/// outward-oriented mesh. Meaningless for an open mesh.
double signed_volume(const Mesh& mesh);

}  // namespace clearfit
