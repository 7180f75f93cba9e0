#include "options.hpp"

#include <clearfit/error.hpp>

namespace clearfit::cli {

void add_mesh_options(CLI::App& app, MeshOptions& o) {
  app.add_option("--units", o.units, "Unit of the mesh file's numbers: um, mm, cm, m, in, ft (default: mm, or the file's own for 3MF/glTF)");
}

void add_contact_options(CLI::App& app, ContactOptions& o) {
  auto* g = app.add_option("--contact-group", o.group, "Contact surface: a group or object name (OBJ g/o, 3MF, glTF)");
  auto* f = app.add_option("--contact-faces", o.faces_file, "Contact surface: a file of 0-based face indices in file order");
  auto* n = app.add_option("--contact-normal", o.normal, "Contact surface: faces whose outward normal is within --contact-angle of x,y,z (part frame)")
                ->delimiter(',')->expected(3);
  app.add_option("--contact-angle", o.angle_deg, "Cone half-angle for --contact-normal, degrees")->capture_default_str();
  g->excludes(f)->excludes(n);
  f->excludes(n);
}

Mesh load_part(const std::string& path, const MeshOptions& o) {
  ImportOptions opt;
  if (!o.units.empty()) {
    opt.units = parse_length_unit(o.units);
    if (!opt.units) throw InputError("", "--units '" + o.units + "'", "unknown unit", "use um, mm, cm, m, in or ft");
  }
  return load_mesh(path, opt);
}

std::optional<ContactSelector> make_contact_selector(const ContactOptions& o) {
  ContactSelector s;
  if (!o.group.empty()) s.group = o.group;
  if (!o.faces_file.empty()) s.face_file = o.faces_file;
  if (!o.normal.empty()) s.normal = Vec3(o.normal[0], o.normal[1], o.normal[2]);
  s.angle_deg = o.angle_deg;
  if (s.empty()) return std::nullopt;
  return s;
}

ChartMethod parse_chart_method(const std::string& name) {
  if (name == "planar") return ChartMethod::planar;
  if (name == "lscm") return ChartMethod::lscm;
  if (name == "arap") return ChartMethod::arap;
  return ChartMethod::automatic;
}

}  // namespace clearfit::cli
