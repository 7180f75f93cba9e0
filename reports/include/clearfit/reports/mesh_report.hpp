#pragma once
// The mesh-info report: what a part's mesh is, what is wrong with it, and its
// contact surface and chart, as plain text for people and JSON for machines.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/geometry/validate.hpp>
#include <nlohmann/json.hpp>
#include <optional>

namespace clearfit::reports {

struct MeshInfo {
  const Mesh* mesh = nullptr;
  ValidationReport validation;
  std::vector<std::string> repairs;        ///< changes made by repair_mesh
  std::optional<ContactSurface> contact;
  std::optional<Chart> chart;
};

/// JSON with "schema": "clearfit.mesh-info/1".
nlohmann::json to_json(const MeshInfo& info);
/// Plain text: one section per topic, warnings last.
std::string to_text(const MeshInfo& info);

}  // namespace clearfit::reports
