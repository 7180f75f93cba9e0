#include <clearfit/cli/options.hpp>

#include <clearfit/error.hpp>

namespace clearfit::cli {

Mesh load_part(const std::string& path, const std::string& units) {
  ImportOptions opt;
  if (!units.empty()) {
    opt.units = parse_length_unit(units);
    if (!opt.units) throw InputError("", "--units '" + units + "'", "unknown unit", "use um, mm, cm, m, in or ft");
  }
  return load_mesh(path, opt);
}

std::optional<ContactSelector> make_contact_selector(const ContactSection& c) {
  ContactSelector s;
  if (!c.group.empty()) s.group = c.group;
  if (!c.faces.empty()) s.face_file = c.faces;
  if (!c.normal.empty()) s.normal = Vec3(c.normal[0], c.normal[1], c.normal[2]);
  s.angle_deg = c.angle_deg;
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
