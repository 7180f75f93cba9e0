// report.html from an assessment output folder (see report_html.hpp).
#include <clearfit/reports/report_html.hpp>

#include "report_html_glb.hpp"
#include "report_view.hpp"

#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/reports/colormap.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#ifndef CLEARFIT_REPORT_ASSETS_DIR
// Without the definition from CMake: reports/assets beside this source file.
#define CLEARFIT_REPORT_ASSETS_DIR ""
#endif

namespace clearfit::reports {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const char* const kDash = "\xE2\x80\x94";  // an em dash: "no value"

std::string read_binary(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), "", "cannot be read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string base64(const std::string& bytes) {
  return tinygltf::base64_encode(reinterpret_cast<const unsigned char*>(bytes.data()),
                                 static_cast<unsigned int>(bytes.size()));
}

// Fixed-point text of a finite number, never "-0.00" in the page; "—" otherwise (never "nan").
std::string fixed(double v, int digits) {
  const std::string s = fixed_digits(v, digits, kDash);
  return s.find_first_not_of("-0.") == std::string::npos ? fixed_digits(0.0, digits) : s;
}

bool is_number(const json& j) { return j.is_number() && std::isfinite(j.get<double>()); }

// A JSON value from report.json as escaped display text.
std::string num(const json& j, int digits) { return is_number(j) ? fixed(j.get<double>(), digits) : kDash; }
std::string percent(const json& j) { return is_number(j) ? fixed(100.0 * j.get<double>(), 1) + " %" : kDash; }
std::string text(const json& j) {
  if (j.is_string()) return html_escape(j.get<std::string>());
  if (j.is_boolean()) return j.get<bool>() ? "yes" : "no";
  if (j.is_number()) return is_number(j) ? html_escape(j.dump()) : kDash;
  if (j.is_null()) return kDash;
  return html_escape(j.dump(-1, ' ', false, json::error_handler_t::replace));
}
// The value at `key` of an object, null when absent or when `j` is no object.
const json& at(const json& j, const char* key) {
  static const json null;
  if (!j.is_object()) return null;
  const auto it = j.find(key);
  return it == j.end() ? null : *it;
}

// A table cell whose display text is rounded; data-value keeps the exact JSON value.
std::string cell(const char* key, const json& value, const std::string& shown) {
  return std::string("<td data-key=\"") + key + "\" data-value=\"" +
         html_escape(value.is_null() ? std::string() : value.dump(-1, ' ', false, json::error_handler_t::replace)) +
         "\">" + shown + "</td>";
}

// JSON safe inside <script>: no "<", ">" or "&" that could close the element.
std::string script_json(const json& j) {
  std::string s = j.dump(-1, ' ', true, json::error_handler_t::replace);
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    if (c == '<') out += "\\u003c";
    else if (c == '>') out += "\\u003e";
    else if (c == '&') out += "\\u0026";
    else out += c;
  }
  return out;
}

// Replaces every {{name}} of the template in one pass (inserted text is never re-scanned).
std::string fill_template(const std::string& tpl, const std::map<std::string, std::string>& slots, const fs::path& file) {
  std::string out;
  std::size_t pos = 0;
  for (;;) {
    const std::size_t open = tpl.find("{{", pos);
    if (open == std::string::npos) break;
    const std::size_t close = tpl.find("}}", open);
    if (close == std::string::npos) throw InputError(file.string(), "template", "has an unclosed '{{'");
    const std::string name = tpl.substr(open + 2, close - open - 2);
    const auto it = slots.find(name);
    if (it == slots.end()) throw InputError(file.string(), "slot {{" + name + "}}", "is not known to this clearfit");
    out.append(tpl, pos, open - pos);
    out += it->second;
    pos = close + 2;
  }
  out.append(tpl, pos, std::string::npos);
  return out;
}

// Round tick values over [lo, hi]: steps of 1, 2, 2.5 or 5 × 10^k, about five of them.
std::vector<double> ticks(double lo, double hi) {
  const double raw = (hi - lo) / 5;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  std::vector<double> t;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) t.push_back(std::abs(v) < 1e-12 * step ? 0 : v);
  return t;
}

std::string hex(const Rgb8& c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", c.r, c.g, c.b);
  return buf;
}

// The colour bar of one view: a CSS gradient sampled from the colormap and round ticks.
std::string colour_bar(const std::string& view, const std::string& colormap, double lo, double hi, const std::string& unit,
                       const std::string& caption) {
  const Colormap& cm = Colormap::get(colormap);
  std::string stops;
  for (int k = 0; k <= 16; ++k) stops += (k ? "," : "") + hex(cm.srgb8(k / 16.0)) + " " + fixed(100.0 * k / 16, 2) + "%";
  const double span = hi - lo;
  auto label = [](double t) {  // shortest of up to 6 decimals
    std::string s = fixed(t, 6);
    if (s.find('.') != std::string::npos) s.erase(s.find_last_not_of('0') + 1);
    if (s.back() == '.') s.pop_back();
    return s;
  };
  std::string s = "<div class=\"colorbar\" data-view=\"" + view + "\" data-lo=\"" + fixed(lo, 6) + "\" data-hi=\"" +
                  fixed(hi, 6) + "\"><div class=\"colorbar-caption\">" + html_escape(caption) +
                  (unit.empty() ? "" : " (" + html_escape(unit) + ")") +
                  "</div><div class=\"colorbar-ramp\" style=\"background:linear-gradient(to right," + stops +
                  ")\"></div><div class=\"colorbar-ticks\">";
  for (double t : ticks(lo, hi))
    s += "<span style=\"left:" + fixed(100 * (t - lo) / span, 2) + "%\">" + label(t) + "</span>";
  s += "</div><div class=\"colorbar-nodata\"><span class=\"swatch\" style=\"background:" + hex(cm.no_data_srgb8()) +
       "\"></span> not seen or not on the contact surface</div></div>";
  return s;
}

// The model reduced to one scene: its nodes (reachable from `scene`) and their
// meshes, renumbered; everything else is dropped from the node and mesh lists
// (accessors and materials stay). model-viewer loads every scene of a file and
// logs console errors for meshes outside the one it shows.
tinygltf::Model single_scene(tinygltf::Model model, int scene) {
  if (scene < 0 || scene >= static_cast<int>(model.scenes.size())) return model;
  std::vector<int> node_map(model.nodes.size(), -1), mesh_map(model.meshes.size(), -1);
  std::vector<tinygltf::Node> nodes;
  std::vector<tinygltf::Mesh> meshes;
  std::vector<int> stack(model.scenes.at(scene).nodes.rbegin(), model.scenes.at(scene).nodes.rend());
  std::vector<int> order;
  while (!stack.empty()) {
    const int n = stack.back();
    stack.pop_back();
    if (node_map.at(n) >= 0) continue;
    node_map[n] = static_cast<int>(order.size());
    order.push_back(n);
    for (auto c = model.nodes[n].children.rbegin(); c != model.nodes[n].children.rend(); ++c) stack.push_back(*c);
  }
  for (int n : order) {
    tinygltf::Node node = model.nodes[n];
    for (int& c : node.children) c = node_map[c];
    if (node.mesh >= 0) {
      if (mesh_map[node.mesh] < 0) {
        mesh_map[node.mesh] = static_cast<int>(meshes.size());
        meshes.push_back(model.meshes[node.mesh]);
      }
      node.mesh = mesh_map[node.mesh];
    }
    nodes.push_back(std::move(node));
  }
  tinygltf::Scene only = model.scenes[scene];
  for (int& n : only.nodes) n = node_map[n];
  model.nodes = std::move(nodes);
  model.meshes = std::move(meshes);
  model.scenes = {only};
  model.defaultScene = 0;
  return model;
}

using View = detail::PageView;

// A view's model as glb bytes: the scene `scene` alone, with the part beside the contact surface (the
// primitives whose indices are named "rest" by write_heatmap_glb) lit, in its vertex colours (the grey of
// no data), so that the part's shape and outline read in the view, apart from the flat, unlit heatmap and its
// unseen grey.
std::string view_glb(tinygltf::Model model, int scene) {
  tinygltf::Material part;
  part.name = "part (lit)";
  part.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
  part.pbrMetallicRoughness.metallicFactor = 0;
  part.pbrMetallicRoughness.roughnessFactor = 0.9;
  part.doubleSided = true;
  const int material = static_cast<int>(model.materials.size());
  bool used = false;
  for (tinygltf::Mesh& mesh : model.meshes)
    for (tinygltf::Primitive& p : mesh.primitives)
      if (p.indices >= 0 && p.indices < static_cast<int>(model.accessors.size()) && model.accessors[p.indices].name == "rest") {
        p.material = material, used = true;
      }
  if (used) model.materials.push_back(part);
  return detail::to_glb_bytes(single_scene(std::move(model), scene));
}

// The views of the 3D section from heatmap.glb: what the file shows (pressure,
// or the signal when uncalibrated) and, when the file is a pressure heatmap
// with a _BLANCH attribute, the same mesh recoloured by the blanching signal.
// A heatmap of more than max_view_triangles triangles (0: no limit) is
// simplified first, for every view alike (report_view.hpp).
json hover_vertices(const detail::HeatmapGlb& g, bool calibrated);

std::vector<View> make_views(const detail::HeatmapGlb& full, const json& report, std::size_t max_view_triangles,
                             std::vector<std::string>& notes, json& hover) {
  std::optional<detail::HeatmapGlb> simplified;
  if (const std::size_t n = full.triangles.size() / 3; max_view_triangles > 0 && n > max_view_triangles) {
    simplified = detail::simplify_heatmap_for_view(full, max_view_triangles);
    if (simplified)
      notes.push_back("3D view simplified from " + std::to_string(n) + " to " +
                      std::to_string(simplified->triangles.size() / 3) + " triangles (heatmap.glb keeps all " +
                      std::to_string(n) + ")");
    else
      notes.push_back("3D view shows all " + std::to_string(n) +
                      " triangles: heatmap.glb's layout (sparse accessors or unshared indices) cannot be simplified");
  }
  const detail::HeatmapGlb& g = simplified ? *simplified : full;
  hover = hover_vertices(g, at(at(report, "calibration"), "pressure").is_object());  // the vertices drawn
  std::vector<View> views;
  const std::string quantity = at(g.info, "quantity").is_string() ? g.info["quantity"].get<std::string>() : "pressure_kpa";
  const std::string colormap = at(g.info, "colormap").is_string() ? g.info["colormap"].get<std::string>() : "viridis";
  double lo = 0, hi = 1;
  if (const json& r = at(g.info, "range"); r.is_array() && r.size() == 2 && is_number(r[0]) && is_number(r[1]) &&
                                           r[0].get<double>() < r[1].get<double>()) {
    lo = r[0].get<double>();
    hi = r[1].get<double>();
  }
  const std::string unit = at(g.info, "unit").is_string() ? g.info["unit"].get<std::string>() : "";
  const bool pressure = quantity == "pressure_kpa";
  const int default_scene = g.model.defaultScene >= 0 ? g.model.defaultScene : 0;
  views.push_back({pressure ? "pressure" : "signal", pressure ? "Pressure" : "Blanching signal",
                   view_glb(g.model, default_scene),
                   colour_bar(pressure ? "pressure" : "signal", colormap, lo, hi, unit,
                              pressure ? "Pressure" : "Blanching signal (relative)")});
  const std::vector<float> blanch = g.scalar("_BLANCH");
  if (!pressure || blanch.empty()) {
    if (pressure) notes.push_back("heatmap.glb has no _BLANCH attribute: the 3D view shows pressure only");
    return views;
  }
  // Signal view: the vertex-colour scene, COLOR_0 rewritten in place from _BLANCH
  // over [0, 99th percentile of the seen vertices' signal].
  tinygltf::Model model = g.model;
  const auto& attributes = model.meshes[g.mesh].primitives[0].attributes;
  const auto colour = attributes.find("COLOR_0");
  const json& scenes = at(g.info, "scenes");
  if (colour == attributes.end() || !at(scenes, "vertex_colors").is_number_integer()) {
    notes.push_back("heatmap.glb has no vertex-colour scene: the 3D view shows pressure only");
    return views;
  }
  std::vector<float> seen_signal;
  for (std::size_t v = 0; v < blanch.size(); ++v)
    if (g.seen[v] > 0.5f && std::isfinite(blanch[v])) seen_signal.push_back(blanch[v]);
  double s_hi = 0;
  if (!seen_signal.empty()) {
    const std::size_t k = static_cast<std::size_t>(0.99 * (seen_signal.size() - 1));
    std::nth_element(seen_signal.begin(), seen_signal.begin() + k, seen_signal.end());
    s_hi = seen_signal[k];
  }
  if (!(s_hi > 0)) s_hi = std::max(1e-3, std::abs(at(at(report, "signal"), "noise_sigma").is_number() ? report["signal"]["noise_sigma"].get<double>() * 3 : 0.0));
  const Colormap& cm = Colormap::get(colormap);
  tinygltf::Accessor& acc = model.accessors.at(colour->second);
  const int components = tinygltf::GetNumComponentsInType(acc.type);
  if (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || (components != 3 && components != 4)) {
    notes.push_back("heatmap.glb's COLOR_0 is not float RGB: the 3D view shows pressure only");
    return views;
  }
  const tinygltf::BufferView& bv = model.bufferViews.at(acc.bufferView);
  const int stride = acc.ByteStride(bv) > 0 ? acc.ByteStride(bv) : 4 * components;
  unsigned char* base = model.buffers.at(bv.buffer).data.data() + bv.byteOffset + acc.byteOffset;
  const Eigen::Vector3f grey = cm.no_data_linear();
  for (std::size_t v = 0; v < acc.count && v < blanch.size(); ++v) {
    const Eigen::Vector3f c = g.seen[v] > 0.5f ? cm.linear(normalise_to_range(blanch[v], 0.0, s_hi)) : grey;
    std::memcpy(base + v * stride, c.data(), 3 * sizeof(float));
  }
  acc.minValues.clear();
  acc.maxValues.clear();
  views.push_back({"signal", "Blanching signal", view_glb(std::move(model), scenes["vertex_colors"].get<int>()),
                   colour_bar("signal", colormap, 0.0, s_hi, "", "Blanching signal (relative)")});
  return views;
}

// "12.4 ± 0.3" of a level's area (mm²).
std::string level_area(const json& level) {
  const json& sigma = at(level, "area_sigma_mm2");
  return num(at(level, "area_mm2"), 1) + (is_number(sigma) && sigma.get<double>() > 0 ? " &plusmn; " + num(sigma, 1) : "");
}

// The seen vertices of a view for report.js's hover, as base64 of little-endian float32 rows
// (x, y, z mm, kPa, kPa σ, signal; NaN where the glb has no such attribute or no value) and uint32 mesh
// vertex ids; reach_mm, three times the median edge of the seen triangles: a surface point farther than
// that from every seen vertex lies where the camera does not see. The σ is NaN where the glb's
// _PRESSURE_SIGMA_KPA is 0, its "none": below detection (0 kPa, a bound) and saturated (a lower bound).
json hover_vertices(const detail::HeatmapGlb& g, bool calibrated) {
  const double scale = is_number(at(g.info, "node_scale")) ? g.info["node_scale"].get<double>() : 0.001;
  const std::vector<float> kpa = g.scalar("_PRESSURE_KPA"), sigma = g.scalar("_PRESSURE_SIGMA_KPA"), signal = g.scalar("_BLANCH");
  auto value = [](const std::vector<float>& a, std::size_t v, bool wanted) { return wanted && !a.empty() ? a[v] : NAN; };
  std::vector<float> rows;
  std::vector<std::uint32_t> ids;
  for (std::size_t v = 0; v < g.vertex_count(); ++v) {
    if (g.seen[v] < 0.5f) continue;
    ids.push_back(static_cast<std::uint32_t>(v));
    rows.insert(rows.end(), {g.position_mm[3 * v], g.position_mm[3 * v + 1], g.position_mm[3 * v + 2], value(kpa, v, calibrated),
                             value(sigma, v, calibrated) > 0 ? value(sigma, v, calibrated) : NAN, value(signal, v, true)});
  }
  std::vector<double> edges;
  for (std::size_t t = 0; t + 2 < g.triangles.size(); t += 3)
    for (int e = 0; e < 3; ++e) {
      const std::uint32_t a = g.triangles[t + e], b = g.triangles[t + (e + 1) % 3];
      if (g.seen[a] < 0.5f || g.seen[b] < 0.5f) continue;
      const Eigen::Vector3f d = Eigen::Vector3f(&g.position_mm[3 * a]) - Eigen::Vector3f(&g.position_mm[3 * b]);
      edges.push_back(d.norm());
    }
  if (ids.empty() || edges.empty()) return nullptr;
  std::nth_element(edges.begin(), edges.begin() + static_cast<std::ptrdiff_t>(edges.size() / 2), edges.end());
  auto bytes = [](const auto& v) { return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0])); };
  return {{"node_scale", scale},   {"reach_mm", 3 * edges[edges.size() / 2]}, {"count", ids.size()}, {"calibrated", calibrated},
          {"rows", base64(bytes(rows))}, {"ids", base64(bytes(ids))}};
}

// Where a place's marker stands in the 3D view: beside the place, not on it. The place is the seen vertices
// joined by triangles to the one nearest its centroid whose value (kPa, or the signal without a calibration)
// reaches its lowest threshold. Directions in the surface's tangent plane at the centroid are tried in turn,
// up-right first (up: the model's +y, which model-viewer keeps up, seen from the normal's side); the marker goes
// to the seen vertex nearest to the place's farthest extent along the direction plus `margin_mm`, accepted when
// it lies within margin_mm/2 of that point and at least margin_mm/2 beyond the extent, below the threshold
// (outside every place), at least margin_mm from the other places' centroids and 1.3 margin_mm from the
// markers placed before it (labels side by side). A
// second round drops the last two conditions; then the marker falls back to the vertex nearest the centroid.
struct MarkerAnchor {
  std::size_t vertex = 0, centroid_vertex = 0;
  bool found = false, beside = false;
};

class MarkerPlacer {
 public:
  MarkerPlacer(const detail::HeatmapGlb& g, bool calibrated) : g_(g), value_(g.scalar(calibrated ? "_PRESSURE_KPA" : "_BLANCH")) {
    const std::size_t n = g.vertex_count();
    std::vector<std::size_t> degree(n + 1, 0);
    for (std::size_t t = 0; t + 2 < g.triangles.size(); t += 3)
      for (int e = 0; e < 3; ++e) degree[g.triangles[t + e] + 1] += 2;
    for (std::size_t v = 0; v < n; ++v) degree[v + 1] += degree[v];
    first_ = degree;
    neighbours_.resize(degree[n]);
    for (std::size_t t = 0; t + 2 < g.triangles.size(); t += 3)
      for (int e = 0; e < 3; ++e) {
        const std::uint32_t a = g.triangles[t + e], b = g.triangles[t + (e + 1) % 3];
        neighbours_[degree[a]++] = b, neighbours_[degree[b]++] = a;
      }
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
    for (std::size_t v = 0; v < n; ++v) lo = lo.cwiseMin(position(v)), hi = hi.cwiseMax(position(v));
    // About 22 px of the view (half the 26 px label's diagonal and a gap): the page frames the whole part,
    // some 0.4 of the view's width for the model's diagonal.
    margin_mm_ = n > 0 ? std::max(0.2, 0.05 * (hi - lo).norm()) : 0.0;
  }

  Eigen::Vector3d position(std::size_t v) const {
    return {g_.position_mm[3 * v], g_.position_mm[3 * v + 1], g_.position_mm[3 * v + 2]};
  }

  /// `others`: the other places' centroids; the markers placed so far are remembered.
  MarkerAnchor place(const Eigen::Vector3d& centroid, double threshold, const std::vector<Eigen::Vector3d>& others) {
    MarkerAnchor a;
    a.found = nearest_seen(centroid, a.centroid_vertex);
    a.vertex = a.centroid_vertex;
    if (!a.found || value_.empty() || !std::isfinite(threshold)) return a;
    const std::vector<std::size_t> members = flood(a.centroid_vertex, threshold);
    Eigen::Vector3d n = g_.normal.empty() ? Eigen::Vector3d::UnitZ()
                                          : Eigen::Vector3d(g_.normal[3 * a.vertex], g_.normal[3 * a.vertex + 1], g_.normal[3 * a.vertex + 2]);
    if (!(n.norm() > 0)) n = Eigen::Vector3d::UnitZ();
    n.normalize();
    Eigen::Vector3d up = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(n) * n;
    if (up.norm() < 1e-6) up = Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(n) * n;
    up.normalize();
    const Eigen::Vector3d right = up.cross(n);
    auto far_from = [&](const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& points, double d) {
      return std::all_of(points.begin(), points.end(), [&](const Eigen::Vector3d& q) { return (p - q).norm() >= d; });
    };
    for (const bool apart : {true, false})
      for (double deg : {45.0, 90.0, 0.0, 135.0, -45.0, 180.0, -90.0, -135.0}) {
        const double r = deg * M_PI / 180;
        const Eigen::Vector3d u = std::cos(r) * right + std::sin(r) * up;
        double extent = 0;
        for (std::size_t m : members) extent = std::max(extent, (position(m) - centroid).dot(u));
        const Eigen::Vector3d target = centroid + (extent + margin_mm_) * u;
        std::size_t v = 0;
        if (!nearest_seen(target, v) || (position(v) - target).norm() > 0.5 * margin_mm_ ||
            (position(v) - centroid).dot(u) < extent + 0.5 * margin_mm_ || !(value_[v] < threshold))
          continue;
        if (apart && !(far_from(position(v), others, margin_mm_) && far_from(position(v), placed_, 1.3 * margin_mm_))) continue;
        a.vertex = v, a.beside = true;
        placed_.push_back(position(v));
        return a;
      }
    return a;
  }

 private:
  bool nearest_seen(const Eigen::Vector3d& p, std::size_t& out) const {
    double best = INFINITY;
    for (std::size_t v = 0; v < g_.vertex_count(); ++v)
      if (g_.seen[v] >= 0.5f)
        if (const double d = (position(v) - p).squaredNorm(); d < best) best = d, out = v;
    return std::isfinite(best);
  }
  // The seen vertices at or above the threshold joined to `start` by triangle edges (start always in).
  std::vector<std::size_t> flood(std::size_t start, double threshold) const {
    std::vector<std::size_t> members{start}, stack{start};
    std::vector<char> visited(g_.vertex_count(), 0);
    visited[start] = 1;
    while (!stack.empty()) {
      const std::size_t v = stack.back();
      stack.pop_back();
      for (std::size_t k = first_[v]; k < first_[v + 1]; ++k) {
        const std::size_t w = neighbours_[k];
        if (visited[w] || g_.seen[w] < 0.5f || !(value_[w] >= threshold)) continue;
        visited[w] = 1;
        members.push_back(w);
        stack.push_back(w);
      }
    }
    return members;
  }

  const detail::HeatmapGlb& g_;
  std::vector<float> value_;
  std::vector<std::size_t> first_;
  std::vector<std::uint32_t> neighbours_;
  double margin_mm_ = 0;
  std::vector<Eigen::Vector3d> placed_;
};

// The lowest threshold of a place (its outline's), in the heatmap's quantity; NaN when not given.
double lowest_threshold(const json& h, bool calibrated) {
  const json& lv = at(h, "levels");
  const json& t = lv.is_array() && !lv.empty() ? at(lv[0], calibrated ? "threshold_kpa" : "threshold_signal") : json();
  return is_number(t) ? t.get<double>() : NAN;
}

// A hotspot's numbers for the panel its marker opens.
std::string hotspot_info(const json& h, const std::string& id, bool calibrated) {
  std::string s = "<div class=\"hotspot-info\" data-hotspot-info=\"" + id + "\" hidden><b>Hotspot " + id + "</b><br>";
  if (calibrated)
    s += "peak " + num(at(h, "peak_kpa"), 2) + " &plusmn; " + num(at(h, "peak_sigma_kpa"), 2) + " kPa<br>mean " +
         num(at(h, "mean_kpa"), 2) + " &plusmn; " + num(at(h, "mean_sigma_kpa"), 2) + " kPa<br>";
  else
    s += "peak signal " + num(at(h, "peak_signal"), 4) + "<br>mean signal " + num(at(h, "mean_signal"), 4) + "<br>";
  const json& lv = at(h, "levels");
  if (lv.is_array())
    for (const json& level : lv) {
      const json& t = at(level, calibrated ? "threshold_kpa" : "threshold_signal");
      s += "area &ge; " + num(t, calibrated ? 1 : 4) + (calibrated ? " kPa" : "") + ": " + level_area(level) + " mm&sup2;<br>";
    }
  if (is_number(at(h, "centroid_sigma_mm"))) s += "centroid &plusmn; " + num(at(h, "centroid_sigma_mm"), 2) + " mm<br>";
  if (is_number(at(h, "centre_of_pressure_sigma_mm")))
    s += "centre of pressure &plusmn; " + num(at(h, "centre_of_pressure_sigma_mm"), 2) + " mm<br>";
  if (is_number(at(h, "unseen_area_mm2")) && h["unseen_area_mm2"].get<double>() > 0)
    s += "unseen beside it: " + num(at(h, "unseen_area_mm2"), 1) + " mm&sup2;<br>";
  return s + "</div>";
}

// Hotspot markers of the 3D view, numbered as report.json's ids (the chart image's labels and the table's
// rows), each beside its place (MarkerPlacer) on a seen vertex with that vertex's normal, in the scene's
// metres (the part node's scale); data-centroid is the place's centroid (a point on the contact surface).
std::string hotspot_markers(const detail::HeatmapGlb* g, const json& hotspots, bool calibrated) {
  std::string s;
  if (!hotspots.is_array()) return s;
  const double scale = is_number(at(g ? g->info : json(), "node_scale")) ? g->info["node_scale"].get<double>() : 0.001;
  std::optional<MarkerPlacer> placer;
  if (g && g->vertex_count() > 0) placer.emplace(*g, calibrated);
  auto xyz = [](const Eigen::Vector3d& v, double k) { return fixed(k * v[0], 7) + " " + fixed(k * v[1], 7) + " " + fixed(k * v[2], 7); };
  std::vector<Eigen::Vector3d> centroids;
  std::vector<const json*> placed;
  for (const json& h : hotspots) {
    const json& c = at(h, "centroid_mm");
    if (!(c.is_array() && c.size() == 3 && is_number(c[0]) && is_number(c[1]) && is_number(c[2]))) continue;
    centroids.emplace_back(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
    placed.push_back(&h);
  }
  for (std::size_t k = 0; k < placed.size(); ++k) {
    const json& h = *placed[k];
    Eigen::Vector3d p = centroids[k], centre = p, n(0, 0, 1);
    bool have_normal = false;
    if (placer) {
      std::vector<Eigen::Vector3d> others = centroids;
      others.erase(others.begin() + static_cast<std::ptrdiff_t>(k));
      const MarkerAnchor a = placer->place(p, lowest_threshold(h, calibrated), others);
      if (a.found) {
        p = placer->position(a.vertex);
        if (!g->normal.empty()) n = Eigen::Vector3d(g->normal[3 * a.vertex], g->normal[3 * a.vertex + 1], g->normal[3 * a.vertex + 2]), have_normal = true;
      }
    }
    const std::string id = text(at(h, "id"));
    s += "<button class=\"hotspot\" slot=\"hotspot-" + id + "\" data-hotspot=\"" + id + "\" data-position=\"" + xyz(p, scale) +
         "\" data-centroid=\"" + xyz(centre, scale) + "\"";
    if (have_normal) s += " data-normal=\"" + xyz(n, 1) + "\" data-visibility-attribute=\"visible\"";
    s += " aria-label=\"hotspot " + id + "\">" + id + "</button>" + hotspot_info(h, id, calibrated);
  }
  return s;
}

// model-viewer's camera-orbit looking at the contact surface from the skin
// side: the mean normal of the seen vertices (glTF frame: model-viewer's theta
// turns about +y from +z, phi is measured from +y). Empty when undefined.
std::string skin_side_orbit(const detail::HeatmapGlb& g) {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  for (std::size_t v = 0; v < g.vertex_count() && !g.normal.empty(); ++v)
    if (g.seen[v] > 0.5f) d += Eigen::Vector3d(g.normal[3 * v], g.normal[3 * v + 1], g.normal[3 * v + 2]);
  if (!(d.norm() > 1e-9)) return {};
  d.normalize();
  const double theta = std::atan2(d.x(), d.z()), phi = std::acos(std::clamp(d.y(), -1.0, 1.0));
  return fixed(theta, 4) + "rad " + fixed(phi, 4) + "rad auto";
}

std::string row(std::initializer_list<std::string> cells) {
  std::string s = "<tr>";
  for (const auto& c : cells) s += c;
  return s + "</tr>";
}
std::string th(const std::string& t) { return "<th scope=\"row\">" + t + "</th>"; }
std::string td(const std::string& t) { return "<td>" + t + "</td>"; }

// "4.3 and 5.5 kPa" from thresholds_kpa.
std::string thresholds_text(const json& report) {
  const json& t = at(report, "thresholds_kpa");
  std::vector<std::string> parts;
  if (t.is_array())
    for (const json& v : t) parts.push_back(num(v, 1));
  else if (is_number(t))
    parts.push_back(num(t, 1));
  if (parts.empty()) return kDash;
  std::string s = parts[0];
  for (std::size_t i = 1; i < parts.size(); ++i) s += (i + 1 == parts.size() ? " and " : ", ") + parts[i];
  return s + " kPa";
}

// One row per place; its area (± σ) at each threshold in one column per threshold.
std::string hotspot_table(const json& report, bool calibrated) {
  const json& hotspots = at(report, "hotspots");
  if (!hotspots.is_array() || hotspots.empty())
    return calibrated ? "<p id=\"no-hotspots\">No hotspots: no region reaches the thresholds (" + thresholds_text(report) +
                            ").</p>"
                      : "<p id=\"no-hotspots\">No hotspots: no region of significant blanching.</p>";
  const json& thresholds = at(report, calibrated ? "thresholds_kpa" : "thresholds_signal");
  const std::size_t levels = thresholds.is_array() ? thresholds.size() : 0;
  const std::string unit = calibrated ? "kPa" : "";
  std::string s = "<table id=\"hotspot-table\" class=\"data\"><thead><tr><th>#</th>";
  s += calibrated ? "<th>peak (kPa)</th><th>peak &sigma; (kPa)</th><th>mean (kPa)</th><th>mean &sigma; (kPa)</th>"
                  : "<th>peak signal</th><th>mean signal</th>";
  for (std::size_t l = 0; l < levels; ++l)
    s += "<th>area &ge; " + num(thresholds[l], calibrated ? 1 : 4) + (calibrated ? " kPa" : "") + " (mm&sup2;)</th>";
  s += "<th>centroid x, y, z (mm)</th><th>centroid &sigma; (mm)</th><th>centre of pressure &sigma; (mm)</th><th>unseen beside it (mm&sup2;)</th><th>saturated texels</th><th>at glare</th></tr></thead><tbody>";
  for (const json& h : hotspots) {
    const json& c = at(h, "centroid_mm");
    std::string centroid = kDash;
    if (c.is_array() && c.size() == 3) centroid = num(c[0], 2) + ", " + num(c[1], 2) + ", " + num(c[2], 2);
    s += "<tr data-hotspot=\"" + text(at(h, "id")) + "\">" + cell("id", at(h, "id"), text(at(h, "id")));
    if (calibrated)
      s += cell("peak_kpa", at(h, "peak_kpa"), num(at(h, "peak_kpa"), 2)) +
           cell("peak_sigma_kpa", at(h, "peak_sigma_kpa"), num(at(h, "peak_sigma_kpa"), 2)) +
           cell("mean_kpa", at(h, "mean_kpa"), num(at(h, "mean_kpa"), 2)) +
           cell("mean_sigma_kpa", at(h, "mean_sigma_kpa"), num(at(h, "mean_sigma_kpa"), 2));
    else
      s += cell("peak_signal", at(h, "peak_signal"), num(at(h, "peak_signal"), 4)) +
           cell("mean_signal", at(h, "mean_signal"), num(at(h, "mean_signal"), 4));
    const json& lv = at(h, "levels");
    for (std::size_t l = 0; l < levels; ++l) {
      const json& level = lv.is_array() && l < lv.size() ? lv[l] : json();
      const std::string key = "area_mm2_" + std::to_string(l);
      s += cell(key.c_str(), at(level, "area_mm2"), level_area(level));
    }
    const json& unseen = at(h, "unseen_area_mm2");
    s += cell("centroid_mm", c, centroid) + cell("centroid_sigma_mm", at(h, "centroid_sigma_mm"), num(at(h, "centroid_sigma_mm"), 2)) +
         cell("centre_of_pressure_sigma_mm", at(h, "centre_of_pressure_sigma_mm"), num(at(h, "centre_of_pressure_sigma_mm"), 2)) +
         cell("unseen_area_mm2", unseen,
              num(unseen, 1) + (is_number(unseen) && unseen.get<double>() > 0 ? " (" + percent(at(h, "unseen_share")) + ")" : "")) +
         cell("saturated_texels", at(h, "saturated_texels"), text(at(h, "saturated_texels"))) +
         cell("touches_glare", at(h, "touches_glare"), at(h, "touches_glare") == json(true) ? "yes: may extend under the mask" : "no") +
         "</tr>";
  }
  return s + "</tbody></table><p class=\"hint\">Each place once: its outline is the lowest threshold; the higher thresholds' "
             "areas lie inside it. Unseen beside it: contact surface within 1 mm that the camera does not see (a wall seen "
             "edge-on); it may be pressed too, and is counted neither as pressed nor as 0 (the share is of the place's seen and "
             "unseen area).</p>";
}

std::string coverage_table(const json& report) {
  const json& c = at(report, "coverage");
  const json& hidden = at(c, "hidden_fraction");
  std::string s = "<table id=\"coverage-table\" class=\"facts\"><tbody>";
  s += row({th("contact surface"), td(num(at(c, "contact_area_mm2"), 1) + " mm&sup2;")});
  s += row({th("seen by the camera"), td(num(at(c, "seen_area_mm2"), 1) + " mm&sup2; (" + percent(at(c, "seen_fraction")) + ")")});
  s += row({th("hidden: total internal reflection"),
            td(percent(at(hidden, "total_internal_reflection")) +
               " <span class=\"why\">the camera sees a reflection inside the part there, not the skin</span>")});
  s += row({th("hidden: outside the view"),
            td(percent(at(hidden, "outside_view")) + " <span class=\"why\">outside the image or behind other parts of the part</span>")});
  s += row({th("hidden: other"), td(percent(at(hidden, "other")) + " <span class=\"why\">rays that leave through another face, or missed frames</span>")});
  if (const json& u = at(c, "pressed_unseen_mm2"); is_number(u) && u.get<double>() > 0)
    s += row({th("unseen beside the hotspots"),
              td(num(u, 1) + " mm&sup2; = " + percent(at(c, "pressed_unseen_share")) +
                 " of the hotspots' seen and unseen area <span class=\"why\">contact surface within 1 mm of a hotspot that the camera "
                 "does not see (a wall seen edge-on): it may be pressed too, and is counted neither as pressed nor as 0</span>")});
  if (const json& g = at(hidden, "glare"); is_number(g))
    s += row({th("hidden: glare"), td(percent(g) + " (" + num(at(c, "glare_masked_mm2"), 1) +
                                      " mm&sup2;) <span class=\"why\">specular reflections of the part, masked (grey in the pictures)</span>")});
  return s + "</tbody></table>";
}

std::string calibration_table(const json& report) {
  const json& cal = at(report, "calibration");
  const json& cam = at(cal, "camera");
  const json& pose = at(cal, "pose");
  const json& p = at(cal, "pressure");
  std::string s = "<table id=\"calibration-table\" class=\"facts\"><tbody>";
  s += row({th("camera reprojection RMS"), td(is_number(at(cam, "rms_px")) ? num(cam["rms_px"], 3) + " px" : "not known")});
  if (const json& worst = at(cam, "worst_views"); worst.is_array() && !worst.empty())
    s += row({th("camera: worst views"), td(text(worst))});
  s += row({th("camera model"), td(text(at(cam, "source")))});
  s += row({th("pose of the part"), td(text(at(pose, "source")))});
  s += row({th("pose uncertainty"), td(is_number(at(pose, "uncertainty_mm"))
                                          ? num(pose["uncertainty_mm"], 3) + " mm, " + num(at(pose, "uncertainty_deg"), 3) + "&deg;"
                                          : "not known")});
  if (const json& b = at(report, "baseline_geometry"); b.is_object()) {
    const std::string part = text(at(b, "part")), source = text(at(b, "gap_source"));
    std::string what = part == "touching" ? "the part touching the skin, as when worn"
                       : part == "absent" ? "without the part, the skin " + num(at(b, "gap_mm"), 2)
                                          : "the part held " + num(at(b, "gap_mm"), 2);
    if (part != "touching") {
      what += source == "given" ? " mm" : " &plusmn; " + num(at(b, "gap_sigma_mm"), 2) + " mm";
      what += part == "absent" ? " beyond the contact surface" : " off the skin";
      what += source == "given" ? " (given)" : source == "estimated" ? " (estimated from the captures)" : " (estimate unsure)";
    }
    s += row({th("not-worn capture"), "<td data-key=\"baseline-gap\">" + what + "</td>"});
    if (const json& t = at(b, "signal_sigma_from_gap"); t.is_object())
      s += row({th("the gap's &sigma; in the signal"),
                "<td data-key=\"gap-signal-sigma\">median " + num(at(t, "median"), 5) + ", at most " + num(at(t, "max"), 4) +
                    " (in each texel's &sigma; and detection gate; largest where the part is seen obliquely); " +
                    num(at(t, "unseen_mm2"), 2) + " mm&sup2; at the seen skin's edge, which the gap's &sigma; moves, left unseen</td>"});
  }
  if (p.is_object()) {
    s += row({th("pressure calibration"), td(text(at(p, "source")) + " (person: " + text(at(p, "person")) + ")")});
    s += row({th("model"), td(text(at(p, "model")) + ": p50 " + num(at(p, "p50_kpa"), 2) + " kPa, width " +
                              num(at(p, "width_kpa"), 2) + " kPa, y_max " + num(at(p, "y_max"), 4))});
    s += row({th("pressure-model RMSE"), td(num(at(p, "rmse_kpa"), 2) + " kPa")});
    const json& ref = at(p, "reference_r2");
    s += row({th("R&sup2; (this calibration)"),
              "<td data-key=\"r2\">" + num(at(p, "r2"), 3) + " (linear fit " + num(at(p, "linear_r2"), 3) +
                  "; the study's linear fit reached " + (is_number(ref) ? num(ref, 3) : std::string("0.439")) + ")</td>"});
    s += row({th("calibrated range"), td(text(at(p, "range_kpa")) + " kPa")});
  } else {
    s += row({th("pressure calibration"),
              "<td id=\"no-calibration\">none: this report shows the blanching signal (relative, no unit), not kPa. "
              "Calibrate a person against a force sensor to get pressure. (For reference, the study's linear "
              "colour-to-pressure fit reached R&sup2; = 0.439.)</td>"});
  }
  return s + "</tbody></table>";
}

std::string captures_table(const json& report) {
  const json& caps = at(report, "captures");
  std::string s = "<table id=\"captures-table\" class=\"data\"><thead><tr><th></th><th>source</th><th>frames used</th>"
                  "<th>fps</th><th>motion (px)</th><th>saturated</th></tr></thead><tbody>";
  for (const char* name : {"baseline", "worn"}) {
    const json& c = at(caps, name);
    if (!c.is_object()) continue;
    const json& used = at(c, "frames_used");
    std::string frames = used.is_array() && used.size() == 2 ? text(used[0]) + "&ndash;" + text(used[1]) : text(used);
    frames += " of " + text(at(c, "frames_total"));
    std::string motion = num(at(c, "motion_px_max"), 2);
    if (at(c, "motion_compensated").is_boolean()) motion += c["motion_compensated"].get<bool>() ? ", compensated" : ", not compensated";
    // A folder of images has no frame rate (report.json's fps 0): a dash, not "0.0".
    const json& rate = at(c, "fps");
    const std::string fps = is_number(rate) && rate.get<double>() > 0 ? num(rate, 1) : std::string(kDash) + " (images)";
    s += row({std::string("<th scope=\"row\">") + (std::string(name) == "worn" ? "worn" : "not worn (baseline)") + "</th>",
              td(text(at(c, "source"))), td(frames), td(fps), td(motion), td(percent(at(c, "saturated_fraction")))});
  }
  s += "</tbody></table>";
  if (const json& split = at(caps, "split"); !split.is_null()) s += "<p>Phases split from one capture: " + text(split) + "</p>";
  if (const json& reg = at(report, "phase_registration"); reg.is_object()) {
    const json& m = at(reg, "magnitude_mm");
    s += "<p id=\"phase-registration\">Skin displacement between the phases (registered on the chart, displacement.npy): median " +
         num(at(m, "median"), 3) + " mm, 95th percentile " + num(at(m, "p95"), 3) + " mm, max " + num(at(m, "max"), 3) +
         " mm; texture correlation " + num(at(reg, "texture_match_before"), 2) + " before, " + num(at(reg, "texture_match_after"), 2) +
         " after" + (at(reg, "unsure") == json(true) ? " <strong>(unsure: see the warnings)</strong>" : "") + ".</p>";
  }
  return s;
}

std::string signal_table(const json& report) {
  const json& sig = at(report, "signal");
  std::string s = "<table id=\"signal-table\" class=\"facts\"><tbody>";
  s += row({th("feature"), td(text(at(sig, "feature")))});
  s += row({th("reference region"), td(text(at(sig, "reference")))});
  s += row({th("noise (1 &sigma;)"), td(num(at(sig, "noise_sigma"), 5))});
  s += row({th("blanched area"), td(num(at(sig, "blanched_area_mm2"), 1) + " mm&sup2;")});
  s += row({th("mean plain difference"), td(num(at(sig, "plain_difference_mean"), 5))});
  return s + "</tbody></table>";
}

std::string part_table(const json& report) {
  const json& part = at(report, "part");
  const json& chart = at(report, "chart");
  std::string s = "<table id=\"part-table\" class=\"facts\"><tbody>";
  s += row({th("mesh"), td(text(at(part, "mesh")) + ": " + text(at(part, "vertices")) + " vertices, " + text(at(part, "faces")) + " faces")});
  s += row({th("index of refraction"), td("part " + num(at(part, "ior"), 3) + ", camera side " + num(at(part, "medium_ior"), 3))});
  s += row({th("contact surface"), td(text(at(part, "contact_faces")) + " faces, " + num(at(part, "contact_area_mm2"), 1) + " mm&sup2;")});
  s += row({th("refraction fast path"), td(text(at(part, "fast_path")))});
  s += row({th("chart"), td(text(at(chart, "method")) + ", " + text(at(chart, "width")) + " &times; " + text(at(chart, "height")) +
                            " texels of " + num(at(chart, "texel_mm"), 3) + " mm; area distortion " +
                            num(at(chart, "area_ratio_min"), 3) + "&ndash;" + num(at(chart, "area_ratio_max"), 3))});
  return s + "</tbody></table>";
}

std::string provenance(const json& report) {
  std::string s = "<table id=\"provenance-table\" class=\"facts\"><tbody>";
  s += row({th("clearfit version"), td(text(at(report, "clearfit_version")))});
  s += row({th("created (UTC)"), td(text(at(report, "created_utc")))});
  s += row({th("run time"), td(num(at(report, "run_time_s"), 1) + " s")});
  s += row({th("scene"), td(text(at(report, "scene")))});
  s += "</tbody></table><table id=\"inputs-table\" class=\"data\"><thead><tr><th>role</th><th>file</th><th>SHA-256</th></tr></thead><tbody>";
  if (const json& inputs = at(report, "inputs"); inputs.is_array())
    for (const json& in : inputs)
      s += row({td(text(at(in, "role"))), td(text(at(in, "path"))), "<td class=\"hash\">" + text(at(in, "sha256")) + "</td>"});
  s += "</tbody></table><h3>Options</h3><pre id=\"options\">" +
       html_escape(at(report, "options").dump(2, ' ', false, json::error_handler_t::replace)) + "</pre>";
  return s;
}

std::string figure(const fs::path& folder, const json& outputs, const char* key, const std::string& caption,
                   std::vector<std::string>& notes) {
  const json& name = at(outputs, key);
  if (!name.is_string()) {
    notes.push_back(std::string("report.json names no outputs.") + key);
    return "<figure class=\"missing\"><figcaption>" + html_escape(caption) + ": not written by this assessment</figcaption></figure>";
  }
  const fs::path path = folder / name.get<std::string>();
  if (!fs::is_regular_file(path)) {
    notes.push_back(path.string() + " is missing: its figure is left out");
    return "<figure class=\"missing\"><figcaption>" + html_escape(caption) + ": " + html_escape(name.get<std::string>()) +
           " is missing</figcaption></figure>";
  }
  return "<figure><img alt=\"" + html_escape(caption) + "\" src=\"data:image/png;base64," + base64(read_binary(path)) +
         "\"><figcaption>" + html_escape(caption) + "</figcaption></figure>";
}

// The worn phase over time: one figure and one row per place (timeline of report.json).
std::string timeline_section(const fs::path& folder, const json& report, std::vector<std::string>& notes) {
  const json& t = at(report, "timeline");
  if (!t.is_object()) return "<p>No time series in this assessment.</p>";
  const json& places = at(t, "places");
  std::string s = "<p>Time bins of " + num(at(t, "bin_s"), 3) + " s (" + num(at(t, "bins"), 0) + " bins); times from the first frame of the worn capture" +
                  (at(t, "release_s").is_number() ? "; the part was removed at " + num(at(t, "release_s"), 2) + " s" : "") + ".</p>";
  if (!places.is_array() || places.empty()) return s + "<p>No place to follow.</p>";
  auto fit_text = [](const json& f, const char* what) {
    if (!at(f, "fitted").is_boolean() || !at(f, "fitted").get<bool>()) {
      const json& note = at(f, "note");
      return std::string(what) + ": " + (note.is_string() ? html_escape(note.get<std::string>()) : kDash);
    }
    return std::string(what) + " &tau; " + num(at(f, "tau_s"), 2) + " &plusmn; " + num(at(f, "tau_sigma_s"), 2) + " s";
  };
  s += "<table id=\"timeline-table\" class=\"data\"><thead><tr><th>#</th><th>onset (s)</th><th>onset</th><th>refill</th><th>time above each threshold</th></tr></thead><tbody>";
  std::string figures;
  for (const json& p : places) {
    const json& onset = at(p, "onset");
    std::string above;
    for (const json& l : at(p, "thresholds"))
      above += (above.empty() ? "" : "; ") + num(at(l, "threshold"), 2) + " " + html_escape(at(l, "unit").get<std::string>()) + ": " +
               num(at(l, "time_above_s"), 2) + " s";
    s += "<tr><td>" + num(at(p, "id"), 0) + "</td><td>" + num(at(onset, "t0_s"), 3) + "</td><td>" + fit_text(onset, "rise") + "</td><td>" +
         fit_text(at(p, "refill"), "refill") + "</td><td>" + (above.empty() ? kDash : above) + "</td></tr>";
    const json& name = at(p, "figure");
    if (!name.is_string()) continue;
    if (!fs::is_regular_file(folder / name.get<std::string>())) {
      notes.push_back((folder / name.get<std::string>()).string() + " is missing: its figure is left out");
      continue;
    }
    figures += "<figure><img alt=\"place " + num(at(p, "id"), 0) + " over time\" src=\"data:image/png;base64," +
               base64(read_binary(folder / name.get<std::string>())) + "\"><figcaption>Place " + num(at(p, "id"), 0) +
               " over time: its signal, the thresholds (dashed), the onset and the removal</figcaption></figure>";
  }
  return s + "</tbody></table><div class=\"figures\">" + figures + "</div>";
}

std::string summary(const json& report, bool calibrated) {
  const json& hotspots = at(report, "hotspots");
  const std::size_t n = hotspots.is_array() ? hotspots.size() : 0;
  std::string s = "<ul class=\"summary\">";
  if (calibrated) {
    const json& p = at(report, "pressure");
    s += "<li>Peak pressure <b>" + num(at(p, "peak_kpa"), 1) + " kPa</b>, mean " + num(at(p, "mean_kpa"), 1) +
         " kPa over the seen contact surface.</li>";
    const json* worst = nullptr;
    if (hotspots.is_array())
      for (const json& h : hotspots)
        if (is_number(at(h, "peak_kpa")) && (!worst || h["peak_kpa"].get<double>() > (*worst)["peak_kpa"].get<double>())) worst = &h;
    if (worst)
      s += "<li>" + std::to_string(n) + " hotspot" + (n == 1 ? "" : "s") + " (thresholds " + thresholds_text(report) +
           "); the strongest is #" + text(at(*worst, "id")) + ": " + num(at(*worst, "peak_kpa"), 1) + " &plusmn; " +
           num(at(*worst, "peak_sigma_kpa"), 1) + " kPa over " + num(at(*worst, "area_mm2"), 1) + " mm&sup2;.</li>";
    else
      s += "<li>No hotspot above " + thresholds_text(report) + ".</li>";
  } else {
    s += "<li><b>No pressure calibration</b>: the report shows the blanching signal (relative), not kPa.</li>";
    s += "<li>" + std::to_string(n) + " region" + (n == 1 ? "" : "s") + " of significant blanching.</li>";
  }
  s += "<li>The camera sees " + percent(at(at(report, "coverage"), "seen_fraction")) + " of the contact surface.</li>";
  if (const json& u = at(at(report, "coverage"), "pressed_unseen_share"); is_number(u) && u.get<double>() > 0)
    s += "<li>" + percent(u) + " of the hotspots' area is not seen (beside them, e.g. a wall seen edge-on): not counted as pressed nor as 0.</li>";
  const json& w = at(report, "warnings");
  if (w.is_array() && !w.empty()) s += "<li>" + std::to_string(w.size()) + " warning" + (w.size() == 1 ? "" : "s") + " below.</li>";
  return s + "</ul>";
}

}  // namespace

std::string html_escape(std::string_view in) {
  std::string out;
  out.reserve(in.size());
  for (char c : in) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

fs::path default_report_assets_dir() {
  if (const char* env = std::getenv("CLEARFIT_REPORT_ASSETS_DIR"); env && *env) return env;
  if (*CLEARFIT_REPORT_ASSETS_DIR) return CLEARFIT_REPORT_ASSETS_DIR;
  // reports/assets beside this source file; __FILE__ may be relative to the
  // build folder (Ninja), which is an ancestor of the running executable.
  const fs::path source(__FILE__);
  const fs::path assets = source.parent_path().parent_path() / "assets";
  if (source.is_absolute()) return assets;
  std::error_code ec;
  for (fs::path dir = fs::read_symlink("/proc/self/exe", ec).parent_path(); !ec && !dir.empty(); dir = dir.parent_path()) {
    if (fs::is_regular_file(dir / source)) return fs::weakly_canonical(dir / assets);
    if (dir == dir.root_path()) break;
  }
  return assets;
}

HtmlReportResult write_report_html(const fs::path& folder, const HtmlReportOptions& options) {
  HtmlReportResult result;
  const fs::path report_path = folder / "report.json";
  if (!fs::is_regular_file(report_path))
    throw InputError(report_path.string(), "", "not found", "give the output folder of a finished `clearfit assess` run");
  const json report = json::parse(read_binary(report_path), nullptr, false);
  if (report.is_discarded() || !report.is_object()) throw InputError(report_path.string(), "", "is not a JSON object");
  if (at(report, "schema") != "clearfit.report/1")
    throw InputError(report_path.string(), "key 'schema'", "expected \"clearfit.report/1\", got " + at(report, "schema").dump(),
                     "write it with this version of clearfit assess");
  const fs::path assets = options.assets_dir.empty() ? default_report_assets_dir() : options.assets_dir;
  const detail::PageAssets page_assets = detail::load_page_assets(assets);

  const bool calibrated = at(at(report, "calibration"), "pressure").is_object();
  const json& outputs = at(report, "outputs");

  // The 3D views.
  std::optional<detail::HeatmapGlb> glb;
  std::vector<View> views;
  json hover;  // the hover's vertex table (report.js)
  if (const json& name = at(outputs, "heatmap_glb"); name.is_string() && fs::is_regular_file(folder / name.get<std::string>())) {
    glb = detail::load_heatmap_glb(folder / name.get<std::string>());
    views = make_views(*glb, report, options.max_view_triangles, result.notes, hover);
  } else {
    result.notes.push_back("no heatmap .glb in the output folder: the report has no 3D view");
  }
  const auto [view_html, models] =
      detail::view_section(views, hotspot_markers(glb ? &*glb : nullptr, at(report, "hotspots"), calibrated),
                           glb ? detail::skin_side_orbit(*glb) : std::string());

  std::string warnings;
  if (const json& w = at(report, "warnings"); w.is_array() && !w.empty()) {
    warnings = "<ul id=\"warnings-list\">";
    for (const json& s : w) warnings += "<li>" + text(s) + "</li>";
    warnings += "</ul>";
  } else {
    warnings = "<p id=\"no-warnings\">No warnings.</p>";
  }

  const std::string mesh_name = at(at(report, "part"), "mesh").is_string() ? report["part"]["mesh"].get<std::string>() : "";
  const std::string title = !options.title.empty() ? options.title
                            : "Fit report" + (mesh_name.empty() ? std::string() : ": " + fs::path(mesh_name).filename().string());
  std::string body;
  body += "<header><h1>" + html_escape(title) + "</h1><p class=\"meta\">clearfit " + text(at(report, "clearfit_version")) +
          " &middot; " + text(at(report, "created_utc")) + "</p>" + summary(report, calibrated) + "</header>";
  body += "<section id=\"view\"><h2>Where the part presses</h2>" + view_html + "</section>";
  body += "<section id=\"warnings\"><h2>Warnings</h2>" + warnings + "</section>";
  body += std::string("<section id=\"hotspots\"><h2>") + (calibrated ? "Hotspots" : "Regions of significant blanching") + "</h2>" +
          hotspot_table(report, calibrated) + "</section>";
  body += "<section id=\"timeline\"><h2>Over time</h2>" + timeline_section(folder, report, result.notes) + "</section>";
  body += "<section id=\"chart\"><h2>The contact surface, unrolled</h2><div class=\"figures\">" +
          figure(folder, outputs, "chart_pressure_png", calibrated ? "Pressure on the chart, hotspots outlined" : "Blanching signal on the chart, regions outlined", result.notes) +
          (calibrated ? figure(folder, outputs, "chart_signal_png", "Blanching signal on the chart", result.notes) : "") + "</div></section>";
  body += "<section id=\"skin\"><h2>What the camera saw, and the skin with refraction undone</h2><div class=\"figures side-by-side\">" +
          figure(folder, outputs, "skin_camera_png", "Worn capture as the camera saw it (through the part)", result.notes) +
          figure(folder, outputs, "skin_chart_png", "The same skin resampled onto the chart (refraction undone)", result.notes) +
          "</div></section>";
  body += "<section id=\"coverage\"><h2>How much of the contact surface the camera sees</h2>" + coverage_table(report) + "</section>";
  body += "<section id=\"calibration\"><h2>Calibration quality</h2>" + calibration_table(report) + "</section>";
  body += "<section id=\"captures\"><h2>Captures</h2>" + captures_table(report) + "</section>";
  body += "<section id=\"signal\"><h2>Blanching signal</h2>" + signal_table(report) + "</section>";
  body += "<section id=\"part\"><h2>Part and chart</h2>" + part_table(report) + "</section>";
  body += "<section id=\"provenance\"><h2>Provenance</h2>" + provenance(report) + "</section>";

  const std::string html = detail::render_page(page_assets, title, body, views, models, hover);
  result.html = folder / "report.html";
  write_file_atomically(result.html, html);
  return result;
}

namespace detail {

std::string colour_bar(const std::string& view, const std::string& colormap, double lo, double hi, const std::string& unit,
                       const std::string& caption) {
  return reports::colour_bar(view, colormap, lo, hi, unit, caption);
}
tinygltf::Model single_scene(tinygltf::Model model, int scene) { return reports::single_scene(std::move(model), scene); }
std::string skin_side_orbit(const HeatmapGlb& g) { return reports::skin_side_orbit(g); }

PageAssets load_page_assets(const fs::path& assets) {
  PageAssets a;
  const fs::path viewer_path = assets / "vendor" / "model-viewer-umd.min.js";
  for (const fs::path& p : {assets / "report.html", assets / "report.css", assets / "report.js", viewer_path})
    if (!fs::is_regular_file(p))
      throw InputError(p.string(), "", "report asset not found",
                       "set CLEARFIT_REPORT_ASSETS_DIR to clearfit's reports/assets folder; the viewer is vendored by web/scripts/vendor-viewer.sh");
  a.template_path = assets / "report.html";
  a.page = read_binary(a.template_path);
  a.css = read_binary(assets / "report.css");
  a.js = read_binary(assets / "report.js");
  a.viewer = read_binary(viewer_path);
  std::string lowered = a.viewer;
  std::transform(lowered.begin(), lowered.end(), lowered.begin(), [](unsigned char c) { return std::tolower(c); });
  if (lowered.find("</script") != std::string::npos)
    throw InputError(viewer_path.string(), "", "contains '</script' and cannot be inlined", "vendor a different build of the viewer");
  return a;
}

std::pair<std::string, std::string> view_section(const std::vector<PageView>& views, const std::string& markers,
                                                 const std::string& orbit) {
  if (views.empty()) return {"<p class=\"missing\">No 3D heatmap in this output folder.</p>", ""};
  std::string html = "<div class=\"viewer-wrap\"><model-viewer id=\"viewer\" camera-controls touch-action=\"pan-y\" " +
                     (orbit.empty() ? std::string() : "camera-orbit=\"" + orbit + "\" ") +
                     "interaction-prompt=\"none\" shadow-intensity=\"0\" exposure=\"1\" tone-mapping=\"neutral\" "
                     "alt=\"The part's contact surface coloured by the measured quantity\"><div slot=\"progress-bar\"></div>" +
                     markers +
                     "</model-viewer><img id=\"viewer-print\" alt=\"3D view (snapshot for printing)\" hidden></div>"
                     "<div class=\"view-controls\">";
  if (views.size() > 1) {
    html += "<div class=\"toggle\" role=\"group\" aria-label=\"quantity shown\">";
    for (const PageView& v : views)
      html += "<button type=\"button\" data-view=\"" + v.key + "\">" + html_escape(v.label) + "</button>";
    html += "</div>";
  }
  for (const PageView& v : views) html += v.colorbar;
  html += "<p class=\"hint\">Drag to turn, scroll to zoom; point at the surface for a vertex's values; click a numbered marker for "
          "its hotspot's numbers.</p></div>";
  std::string models;
  for (const PageView& v : views)
    models += "<script type=\"application/octet-stream\" class=\"clearfit-model\" data-view=\"" + v.key + "\">" +
              base64(v.glb) + "</script>\n";
  return {html, models};
}

std::string render_page(const PageAssets& assets, const std::string& title, const std::string& body,
                        const std::vector<PageView>& views, const std::string& models, const json& vertices) {
  json data = {{"views", json::array()}};
  if (!vertices.is_null()) data["vertices"] = vertices;
  for (const PageView& v : views) data["views"].push_back({{"key", v.key}, {"label", v.label}});
  return fill_template(assets.page,
                       {{"title", html_escape(title)}, {"style", assets.css}, {"body", body}, {"models", models},
                        {"data", script_json(data)}, {"viewer", assets.viewer}, {"script", assets.js}},
                       assets.template_path);
}

}  // namespace detail

}  // namespace clearfit::reports
