// Wavefront OBJ through tinyobjloader (it keeps g/o groups in file order), and a
// plain-text OBJ writer (OpenMesh's OBJ writer cannot write groups).
// tinyobjloader reads "nan" or a typo in a coordinate as 0 and silently skips
// faces with fewer than 3 vertices, so 'v' and 'f' lines are checked first.
#include "import_internal.hpp"

#include <tiny_obj_loader.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace clearfit::detail {
namespace {

// Checks vertex coordinates and face sizes; returns the number of 'f' lines.
size_t check_obj_text(const std::string& text, const std::string& name) {
  size_t vertices = 0, faces = 0;
  LineCursor lines(text);
  for (std::string_view line; lines.next(line);) {
    const int line_no = lines.line_no();
    const auto tok = split_ws(line.substr(0, line.find('#')));
    if (tok.empty()) continue;
    if (tok[0] == "v") {
      const std::string where = "line " + std::to_string(line_no) + " (vertex " + std::to_string(++vertices) + ")";
      if (tok.size() < 4) throw InputError(name, where, "expected 'v x y z'");
      for (int k = 1; k <= 3; ++k) {
        double value = 0;
        if (!parse_double(tok[k], value))
          throw InputError(name, where, "'" + std::string(tok[k].substr(0, 40)) + "' is not a number");
        if (!std::isfinite(value))
          throw InputError(name, where, "coordinate is not finite (nan or inf)", "fix or re-export the mesh");
      }
    } else if (tok[0] == "f") {
      ++faces;
      if (tok.size() < 4)
        throw InputError(name, "line " + std::to_string(line_no) + " (face " + std::to_string(faces) + ")",
                         "has " + std::to_string(tok.size() - 1) + " vertices; a face needs at least 3");
    }
  }
  return faces;
}

std::vector<std::string> note_lines(const std::string& text, const std::string& prefix) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.find_first_not_of(" \t\r") != std::string::npos) out.push_back(prefix + line);
  return out;
}

}  // namespace

RawMesh read_obj(const std::filesystem::path& path) {
  const std::string name = display(path);
  const size_t face_lines = check_obj_text(read_file_bytes(path), name);
  tinyobj::ObjReaderConfig config;
  config.triangulate = false;
  config.vertex_color = false;
  config.mtl_search_path = path.parent_path().string();
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path.string(), config)) {
    std::string why = reader.Error();
    while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
    throw InputError(name, "", "tinyobjloader could not read it: " + why);
  }
  RawMesh raw;
  raw.index_base = 1;
  raw.notes = note_lines(reader.Warning(), "tinyobjloader: ");
  const auto& xyz = reader.GetAttrib().vertices;
  raw.vertices.reserve(xyz.size() / 3);
  for (size_t i = 0; i + 2 < xyz.size(); i += 3) raw.vertices.emplace_back(xyz[i], xyz[i + 1], xyz[i + 2]);
  bool any_group = false;
  for (const auto& shape : reader.GetShapes()) {
    const int group = shape.name.empty() ? -1 : raw.group_index(shape.name);
    any_group |= group >= 0;
    size_t offset = 0;
    for (unsigned char n : shape.mesh.num_face_vertices) {
      std::vector<int> poly;
      for (size_t k = 0; k < n; ++k) poly.push_back(shape.mesh.indices[offset + k].vertex_index);
      offset += n;
      raw.polygons.push_back(std::move(poly));
      raw.polygon_group.push_back(group);
    }
  }
  if (!any_group) raw.polygon_group.clear();
  if (raw.polygons.size() != face_lines)
    throw InputError(name, "", "the file has " + std::to_string(face_lines) + " 'f' lines but tinyobjloader read " +
                                   std::to_string(raw.polygons.size()) + " faces");
  return raw;
}

void write_obj(const Mesh& mesh, const std::filesystem::path& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot create " + display(path));
  out << "# clearfit mesh, millimetres\n";
  char buf[32];
  auto num = [&](double v) {
    auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);  // shortest exact round trip
    (void)ec;
    return std::string_view(buf, end - buf);
  };
  for (const auto& v : mesh.vertices) {
    out << "v " << num(v.x());
    out << ' ' << num(v.y());
    out << ' ' << num(v.z()) << '\n';
  }
  const bool grouped = !mesh.face_group.empty();
  int current = -2;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (grouped && mesh.face_group[f] != current) {
      current = mesh.face_group[f];
      out << "g";
      if (current >= 0) out << ' ' << mesh.groups[current];
      out << '\n';
    }
    const auto& t = mesh.faces[f];
    out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error("write error on " + display(path));
}

}  // namespace clearfit::detail
