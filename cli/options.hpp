#pragma once
// Options shared by the subcommands that read a part: mesh units and the
// contact-surface selection.
#include <CLI/CLI.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/validate.hpp>
#include <optional>

namespace clearfit::cli {

struct MeshOptions {
  std::string units;   ///< empty: the file's own unit (mm for STL/OBJ/PLY/OFF)
};
struct ContactOptions {
  std::string group, faces_file;
  std::vector<double> normal;
  double angle_deg = 30.0;
};

void add_mesh_options(CLI::App& app, MeshOptions& o);
void add_contact_options(CLI::App& app, ContactOptions& o);
/// Loads the mesh with the units option; throws InputError on bad input.
Mesh load_part(const std::string& path, const MeshOptions& o);
/// nullopt when no contact option was given.
std::optional<ContactSelector> make_contact_selector(const ContactOptions& o);
ChartMethod parse_chart_method(const std::string& name);

}  // namespace clearfit::cli
