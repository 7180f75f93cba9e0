#pragma once
// Reading part meshes: STL (ASCII, binary), OBJ (with g/o groups), PLY, OFF,
// 3MF and glTF/GLB. Every importer hands back triangles in the file's order.
#include <clearfit/geometry/mesh.hpp>
#include <filesystem>
#include <optional>
#include <string_view>

namespace clearfit {

enum class LengthUnit { micrometre, millimetre, centimetre, metre, inch, foot };

/// "um", "mm", "cm", "m", "in"/"inch", "ft"/"foot" (and the long names); nullopt otherwise.
std::optional<LengthUnit> parse_length_unit(std::string_view text);
std::string_view to_string(LengthUnit unit);
/// Millimetres in one unit.
double millimetres_per(LengthUnit unit);

struct ImportOptions {
  /// Unit of the numbers in STL/OBJ/PLY/OFF files (which carry none); default mm.
  /// 3MF and glTF carry their own unit (glTF: metres); an explicit unit here
  /// overrides it with a note.
  std::optional<LengthUnit> units;
};

/// Reads a mesh, converts it to millimetres, checks it (finite coordinates,
/// indices in range, at least one face).
/// Faces come in the file's order with their corners in the file's order;
/// Mesh::file_face is the identity. Polygons with more than 3 vertices
/// (OBJ/PLY/OFF) are fan-triangulated in place (v0,vk,vk+1) with a note, so
/// face numbers count those triangles in file order. Triangles that repeat a
/// vertex are kept in place (noted). STL corners at exactly equal positions are
/// merged into one vertex (noted). Groups: OBJ g/o names, 3MF object names,
/// glTF node (else mesh) names; face_group/groups stay empty for STL/PLY/OFF.
/// 3MF: build items and components are placed by their transforms; glTF: the
/// default scene's node transforms are applied. Precision: STL binary, PLY,
/// OFF, 3MF and OBJ (tinyobjloader's float build) carry single precision.
/// Throws InputError naming the file and the element (line, vertex, face,
/// accessor, object) on any bad input.
Mesh load_mesh(const std::filesystem::path& path, const ImportOptions& options = {});

/// Writes a mesh in the format of the extension (.stl binary, .obj with `g`
/// groups, .ply binary, .off, .3mf in millimetres with one object per run of
/// faces in the same group), keeping the face order, atomically (temporary file
/// beside it, then rename). Used by tests and samples. Coordinates are written
/// in single precision except OBJ (shortest exact decimal). A face that repeats
/// a vertex or is non-manifold gets its own vertex copies in STL/PLY/OFF/3MF.
/// Throws InputError if it cannot write, std::logic_error if the mesh is inconsistent.
void save_mesh(const Mesh& mesh, const std::filesystem::path& path);

}  // namespace clearfit
