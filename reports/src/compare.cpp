// clearfit compare: the pressure difference of two assessments (see compare.hpp).
#include <clearfit/reports/compare.hpp>

#include "report_html_glb.hpp"

#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/geometry/mesh.hpp>
#include <clearfit/reports/heatmap_glb.hpp>
#include <clearfit/reports/report_html.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace clearfit::reports {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct Assessment {
  fs::path folder;
  json report;
  detail::HeatmapGlb glb;
  std::vector<float> pressure;  // _PRESSURE_KPA per glb vertex
};

Assessment load(const fs::path& folder, const char* which) {
  Assessment a;
  a.folder = folder;
  const fs::path rp = folder / "report.json";
  std::ifstream in(rp, std::ios::binary);
  if (!in) throw InputError(rp.string(), "", std::string("not found (assessment ") + which + ")", "give the output folder of a finished `clearfit assess` run");
  a.report = json::parse(in, nullptr, false);
  if (a.report.is_discarded() || !a.report.is_object() || a.report.value("schema", "") != "clearfit.report/1")
    throw InputError(rp.string(), "key 'schema'", "expected a clearfit.report/1 report");
  const json& outputs = a.report.value("outputs", json::object());
  const std::string glb_name = outputs.is_object() && outputs.value("heatmap_glb", json()).is_string() ? outputs["heatmap_glb"].get<std::string>() : "heatmap.glb";
  a.glb = detail::load_heatmap_glb(folder / glb_name);
  a.pressure = a.glb.scalar("_PRESSURE_KPA");
  const json& cal = a.report.value("calibration", json::object());
  if (a.pressure.empty() || !(cal.is_object() && cal.value("pressure", json()).is_object()))
    throw InputError(folder.string(), std::string("assessment ") + which, "has no pressure calibration (a signal-only report)",
                     "compare needs pressure in kPa: assess both with a per-person calibration");
  return a;
}

const char* const kDash = "\xE2\x80\x94";  // an em dash: "no value"

std::string signed_fixed(double v, int digits) { return (v > 0 ? "+" : "") + fixed_digits(v, digits, kDash); }

double get(const json& h, const char* key) {
  const auto it = h.find(key);
  return it != h.end() && it->is_number() ? it->get<double>() : NAN;
}

Eigen::Vector3d centroid(const json& h) {
  const json& c = h.value("centroid_mm", json());
  if (c.is_array() && c.size() == 3 && c[0].is_number() && c[1].is_number() && c[2].is_number())
    return {c[0].get<double>(), c[1].get<double>(), c[2].get<double>()};
  return Eigen::Vector3d::Constant(NAN);
}

// For each vertex of B: the vertex of A it corresponds to, or -1.
struct Correspondence {
  std::vector<int> a_of_b;
  std::string method;
  double max_distance_mm = 0;
  double matched_fraction = 0;  // of B's seen vertices
};

Correspondence correspond(const Assessment& A, const Assessment& B, const CompareOptions& o) {
  Correspondence c;
  const auto& pa = A.glb.position_mm;
  const auto& pb = B.glb.position_mm;
  const std::size_t na = A.glb.vertex_count(), nb = B.glb.vertex_count();
  auto pos = [](const std::vector<float>& p, std::size_t v) { return Eigen::Vector3d(p[3 * v], p[3 * v + 1], p[3 * v + 2]); };
  c.a_of_b.assign(nb, -1);
  if (na == nb) {
    double worst = 0;
    for (std::size_t v = 0; v < nb; ++v) worst = std::max(worst, (pos(pa, v) - pos(pb, v)).norm());
    if (worst <= o.same_position_tolerance_mm) {
      for (std::size_t v = 0; v < nb; ++v) c.a_of_b[v] = static_cast<int>(v);
      c.method = "same_vertices";
      c.max_distance_mm = worst;
      c.matched_fraction = 1;
      return c;
    }
  }
  // Nearest seen vertex of A within the tolerance: a hash grid of cell = tolerance, 27 cells searched.
  c.method = "nearest_vertex";
  const double cell = o.match_tolerance_mm;
  auto key = [cell](const Eigen::Vector3d& p, int dx, int dy, int dz) {
    const auto ix = static_cast<std::int64_t>(std::floor(p.x() / cell)) + dx, iy = static_cast<std::int64_t>(std::floor(p.y() / cell)) + dy,
               iz = static_cast<std::int64_t>(std::floor(p.z() / cell)) + dz;
    return static_cast<std::uint64_t>((ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791));
  };
  std::unordered_map<std::uint64_t, std::vector<int>> grid;
  for (std::size_t v = 0; v < na; ++v)
    if (A.glb.seen[v] > 0.5f) grid[key(pos(pa, v), 0, 0, 0)].push_back(static_cast<int>(v));
  std::size_t seen_b = 0, matched = 0;
  for (std::size_t v = 0; v < nb; ++v) {
    if (B.glb.seen[v] < 0.5f) continue;
    ++seen_b;
    const Eigen::Vector3d p = pos(pb, v);
    double best = o.match_tolerance_mm;
    int best_a = -1;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find(key(p, dx, dy, dz));
          if (it == grid.end()) continue;
          for (int a : it->second) {
            const double d = (pos(pa, a) - p).norm();
            if (d <= best) best = d, best_a = a;
          }
        }
    if (best_a >= 0) {
      c.a_of_b[v] = best_a;
      c.max_distance_mm = std::max(c.max_distance_mm, best);
      ++matched;
    }
  }
  c.matched_fraction = seen_b ? static_cast<double>(matched) / seen_b : 0;
  if (c.matched_fraction < o.min_matched_fraction)
    throw InputError(B.folder.string(), "contact surface",
                     "does not correspond to " + A.folder.string() + ": only " +
                         fixed_digits(100 * c.matched_fraction, 1, kDash) +
                         " % of its seen vertices lie within " +
                         fixed_digits(o.match_tolerance_mm, 3, kDash) + " mm of a seen vertex of A",
                     "compare assessments of the same part, or of revisions with the same contact region in "
                     "the same frame "
                     "(or widen --match-tolerance-mm)");
  return c;
}

}  // namespace

void CompareOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0)) throw std::invalid_argument(std::string("CompareOptions::") + name + " must be positive and finite");
  };
  positive(same_position_tolerance_mm, "same_position_tolerance_mm");
  positive(match_tolerance_mm, "match_tolerance_mm");
  positive(hotspot_match_mm, "hotspot_match_mm");
  positive(significance_sigmas, "significance_sigmas");
  if (!(min_matched_fraction > 0 && min_matched_fraction <= 1))
    throw std::invalid_argument("CompareOptions::min_matched_fraction must be in (0, 1]");
}

namespace {

/// Hotspots of A and B matched greedily by centroid distance, each pair's verdict (better, worse, unchanged
/// within the significance), and the unmatched as gone or new.
json hotspot_changes(const json& ha, const json& hb, const CompareOptions& o) {
  struct Pair { double d; std::size_t i, j; };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < ha.size(); ++i)
    for (std::size_t j = 0; j < hb.size(); ++j) {
      const double d = (centroid(ha[i]) - centroid(hb[j])).norm();
      if (d <= o.hotspot_match_mm) pairs.push_back({d, i, j});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) { return x.d < y.d; });
  std::vector<char> used_a(ha.size(), 0), used_b(hb.size(), 0);
  json changes = json::array();
  for (const Pair& p : pairs) {
    if (used_a[p.i] || used_b[p.j]) continue;
    used_a[p.i] = used_b[p.j] = 1;
    const json &x = ha[p.i], &y = hb[p.j];
    const double dpeak = get(y, "peak_kpa") - get(x, "peak_kpa");
    const double sigma = std::hypot(std::isfinite(get(x, "peak_sigma_kpa")) ? get(x, "peak_sigma_kpa") : 0.0,
                                    std::isfinite(get(y, "peak_sigma_kpa")) ? get(y, "peak_sigma_kpa") : 0.0);
    const double limit = std::max(0.1, o.significance_sigmas * sigma);
    const std::string verdict = !std::isfinite(dpeak) ? "unknown" : dpeak < -limit ? "better" : dpeak > limit ? "worse" : "unchanged";
    changes.push_back({{"a_id", x.value("id", json())}, {"b_id", y.value("id", json())}, {"centroid_distance_mm", p.d},
                       {"a_peak_kpa", get(x, "peak_kpa")}, {"b_peak_kpa", get(y, "peak_kpa")}, {"delta_peak_kpa", dpeak},
                       {"delta_peak_sigma_kpa", sigma}, {"delta_mean_kpa", get(y, "mean_kpa") - get(x, "mean_kpa")},
                       {"delta_area_mm2", get(y, "area_mm2") - get(x, "area_mm2")}, {"verdict", verdict}});
  }
  for (std::size_t i = 0; i < ha.size(); ++i)
    if (!used_a[i])
      changes.push_back({{"a_id", ha[i].value("id", json())}, {"b_id", nullptr}, {"a_peak_kpa", get(ha[i], "peak_kpa")},
                         {"b_peak_kpa", nullptr}, {"delta_peak_kpa", -get(ha[i], "peak_kpa")}, {"verdict", "gone"}});
  for (std::size_t j = 0; j < hb.size(); ++j)
    if (!used_b[j])
      changes.push_back({{"a_id", nullptr}, {"b_id", hb[j].value("id", json())}, {"a_peak_kpa", nullptr},
                         {"b_peak_kpa", get(hb[j], "peak_kpa")}, {"delta_peak_kpa", get(hb[j], "peak_kpa")}, {"verdict", "new"}});
  return changes;
}

/// The rows of compare.html's hotspot table, each change in words.
std::string change_rows(const json& changes) {
  std::string rows;
  for (const json& c : changes) {
    const std::string verdict = c["verdict"].get<std::string>();
    std::string words;
    const double d = c.value("delta_peak_kpa", json()).is_number() ? c["delta_peak_kpa"].get<double>() : NAN;
    if (verdict == "better")
      words = "better: peak " + fixed_digits(-d, 1, kDash) + " kPa lower";
    else if (verdict == "worse")
      words = "worse: peak " + fixed_digits(d, 1, kDash) + " kPa higher";
    else if (verdict == "unchanged") words = "unchanged within the uncertainty (" + signed_fixed(d, 1) + " kPa)";
    else if (verdict == "gone")
      words = "gone in B (was " +
              fixed_digits(c["a_peak_kpa"].is_number() ? c["a_peak_kpa"].get<double>() : NAN, 1, kDash) +
              " kPa)";
    else if (verdict == "new")
      words = "new in B (" +
              fixed_digits(c["b_peak_kpa"].is_number() ? c["b_peak_kpa"].get<double>() : NAN, 1, kDash) +
              " kPa)";
    else words = "unknown";
    auto id = [](const json& v) { return v.is_null() ? std::string(kDash) : html_escape(v.dump()); };
    auto kpa = [](const json& c, const char* k) {
      return c.contains(k) && c[k].is_number() ? fixed_digits(c[k].get<double>(), 2, kDash)
                                               : std::string(kDash);
    };
    rows += "<tr data-verdict=\"" + verdict + "\"><td>" + id(c["a_id"]) + "</td><td>" + id(c["b_id"]) + "</td><td>" + kpa(c, "a_peak_kpa") +
            "</td><td>" + kpa(c, "b_peak_kpa") + "</td><td>" + kpa(c, "delta_peak_kpa") + "</td><td>" + kpa(c, "delta_area_mm2") +
            "</td><td>" + html_escape(words) + "</td></tr>";
  }
  return rows;
}

}  // namespace

CompareResult compare_assessments(const fs::path& a_folder, const fs::path& b_folder, const fs::path& out,
                                  const CompareOptions& o) {
  o.validate();
  const Assessment A = load(a_folder, "A"), B = load(b_folder, "B");
  const detail::PageAssets assets = detail::load_page_assets(o.assets_dir.empty() ? default_report_assets_dir() : o.assets_dir);
  const Correspondence corr = correspond(A, B, o);
  CompareResult result;
  result.notes.push_back(
      corr.method == "same_vertices"
          ? "same mesh: vertices compared one to one"
          : "meshes differ: each seen vertex of B took the nearest seen vertex of A within " +
                fixed_digits(o.match_tolerance_mm, 3, kDash) + " mm (" +
                fixed_digits(100 * corr.matched_fraction, 1, kDash) + " % matched, farthest " +
                fixed_digits(corr.max_distance_mm, 3, kDash) + " mm)");

  // Per-vertex difference on B's vertices where both saw the skin.
  const std::size_t nb = B.glb.vertex_count();
  std::vector<float> diff(nb, NAN), pa(nb, NAN), pb(nb, NAN);
  std::size_t n = 0;
  double sum = 0, sum2 = 0, max_inc = -INFINITY, max_dec = INFINITY;
  for (std::size_t v = 0; v < nb; ++v) {
    const int a = corr.a_of_b[v];
    if (a < 0 || B.glb.seen[v] < 0.5f || A.glb.seen[a] < 0.5f) continue;
    pa[v] = A.pressure[a];
    pb[v] = B.pressure[v];
    diff[v] = pb[v] - pa[v];
    ++n;
    sum += diff[v];
    sum2 += static_cast<double>(diff[v]) * diff[v];
    max_inc = std::max(max_inc, static_cast<double>(diff[v]));
    max_dec = std::min(max_dec, static_cast<double>(diff[v]));
  }
  if (n == 0) throw InputError(b_folder.string(), "seen contact surface", "shares no seen vertex with " + a_folder.string());

  // Hotspots: greedy matching by centroid distance.
  const json ha = A.report.value("hotspots", json::array()), hb = B.report.value("hotspots", json::array());
  const json changes = hotspot_changes(ha, hb, o);
  // NaN never reaches the JSON: nlohmann writes it as null.

  fs::create_directories(out);
  result.json = out / "compare.json";
  result.glb = out / "difference.glb";
  result.html = out / "compare.html";

  // The difference heatmap on B's geometry (the glb's vertex set as a mesh).
  Mesh mesh;
  mesh.source = (b_folder / "heatmap.glb").string();
  for (std::size_t v = 0; v < nb; ++v)
    mesh.vertices.emplace_back(B.glb.position_mm[3 * v], B.glb.position_mm[3 * v + 1], B.glb.position_mm[3 * v + 2]);
  for (std::size_t t = 0; t + 2 < B.glb.triangles.size(); t += 3) {
    mesh.faces.push_back({static_cast<int>(B.glb.triangles[t]), static_cast<int>(B.glb.triangles[t + 1]), static_cast<int>(B.glb.triangles[t + 2])});
    mesh.file_face.push_back(static_cast<int>(t / 3));
  }
  HeatmapInput in;
  in.mesh = &mesh;
  in.values = diff;
  in.scalars = {{"_PRESSURE_DIFF_KPA", diff}, {"_PRESSURE_A_KPA", pa}, {"_PRESSURE_B_KPA", pb}};
  in.quantity = "pressure_difference_kpa";
  in.unit = "kPa";
  in.extras = {{"a", a_folder.string()}, {"b", b_folder.string()}};
  for (const json& h : hb) {
    const Eigen::Vector3d c = centroid(h);
    if (c.allFinite()) in.hotspots.push_back({h.value("id", 0), c, "B hotspot " + std::to_string(h.value("id", 0))});
  }
  const double max_abs = std::max({std::abs(max_inc), std::abs(max_dec), 0.1});
  write_difference_glb(in, max_abs, result.glb);

  result.summary = {
      {"schema", "clearfit.compare/1"},
      {"a", {{"folder", a_folder.string()}, {"created_utc", A.report.value("created_utc", json())}, {"mesh", A.report.value("part", json::object()).value("mesh", json())}}},
      {"b", {{"folder", b_folder.string()}, {"created_utc", B.report.value("created_utc", json())}, {"mesh", B.report.value("part", json::object()).value("mesh", json())}}},
      {"correspondence", {{"method", corr.method}, {"tolerance_mm", corr.method == "same_vertices" ? o.same_position_tolerance_mm : o.match_tolerance_mm},
                          {"matched_fraction", corr.matched_fraction}, {"max_distance_mm", corr.max_distance_mm}}},
      {"difference", {{"unit", "kPa"}, {"definition", "B - A"}, {"vertices", n}, {"mean_kpa", sum / n},
                      {"rms_kpa", std::sqrt(sum2 / n)}, {"max_increase_kpa", max_inc}, {"max_decrease_kpa", max_dec},
                      {"colormap", "coolwarm"}, {"range_kpa", {-max_abs, max_abs}}}},
      {"peak_kpa", {{"a", get(A.report.value("pressure", json::object()), "peak_kpa")}, {"b", get(B.report.value("pressure", json::object()), "peak_kpa")}}},
      {"hotspots", changes},
      {"notes", result.notes},
      {"outputs", {{"difference_glb", "difference.glb"}, {"compare_html", "compare.html"}}}};

  // compare.html: summary sentences, the difference in 3D, the hotspot table.
  std::string body = "<header><h1>Design comparison</h1><p class=\"meta\">A: " + html_escape(a_folder.string()) + " &middot; B: " +
                     html_escape(b_folder.string()) + "</p><ul class=\"summary\">";
  body +=
      "<li>Peak pressure " +
      fixed_digits(
          result.summary["peak_kpa"]["a"].is_number() ? result.summary["peak_kpa"]["a"].get<double>() : NAN,
          1, kDash) +
      " kPa &rarr; " +
      fixed_digits(
          result.summary["peak_kpa"]["b"].is_number() ? result.summary["peak_kpa"]["b"].get<double>() : NAN,
          1, kDash) +
      " kPa.</li>";
  body += "<li>Over the surface both saw, B &minus; A is " + signed_fixed(sum / n, 2) + " kPa on average; the largest rise " +
          signed_fixed(max_inc, 1) + " kPa, the largest drop " + signed_fixed(max_dec, 1) + " kPa.</li>";
  body += "<li>" + html_escape(result.notes[0]) + ".</li></ul></header>";
  const std::string rows = change_rows(changes);
  body += "<section id=\"hotspot-changes\"><h2>Hotspots: better or worse</h2>";
  body += changes.empty() ? "<p>Neither assessment has hotspots.</p>"
                          : "<table id=\"changes-table\" class=\"data\"><thead><tr><th>A #</th><th>B #</th><th>A peak (kPa)</th>"
                            "<th>B peak (kPa)</th><th>&Delta; peak (kPa)</th><th>&Delta; area (mm&sup2;)</th><th>verdict</th></tr></thead><tbody>" +
                                rows + "</tbody></table>";
  body += "</section>";
  const detail::HeatmapGlb diff_glb = detail::load_heatmap_glb(result.glb);
  std::vector<detail::PageView> views{{"difference", "Pressure difference B \xE2\x88\x92 A",
                                       detail::to_glb_bytes(detail::single_scene(diff_glb.model, diff_glb.model.defaultScene)),
                                       detail::colour_bar("difference", "coolwarm", -max_abs, max_abs, "kPa",
                                                          "Pressure difference B \xE2\x88\x92 A (blue: less pressure, red: more)")}};
  const auto [view_html, models] = detail::view_section(views, "", detail::skin_side_orbit(diff_glb));
  body = body.substr(0, body.find("<section")) + "<section id=\"view\"><h2>Where the pressure changed</h2>" + view_html +
         "</section>" + body.substr(body.find("<section"));
  write_file_atomically(result.json, result.summary.dump(2));
  write_file_atomically(result.html, detail::render_page(assets, "Design comparison", body, views, models));
  return result;
}

}  // namespace clearfit::reports
