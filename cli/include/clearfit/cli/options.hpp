#pragma once
// Helpers shared by the subcommands that read a part: the mesh with its units,
// the contact-surface selection, the chart method (the values come from the
// scene's sections, scene.hpp).
#include <clearfit/cli/scene.hpp>

#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/validate.hpp>
#include <optional>

namespace clearfit::cli {

/// Loads the mesh in `units` (empty: the file's own); throws InputError on bad input.
Mesh load_part(const std::string& path, const std::string& units);
/// nullopt when no contact surface was given.
std::optional<ContactSelector> make_contact_selector(const ContactSection& c);
ChartMethod parse_chart_method(const std::string& name);

}  // namespace clearfit::cli
