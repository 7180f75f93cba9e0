#pragma once
// What is wrong with a mesh, and the safe repairs (CGAL Polygon_mesh_processing).
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <optional>

namespace clearfit {

struct ValidationOptions {
  double sliver_min_angle_deg = 1.0;   ///< a face with a smaller interior angle is a sliver
  double degenerate_area_mm2 = 1e-12;  ///< relative to bbox diagonal² below this: degenerate
  bool check_self_intersections = true;
  void validate() const;               ///< throws std::invalid_argument naming the field
};

struct ValidationReport {
  int vertices = 0, faces = 0;
  bool closed = false;                 ///< no boundary edges
  int boundary_loops = 0;
  bool consistently_oriented = false;  ///< every interior edge used once each way
  std::optional<bool> outward;         ///< closed meshes only: normals point out
  std::vector<int> degenerate_faces;   ///< file face indices
  std::vector<int> sliver_faces;       ///< file face indices
  std::vector<std::array<int, 2>> duplicate_faces;   ///< pairs of file face indices
  int non_manifold_edges = 0;          ///< edges with more than two faces
  int non_manifold_vertices = 0;       ///< vertices whose faces form more than one fan
  std::vector<std::array<int, 2>> self_intersections;  ///< pairs of file face indices (first 100)
  int self_intersection_count = 0;     ///< all intersecting pairs found
  bool self_intersections_checked = false;
  int components = 0;
  Vec3 bbox_min = Vec3::Zero(), bbox_max = Vec3::Zero();
  double area_mm2 = 0;
  std::optional<double> volume_mm3;    ///< closed meshes only
  /// Thickness between contact surface and the rest (outer surface), where both
  /// exist: distance along the inward normal from contact face centroids.
  std::optional<double> thickness_min_mm, thickness_max_mm;
  std::vector<std::string> warnings;   ///< plain words
  /// Nothing a user must fix: closed, consistently oriented, outward, no
  /// degenerate or duplicate faces, manifold, no self-intersections (if checked).
  /// Slivers and several components only warn.
  bool ok() const;
};

/// Checks everything; never throws on a bad mesh (it reports), only on bad
/// options (std::invalid_argument) or contact flags that do not match the mesh.
/// Topology (boundary loops, orientation, non-manifold edges and fans,
/// components) is computed on the raw triangle list, so any soup works; faces
/// with a repeated vertex are reported as degenerate and left out of it.
/// Self-intersections use exact predicates (CGAL) on all non-degenerate face
/// pairs, ignoring faces that only share a vertex or edge. `outward` uses CGAL
/// orient_to_bound_a_volume (a cavity's normals point into the cavity); the
/// volume is computed as if oriented outward. Thickness: from each contact
/// face centroid along the inward normal (open meshes: the stored orientation
/// is taken as outward) to the first non-contact face (CGAL AABB tree).
ValidationReport validate_mesh(const Mesh& mesh, const ContactSurface* contact = nullptr,
                               const ValidationOptions& options = {});

struct RepairOptions {
  bool drop_degenerate = true;
  bool orient_outward = true;          ///< closed meshes: make normals point out
  bool orient_consistently = true;     ///< open meshes: one orientation per component
};

/// Safe repairs in place, in this order: drop degenerate faces (as
/// validate_mesh with default options finds them); make each edge-connected
/// piece consistently oriented (keeping the orientation of the larger area);
/// for closed manifold meshes reverse the pieces that face inward. Returns one
/// plain sentence per change, naming counts and the first file face indices
/// ("dropped 2 degenerate faces ...: file faces 17, 40"), plus one for a step it
/// could not do; empty if nothing changed. Keeps Mesh::file_face and
/// face_group in step, so face indices still name the file's triangles.
std::vector<std::string> repair_mesh(Mesh& mesh, const RepairOptions& options = {});

}  // namespace clearfit
