#include <clearfit/error.hpp>
#include <clearfit/geometry/contact.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <numeric>
#include <sstream>

namespace clearfit {

namespace {
int find(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

std::string format_deg(double d) {
  std::ostringstream s;
  s << d;
  return s.str();
}

std::vector<char> faces_from_file(const Mesh& mesh, const std::filesystem::path& path) {
  const std::string file = path.string();
  if (std::filesystem::is_directory(path)) throw InputError(file, "", "is a directory, expected a face-index file");
  std::ifstream in(path);
  if (!in) throw InputError(file, "", "cannot open the face-index file", "check the path and permissions");
  std::vector<char> flag(mesh.num_faces(), 0);
  int max_file_face = mesh.file_face.empty() ? -1 : *std::max_element(mesh.file_face.begin(), mesh.file_face.end());
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream tokens(line);
    std::string token;
    while (tokens >> token) {
      const std::string where = "line " + std::to_string(line_no) + ", '" + token + "'";
      std::size_t used = 0;
      long long value = -1;
      try {
        value = std::stoll(token, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != token.size() || value < 0)
        throw InputError(file, where, "expected a 0-based face index (a whole number >= 0)");
      if (value > max_file_face)
        throw InputError(file, where, "face index out of range: the mesh has faces 0.." + std::to_string(max_file_face));
      const int face = mesh.face_from_file_index(static_cast<int>(value));
      if (face < 0)
        throw InputError(file, where, "face " + token + " was removed by a repair (degenerate)",
                         "remove it from the list or fix the mesh");
      flag[face] = 1;
    }
  }
  return flag;
}
}  // namespace

ContactSurface make_contact_surface(const Mesh& mesh, std::vector<char> is_contact, std::string chosen_by) {
  ContactSurface s;
  s.is_contact = std::move(is_contact);
  s.chosen_by = std::move(chosen_by);
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (s.is_contact[f]) s.faces.push_back(f);
  // Edge-connected components among the contact faces.
  std::vector<int> parent(mesh.num_faces());
  std::iota(parent.begin(), parent.end(), 0);
  std::map<std::pair<int, int>, int> first_face_of_edge;
  for (int f : s.faces)
    for (int k = 0; k < 3; ++k) {
      auto key = std::minmax(mesh.faces[f][k], mesh.faces[f][(k + 1) % 3]);
      auto [it, inserted] = first_face_of_edge.try_emplace(key, f);
      if (!inserted) parent[find(parent, f)] = find(parent, it->second);
    }
  std::map<int, int> component_of_root;
  s.component.assign(mesh.num_faces(), -1);
  for (int f : s.faces) {
    auto [it, inserted] = component_of_root.try_emplace(find(parent, f), static_cast<int>(component_of_root.size()));
    if (inserted) s.component_area_mm2.push_back(0);
    s.component[f] = it->second;
    const double a = mesh.face_area(f);
    s.component_area_mm2[it->second] += a;
    s.area_mm2 += a;
  }
  s.components = static_cast<int>(component_of_root.size());
  return s;
}

ContactSurface select_contact(const Mesh& mesh, const ContactSelector& sel) {
  const int ways = (sel.group ? 1 : 0) + (sel.face_file ? 1 : 0) + (sel.normal ? 1 : 0);
  if (ways != 1)
    throw InputError("", "contact surface",
                     ways == 0 ? "no contact surface given" : "more than one way of choosing the contact surface given",
                     "give exactly one of a group name, a face-index file, or a normal with an angle");
  std::vector<char> flag(mesh.num_faces(), 0);
  std::string how;
  if (sel.group) {
    auto it = std::find(mesh.groups.begin(), mesh.groups.end(), *sel.group);
    if (it == mesh.groups.end() || mesh.face_group.empty()) {
      std::string known;
      for (const auto& g : mesh.groups) known += (known.empty() ? "" : ", ") + ("'" + g + "'");
      throw InputError(mesh.source, "group '" + *sel.group + "'", "no such group or object in the mesh",
                       known.empty() ? "this file has no groups: use a face-index file or a normal cone"
                                     : "groups in the file: " + known);
    }
    const int g = static_cast<int>(it - mesh.groups.begin());
    for (int f = 0; f < mesh.num_faces(); ++f) flag[f] = mesh.face_group[f] == g;
    how = "group '" + *sel.group + "'";
  } else if (sel.face_file) {
    flag = faces_from_file(mesh, *sel.face_file);
    how = "faces listed in " + sel.face_file->string();
  } else {
    const Vec3& n = *sel.normal;
    if (!n.allFinite() || n.norm() == 0)
      throw InputError("", "contact normal", "must be a finite, non-zero vector x,y,z");
    if (!(sel.angle_deg >= 0 && sel.angle_deg <= 180))
      throw InputError("", "contact angle", "must be within 0..180 degrees, got " + format_deg(sel.angle_deg));
    const Vec3 u = n.normalized();
    const double c = std::cos(sel.angle_deg * std::numbers::pi / 180.0);
    for (int f = 0; f < mesh.num_faces(); ++f) {
      const Vec3 fn = mesh.face_normal(f);
      flag[f] = !fn.isZero() && fn.dot(u) >= c;
    }
    std::ostringstream s;
    s << "normal cone (" << u.x() << ", " << u.y() << ", " << u.z() << ") ± " << sel.angle_deg << "°";
    how = s.str();
  }
  ContactSurface surface = make_contact_surface(mesh, std::move(flag), how);
  if (surface.faces.empty())
    throw InputError(mesh.source, how, "selects no faces", "check the group name, the face list or the normal cone");
  return surface;
}

}  // namespace clearfit
