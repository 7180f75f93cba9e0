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
/// indices in range, triangles only where the format needs it).
/// Throws InputError naming the file and the element on any bad input.
Mesh load_mesh(const std::filesystem::path& path, const ImportOptions& options = {});

/// Writes a mesh in the format of the extension (.stl .obj .ply .off .3mf), used by
/// tests and samples. Throws InputError if it cannot write.
void save_mesh(const Mesh& mesh, const std::filesystem::path& path);

}  // namespace clearfit
