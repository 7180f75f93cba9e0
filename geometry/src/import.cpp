// Units, the load_mesh / save_mesh front doors, and the checks every format shares.
#include "import_internal.hpp"

#include <clearfit/atomic_file.hpp>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <numeric>
#include <sstream>

namespace clearfit {
namespace fs = std::filesystem;

std::optional<LengthUnit> parse_length_unit(std::string_view text) {
  std::string s;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (s.size() > 3 && s.back() == 's' && s != "inches") s.pop_back();  // plurals: metres, microns (feet below)
  auto any = [&](std::initializer_list<const char*> names) {
    return std::any_of(names.begin(), names.end(), [&](const char* n) { return s == n; });
  };
  if (any({"um", "\xc2\xb5m", "micron", "micrometre", "micrometer"})) return LengthUnit::micrometre;
  if (any({"mm", "millimetre", "millimeter"})) return LengthUnit::millimetre;
  if (any({"cm", "centimetre", "centimeter"})) return LengthUnit::centimetre;
  if (any({"m", "metre", "meter"})) return LengthUnit::metre;
  if (any({"in", "inch", "inches"})) return LengthUnit::inch;
  if (any({"ft", "foot", "feet"})) return LengthUnit::foot;
  return std::nullopt;
}

std::string_view to_string(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::micrometre: return "um";
    case LengthUnit::millimetre: return "mm";
    case LengthUnit::centimetre: return "cm";
    case LengthUnit::metre: return "m";
    case LengthUnit::inch: return "in";
    case LengthUnit::foot: return "ft";
  }
  throw std::invalid_argument("to_string: invalid LengthUnit");
}

double millimetres_per(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::micrometre: return 1e-3;
    case LengthUnit::millimetre: return 1.0;
    case LengthUnit::centimetre: return 10.0;
    case LengthUnit::metre: return 1000.0;
    case LengthUnit::inch: return 25.4;
    case LengthUnit::foot: return 304.8;
  }
  throw std::invalid_argument("millimetres_per: invalid LengthUnit");
}

namespace detail {

int RawMesh::group_index(const std::string& name) {
  auto it = std::find(groups.begin(), groups.end(), name);
  if (it != groups.end()) return static_cast<int>(it - groups.begin());
  groups.push_back(name);
  return static_cast<int>(groups.size()) - 1;
}

std::string display(const fs::path& path) { return path.string(); }

std::string read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(display(path), "", "cannot be opened for reading", "check the file's permissions");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(display(path), "", "read error", "check the file and the disk");
  return bytes;
}

std::vector<std::string_view> split_ws(std::string_view line) {
  std::vector<std::string_view> tok;
  for (size_t i = 0; i < line.size();) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) tok.push_back(line.substr(i, j - i));
    i = j;
  }
  return tok;
}

bool parse_double(std::string_view t, double& value) {
  if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);  // from_chars takes no '+'
  auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (ec == std::errc::result_out_of_range) {
    value = HUGE_VAL;  // overflow: report as not finite
    return true;
  }
  return ec == std::errc() && ptr == t.data() + t.size();
}

namespace {

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

constexpr const char* kReadable = "supported: .stl .obj .ply .off .3mf .gltf .glb";
constexpr const char* kWritable = "supported: .stl .obj .ply .off .3mf";

// Checks the raw data, fan-triangulates polygons, converts to mm.
Mesh finish(RawMesh raw, const std::string& name, const ImportOptions& options) {
  const int base = raw.index_base;
  const int nv = static_cast<int>(raw.vertices.size());
  for (int i = 0; i < nv; ++i)
    if (!raw.vertices[i].allFinite())
      throw InputError(name, "vertex " + std::to_string(i + base),
                       "coordinate is not finite (nan or inf)", "fix or re-export the mesh");
  Mesh mesh;
  const bool grouped = !raw.polygon_group.empty() && !raw.groups.empty();
  int polygons = 0, degenerate = 0;
  for (size_t p = 0; p < raw.polygons.size(); ++p) {
    const auto& poly = raw.polygons[p];
    const std::string face = "face " + std::to_string(p + base);
    if (poly.size() < 3)
      throw InputError(name, face, "has " + std::to_string(poly.size()) + " vertices; a face needs at least 3");
    for (int v : poly)
      if (v < 0 || v >= nv)
        throw InputError(name, face,
                         "vertex index " + std::to_string(v + base) + " is out of range (the file has " +
                             std::to_string(nv) + " vertices" + (base ? ", numbered from 1)" : ", numbered from 0)"));
    if (poly.size() > 3) ++polygons;
    for (size_t k = 1; k + 1 < poly.size(); ++k) {
      std::array<int, 3> tri{poly[0], poly[k], poly[k + 1]};
      if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) ++degenerate;
      mesh.faces.push_back(tri);
      if (grouped) mesh.face_group.push_back(raw.polygon_group[p]);
    }
  }
  if (mesh.faces.empty())
    throw InputError(name, "", "holds no faces (triangles)", "export the part as a triangle mesh (surface, not points or lines)");
  if (polygons > 0)
    raw.notes.push_back("fan-triangulated " + std::to_string(polygons) + " polygons with more than 3 vertices into " +
                        "triangles; face numbers count these triangles in file order");
  if (degenerate > 0)
    raw.notes.push_back(std::to_string(degenerate) + " triangles repeat a vertex (kept in place to keep the file's face order)");

  LengthUnit unit = LengthUnit::millimetre;
  if (options.units) {
    unit = *options.units;
    if (raw.file_unit && *raw.file_unit != unit)
      raw.notes.push_back("the file states its unit as " + std::string(to_string(*raw.file_unit)) + "; using " +
                          std::string(to_string(unit)) + " as requested");
  } else if (raw.file_unit) {
    unit = *raw.file_unit;
  }
  const double scale = millimetres_per(unit);
  mesh.vertices = std::move(raw.vertices);
  if (scale != 1.0)
    for (auto& v : mesh.vertices) v *= scale;
  mesh.file_face.resize(mesh.faces.size());
  std::iota(mesh.file_face.begin(), mesh.file_face.end(), 0);
  if (grouped) mesh.groups = std::move(raw.groups);
  else mesh.face_group.clear();
  mesh.source = name;
  mesh.source_units = std::string(to_string(unit));
  mesh.import_notes = std::move(raw.notes);
  return mesh;
}

}  // namespace
}  // namespace detail

Mesh load_mesh(const fs::path& path, const ImportOptions& options) {
  const std::string name = detail::display(path);
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::exists(status))
    throw InputError(name, "", "file not found", "check the path and its spelling");
  if (fs::is_directory(status))
    throw InputError(name, "", "is a directory, not a mesh file", "name the mesh file inside it");
  if (!fs::is_regular_file(status))
    throw InputError(name, "", "is not a regular file", "name a mesh file");
  if (std::ifstream probe(path, std::ios::binary); !probe)
    throw InputError(name, "", "cannot be opened for reading", "check the file's permissions");
  if (fs::file_size(path, ec) == 0 && !ec)
    throw InputError(name, "", "file is empty", "export the mesh again");
  const std::string ext = detail::lower_extension(path);
  detail::RawMesh raw;
  if (ext == ".stl") raw = detail::read_stl(path);
  else if (ext == ".ply") raw = detail::read_ply(path);
  else if (ext == ".off") raw = detail::read_off(path);
  else if (ext == ".obj") raw = detail::read_obj(path);
  else if (ext == ".3mf") raw = detail::read_3mf(path);
  else if (ext == ".gltf" || ext == ".glb") raw = detail::read_gltf(path, ext == ".glb");
  else
    throw InputError(name, "", "unknown mesh format '" + path.extension().string() + "'", detail::kReadable);
  return detail::finish(std::move(raw), name, options);
}

void save_mesh(const Mesh& mesh, const fs::path& path) {
  mesh.check_consistent();
  const std::string name = detail::display(path);
  const std::string ext = detail::lower_extension(path);
  if (ext != ".stl" && ext != ".obj" && ext != ".ply" && ext != ".off" && ext != ".3mf")
    throw InputError(name, "", "cannot write mesh format '" + path.extension().string() + "'", detail::kWritable);
  write_path_atomically(path, [&](const fs::path& tmp) {
    try {
      if (ext == ".obj") detail::write_obj(mesh, tmp);
      else if (ext == ".3mf") detail::write_3mf(mesh, tmp);
      else detail::write_openmesh(mesh, tmp, ext);
    } catch (const InputError&) {
      throw;
    } catch (const std::runtime_error& e) {
      throw InputError(name, "", std::string("cannot write: ") + e.what(), "check the folder is writable");
    }
  });
}

}  // namespace clearfit
