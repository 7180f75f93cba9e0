#include <clearfit/reports/mesh_report.hpp>
#include <clearfit/format.hpp>

#include <cstdio>
#include <sstream>

namespace clearfit::reports {
namespace {
nlohmann::json vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
template <class T>
std::string first_few(const std::vector<T>& items, std::size_t n = 8) {
  std::ostringstream s;
  for (std::size_t i = 0; i < items.size() && i < n; ++i) {
    if (i) s << ", ";
    if constexpr (std::is_same_v<T, std::array<int, 2>>) s << items[i][0] << "/" << items[i][1];
    else s << items[i];
  }
  if (items.size() > n) s << ", ...";
  return s.str();
}
}  // namespace

nlohmann::json to_json(const MeshInfo& info) {
  const Mesh& m = *info.mesh;
  const ValidationReport& v = info.validation;
  nlohmann::json j;
  j["schema"] = "clearfit.mesh-info/1";
  j["source"] = m.source;
  j["source_units"] = m.source_units;
  j["import_notes"] = m.import_notes;
  j["repairs"] = info.repairs;
  j["vertices"] = v.vertices;
  j["faces"] = v.faces;
  j["groups"] = m.groups;
  j["bbox_mm"] = {{"min", vec(v.bbox_min)}, {"max", vec(v.bbox_max)}};
  j["area_mm2"] = v.area_mm2;
  j["volume_mm3"] = v.volume_mm3 ? nlohmann::json(*v.volume_mm3) : nlohmann::json(nullptr);
  j["closed"] = v.closed;
  j["boundary_loops"] = v.boundary_loops;
  j["consistently_oriented"] = v.consistently_oriented;
  j["outward"] = v.outward ? nlohmann::json(*v.outward) : nlohmann::json(nullptr);
  j["components"] = v.components;
  j["degenerate_faces"] = v.degenerate_faces;
  j["sliver_faces"] = v.sliver_faces;
  j["duplicate_faces"] = v.duplicate_faces;
  j["non_manifold_edges"] = v.non_manifold_edges;
  j["non_manifold_vertices"] = v.non_manifold_vertices;
  j["self_intersections_checked"] = v.self_intersections_checked;
  j["self_intersections"] = v.self_intersections;
  j["thickness_mm"] = v.thickness_min_mm ? nlohmann::json{{"min", *v.thickness_min_mm}, {"max", *v.thickness_max_mm}}
                                         : nlohmann::json(nullptr);
  j["warnings"] = v.warnings;
  j["ok"] = v.ok();
  if (info.contact) {
    const ContactSurface& c = *info.contact;
    j["contact"] = {{"chosen_by", c.chosen_by}, {"faces", c.faces.size()}, {"area_mm2", c.area_mm2},
                    {"components", c.components}, {"component_area_mm2", c.component_area_mm2}};
  }
  if (info.chart) {
    const Chart& c = *info.chart;
    j["chart"] = {{"method", std::string(to_string(c.method))},
                  {"uv_min_mm", {c.uv_min.x(), c.uv_min.y()}},
                  {"uv_max_mm", {c.uv_max.x(), c.uv_max.y()}},
                  {"area_ratio", {{"min", c.area_ratio_min}, {"max", c.area_ratio_max}}},
                  {"angle_error_deg", {{"mean", c.angle_error_mean_deg}, {"max", c.angle_error_max_deg}}},
                  {"notes", c.notes}};
  }
  return j;
}

std::string to_text(const MeshInfo& info) {
  const Mesh& m = *info.mesh;
  const ValidationReport& v = info.validation;
  std::ostringstream s;
  s << "mesh      " << m.source << "  (numbers in " << m.source_units << ", shown in mm)\n";
  s << "size      " << v.vertices << " vertices, " << v.faces << " triangles, " << v.components << " component"
    << (v.components == 1 ? "" : "s") << "\n";
  s << "bbox      [" << significant_digits(v.bbox_min.x(), 4) << ", " << significant_digits(v.bbox_min.y(), 4)
    << ", " << significant_digits(v.bbox_min.z(), 4) << "] .. [" << significant_digits(v.bbox_max.x(), 4)
    << ", " << significant_digits(v.bbox_max.y(), 4) << ", " << significant_digits(v.bbox_max.z(), 4)
    << "] mm\n";
  s << "area      " << significant_digits(v.area_mm2, 6) << " mm²\n";
  s << "volume    " << (v.volume_mm3 ? significant_digits(*v.volume_mm3, 6) + " mm³" : "n/a (mesh is open)")
    << "\n";
  s << "surface   " << (v.closed ? "closed" : "open, " + std::to_string(v.boundary_loops) + " boundary loop(s)")
    << "; orientation " << (v.consistently_oriented ? "consistent" : "INCONSISTENT")
    << (v.outward ? (*v.outward ? ", normals point out" : ", normals point IN") : "") << "\n";
  s << "defects   degenerate " << v.degenerate_faces.size() << ", slivers " << v.sliver_faces.size()
    << ", duplicates " << v.duplicate_faces.size() << ", non-manifold edges " << v.non_manifold_edges
    << ", non-manifold vertices " << v.non_manifold_vertices << ", self-intersections "
    << (v.self_intersections_checked ? std::to_string(v.self_intersections.size()) : std::string("not checked"))
    << "\n";
  if (!v.degenerate_faces.empty()) s << "          degenerate faces: " << first_few(v.degenerate_faces) << "\n";
  if (!v.sliver_faces.empty()) s << "          sliver faces: " << first_few(v.sliver_faces) << "\n";
  if (!v.self_intersections.empty()) s << "          intersecting face pairs: " << first_few(v.self_intersections) << "\n";
  if (v.thickness_min_mm)
    s << "thickness " << significant_digits(*v.thickness_min_mm, 4) << " .. "
      << significant_digits(*v.thickness_max_mm, 4)
      << " mm between the contact surface and the outer surface\n";
  if (info.contact) {
    const ContactSurface& c = *info.contact;
    s << "contact   " << c.chosen_by << ": " << c.faces.size() << " faces, "
      << significant_digits(c.area_mm2, 6) << " mm², " << c.components << " component"
      << (c.components == 1 ? "" : "s") << "\n";
  }
  if (info.chart) {
    const Chart& c = *info.chart;
    s << "chart     " << to_string(c.method) << ", " << significant_digits(c.uv_max.x() - c.uv_min.x(), 4)
      << " x " << significant_digits(c.uv_max.y() - c.uv_min.y(), 4) << " mm; area ratio "
      << significant_digits(c.area_ratio_min, 4) << " .. " << significant_digits(c.area_ratio_max, 4)
      << ", angle error mean " << significant_digits(c.angle_error_mean_deg, 4) << "°, max "
      << significant_digits(c.angle_error_max_deg, 4) << "°\n";
    for (const auto& n : c.notes) s << "          " << n << "\n";
  }
  for (const auto& n : m.import_notes) s << "note: " << n << "\n";
  for (const auto& r : info.repairs) s << "repaired: " << r << "\n";
  for (const auto& w : v.warnings) s << "warning: " << w << "\n";
  s << (v.ok() ? "verdict   usable\n" : "verdict   needs attention (see warnings)\n");
  return s.str();
}

}  // namespace clearfit::reports
