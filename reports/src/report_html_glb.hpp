#pragma once
// Internal to reports/: reading the heatmap .glb files written by
// write_heatmap_glb back through tinygltf (for report.html's 3D views and for
// `clearfit compare`).
#include <tiny_gltf.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

// tinygltf's base64 coder: defined by its implementation (Debian's libtinygltf.so
// exports it) but declared only inside the header's TINYGLTF_IMPLEMENTATION part.
namespace tinygltf {
std::string base64_encode(unsigned char const* bytes, unsigned int len);
std::string base64_decode(std::string const& encoded);
}  // namespace tinygltf

namespace clearfit::reports::detail {

/// A heatmap .glb as read, and the per-vertex arrays of its vertex set (the
/// accessors shared by every primitive of the "heatmap_vertex_colors" mesh).
struct HeatmapGlb {
  tinygltf::Model model;
  nlohmann::json info;             ///< asset.extras.clearfit; {} when absent
  int mesh = -1;                   ///< the vertex-coloured mesh
  std::vector<float> position_mm;  ///< 3 per vertex (the file's own units: mm, node scale 0.001)
  std::vector<float> normal;       ///< 3 per vertex; empty when the file has none
  std::vector<float> seen;         ///< 1/0 per vertex; all 1 when the file has no _SEEN
  std::vector<std::uint32_t> triangles;  ///< 3 per triangle, all primitives of `mesh`
  std::size_t vertex_count() const { return position_mm.size() / 3; }
  /// The float scalar attribute `name` (e.g. "_PRESSURE_KPA") per vertex; empty when absent.
  std::vector<float> scalar(const std::string& name) const;
};

/// Appends `bytes` bytes at `data` to `buffer` (4-byte aligned first) as a new
/// view of buffer 0 at the end of `views` (target, byteStride 0 = packed);
/// returns its index.
int append_buffer_view(std::vector<unsigned char>& buffer, std::vector<tinygltf::BufferView>& views,
                       const void* data, std::size_t bytes, int target, int stride, const std::string& name);

/// Loads `path`. Throws InputError naming the file when it cannot be read, is
/// not a glTF binary, or lacks a triangle mesh with float POSITION.
HeatmapGlb load_heatmap_glb(const std::filesystem::path& path);

/// The float accessor `index` as `components` floats per element (honours byteStride).
/// Throws InputError (naming `file`) when it is not a float accessor of that width.
std::vector<float> read_floats(const tinygltf::Model& model, int index, int components, const std::string& file);

/// One 3D view of a page: a .glb (bytes) and its colour bar (HTML).
struct PageView {
  std::string key, label, glb, colorbar;
};

/// The page template, styles, script and the vendored viewer, read from `assets`.
struct PageAssets {
  std::filesystem::path template_path;
  std::string page, css, js, viewer;
};
/// Throws InputError naming a missing asset (and how to vendor the viewer).
PageAssets load_page_assets(const std::filesystem::path& assets);
/// The 3D section (model-viewer with `markers` inside, toggle, colour bars) and
/// the embedded models (base64 <script> elements), for render_page.
std::pair<std::string, std::string> view_section(const std::vector<PageView>& views, const std::string& markers,
                                                 const std::string& orbit);
/// The whole page: the template filled with `title` (escaped here), `body` (HTML), the views and models;
/// `vertices` (when not null) is the page data's per-vertex table for the hover (report.js).
std::string render_page(const PageAssets& assets, const std::string& title, const std::string& body,
                        const std::vector<PageView>& views, const std::string& models,
                        const nlohmann::json& vertices = nullptr);
/// A colour bar for a view: CSS gradient from the colormap over [lo, hi], round ticks, unit.
std::string colour_bar(const std::string& view, const std::string& colormap, double lo, double hi,
                       const std::string& unit, const std::string& caption);
/// The model reduced to its scene `scene` (unused nodes and meshes dropped).
tinygltf::Model single_scene(tinygltf::Model model, int scene);
/// model-viewer camera-orbit looking at the seen surface from outside ("" when undefined).
std::string skin_side_orbit(const HeatmapGlb& g);

/// The model serialised as a binary glTF.
std::string to_glb_bytes(const tinygltf::Model& model);

}  // namespace clearfit::reports::detail
