// clearfit mesh-info PART: the validation report and contact surface summary.
#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/options.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/reports/mesh_report.hpp>
#include <iostream>

namespace clearfit::cli {

Run add_mesh_info(CLI::App& app) {
  struct Opts {
    std::string part;
    Scene scene;  // the contact surface, the mesh units and the chart method, as the scene file names them
    SceneFields::Options options;
    bool repair = false, json = false, no_self_intersections = false;
    std::string out;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand("mesh-info", "Check a part's mesh and summarise its contact surface and chart");
  sub->add_option("part", o->part, "Mesh file: .stl .obj .ply .off .3mf .gltf .glb")->required();
  o->options = add_scene_options(*sub, o->scene, {"units", "contact", "map.chart"});
  sub->add_flag("--repair", o->repair, "Apply the safe repairs (drop degenerate faces, orient outward) and say what changed");
  sub->add_flag("--no-self-intersections", o->no_self_intersections, "Skip the self-intersection test (slow on huge meshes)");
  sub->add_flag("--json", o->json, "Print JSON (schema clearfit.mesh-info/1) instead of text");
  sub->add_option("--out", o->out, "Also write the JSON report to this file");

  return [o]() {
    check_scene(o->scene, o->options);
    const PartSection& part = o->scene.part;
    const std::string& chart = o->scene.map.chart;
    reports::MeshInfo info;
    Mesh mesh = load_part(o->part, part.units);
    if (o->repair) info.repairs = repair_mesh(mesh);
    info.mesh = &mesh;
    if (auto selector = make_contact_selector(part.contact)) info.contact = select_contact(mesh, *selector);
    ValidationOptions vopt;
    vopt.check_self_intersections = !o->no_self_intersections;
    info.validation = validate_mesh(mesh, info.contact ? &*info.contact : nullptr, vopt);
    if (info.contact && chart != "none") {
      ChartOptions copt;
      copt.method = parse_chart_method(chart);
      info.chart = compute_chart(mesh, *info.contact, copt);
    }
    const nlohmann::json j = reports::to_json(info);
    if (!o->out.empty()) write_file_atomically(o->out, j.dump(2) + "\n");
    std::cout << (o->json ? j.dump(2) + "\n" : reports::to_text(info));
    return 0;
  };
}

static const Registration registered{"mesh-info", 10, add_mesh_info};

}  // namespace clearfit::cli
