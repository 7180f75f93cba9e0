#pragma once
// Private to the import*.cpp files (and the import test): one reader per format
// fills a RawMesh in the file's own order and units; import.cpp checks it,
// triangulates polygons, converts to millimetres and builds the Mesh.
#include <clearfit/error.hpp>
#include <clearfit/geometry/import.hpp>
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <algorithm>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace clearfit::detail {

struct RawMesh {
  std::vector<Vec3> vertices;              ///< file units, file order
  std::vector<std::vector<int>> polygons;  ///< 0-based vertex indices, file order
  std::vector<int> polygon_group;          ///< empty, or a group index (-1: none) per polygon
  std::vector<std::string> groups;
  std::optional<LengthUnit> file_unit;     ///< the unit the file states (3MF, glTF)
  std::vector<std::string> notes;
  int index_base = 0;                      ///< how the format numbers vertices/faces in messages (OBJ: 1)

  /// Index of the group called `name`, added if new (one group per distinct name).
  int group_index(const std::string& name);
};

/// The path as shown in messages.
std::string display(const std::filesystem::path& path);
/// Whole file as bytes; throws InputError if it cannot be read.
std::string read_file_bytes(const std::filesystem::path& path);

/// Walks a text line by line (split at '\n'), counting lines from 1.
class LineCursor {
 public:
  explicit LineCursor(const std::string& text, size_t pos = 0, int line_no = 0)
      : text_(text), pos_(pos), line_no_(line_no) {}
  /// The next line, without its '\n'; false at the end of the text.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) end = text_.size();
    line = std::string_view(text_.data() + pos_, end - pos_);
    pos_ = end + 1;
    ++line_no_;
    return true;
  }
  int line_no() const { return line_no_; }
  size_t pos() const { return std::min(pos_, text_.size()); }

 private:
  const std::string& text_;
  size_t pos_;
  int line_no_;
};

/// Whitespace-separated tokens of a line.
std::vector<std::string_view> split_ws(std::string_view line);
/// Parses a whole token as a double ("nan"/"inf" parse, a leading '+' is allowed); false if it is no number.
bool parse_double(std::string_view token, double& value);

/// What a PLY or OFF file declares, after its whole structure was checked against
/// what the file holds (import_ply_off_check.cpp); InputError naming the line otherwise.
struct PlyOffCounts {
  std::uint64_t vertices = 0, faces = 0;
};
PlyOffCounts check_ply(const std::string& text, const std::string& name);

RawMesh read_stl(const std::filesystem::path& path);
RawMesh read_ply(const std::filesystem::path& path);                              // checked, then OpenMesh
RawMesh read_off(const std::filesystem::path& path);                              // import_ply_off_check.cpp
RawMesh read_obj(const std::filesystem::path& path);                              // tinyobjloader
RawMesh read_3mf(const std::filesystem::path& path);                              // checked, then lib3mf
/// Bounds every zip entry's declared size by its packed bytes and the package's total, and
/// unpacks each once to check it gives what it declares (import_3mf_check.cpp); throws InputError.
void check_3mf_package(const std::filesystem::path& path, const std::string& name);
RawMesh read_gltf(const std::filesystem::path& path, bool binary);               // tinygltf

// Writers take the final (temporary) path; the extension is passed separately.
void write_openmesh(const Mesh& mesh, const std::filesystem::path& path, const std::string& ext);
void write_obj(const Mesh& mesh, const std::filesystem::path& path);
/// `unit`: the unit written into the file (coordinates are converted from mm);
/// `build_transform`: optional 3×4 affine (row-major, x' = A·x + t) put on every build item.
void write_3mf(const Mesh& mesh, const std::filesystem::path& path,
               LengthUnit unit = LengthUnit::millimetre,
               const Eigen::Matrix<double, 3, 4>* build_transform = nullptr);

}  // namespace clearfit::detail
