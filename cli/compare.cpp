// clearfit compare A B --out DIR: what changed between two assessments of the
// same part (or of two revisions with the same contact region).
#include <clearfit/cli/commands.hpp>

#include <clearfit/reports/compare.hpp>
#include <iostream>

namespace clearfit::cli {

Run add_compare(CLI::App& app) {
  struct Opts {
    std::string a, b, out;
    reports::CompareOptions options;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "compare", "Compare two assessments (A before, B after): pressure difference on the mesh, hotspots better or worse");
  sub->add_option("A", o->a, "Output folder of the first `clearfit assess` (with report.json and heatmap.glb)")->required();
  sub->add_option("B", o->b, "Output folder of the second assessment")->required();
  sub->add_option("--out", o->out, "Folder for compare.json, difference.glb and compare.html (created)")->required();
  sub->add_option("--match-tolerance-mm", o->options.match_tolerance_mm,
                  "When the meshes differ: a vertex of B takes the nearest seen vertex of A within this distance, mm")
      ->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_option("--hotspot-match-mm", o->options.hotspot_match_mm,
                  "Hotspots of A and B are the same when their centroids are this close, mm")
      ->capture_default_str()->check(CLI::PositiveNumber);
  return [o]() {
    const reports::CompareResult r = reports::compare_assessments(o->a, o->b, o->out, o->options);
    for (const std::string& note : r.notes) std::cerr << "clearfit: note: " << note << "\n";
    const auto& d = r.summary["difference"];
    std::cout << "pressure difference B - A over " << d["vertices"] << " vertices: mean " << d["mean_kpa"].get<double>()
              << " kPa, largest rise " << d["max_increase_kpa"].get<double>() << " kPa, largest drop "
              << d["max_decrease_kpa"].get<double>() << " kPa\n";
    for (const auto& h : r.summary["hotspots"])
      std::cout << "hotspot A#" << h["a_id"].dump() << " -> B#" << h["b_id"].dump() << ": " << h["verdict"].get<std::string>()
                << " (peak change " << h["delta_peak_kpa"].dump() << " kPa)\n";
    std::cout << "wrote " << r.json.string() << ", " << r.glb.string() << ", " << r.html.string() << "\n";
    return 0;
  };
}

static const Registration registered{"compare", 80, add_compare};

}  // namespace clearfit::cli
