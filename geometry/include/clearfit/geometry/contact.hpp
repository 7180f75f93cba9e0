#pragma once
// The contact surface: the faces of the part that the skin touches.
#include <clearfit/geometry/mesh.hpp>
#include <filesystem>
#include <optional>

namespace clearfit {

/// Exactly one way of choosing the contact faces must be set.
struct ContactSelector {
  std::optional<std::string> group;                 ///< OBJ g/o, 3MF object, glTF mesh/node name
  std::optional<std::filesystem::path> face_file;   ///< 0-based file face indices, whitespace separated
  std::optional<Vec3> normal;                       ///< part frame; faces whose outward normal is
  double angle_deg = 30.0;                          ///< within this angle of `normal`
  bool empty() const { return !group && !face_file && !normal; }
};

struct ContactSurface {
  std::vector<int> faces;          ///< mesh face indices (ascending)
  std::vector<char> is_contact;    ///< per mesh face
  double area_mm2 = 0;
  int components = 0;              ///< edge-connected pieces
  std::vector<int> component;      ///< per mesh face: its piece (0..components-1), -1 if not contact
  std::vector<double> component_area_mm2;
  std::string chosen_by;           ///< "group 'skin'", "faces from f.txt", "normal cone ..."
};

/// Throws InputError if the selector names a group that does not exist, a face
/// file is malformed (names file, line, token) or indices are out of range, or
/// the selection is empty.
ContactSurface select_contact(const Mesh& mesh, const ContactSelector& selector);
/// Builds the summary from a per-face flag (area, components).
ContactSurface make_contact_surface(const Mesh& mesh, std::vector<char> is_contact,
                                    std::string chosen_by);

}  // namespace clearfit
