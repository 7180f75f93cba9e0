#pragma once
// The heatmap .glb: the part mesh coloured by a scalar field (pressure, blanching
// signal, or a signed difference), with the field's chart texture, for any glTF
// viewer. Layout (docs/assessment-outputs.md, schema "clearfit.heatmap/1"):
//  - Geometry stays in millimetres (the part frame); every root node carries
//    scale 0.001, so the scene is in metres as glTF requires.
//  - One vertex set shared by all primitives: POSITION, NORMAL (the corner
//    normals, split at creases), COLOR_0 (linear RGB float: colormap(value) on
//    seen contact vertices, the colormap's no-data grey elsewhere), TEXCOORD_0
//    (chart uv scaled to the texture: [0, 1] over the texel grid's extent),
//    `_SEEN` (1/0) and the given scalar attributes (e.g. `_PRESSURE_KPA`,
//    `_BLANCH`; 0 where unseen or off the contact surface). A mesh vertex used
//    by contact and other faces, or with several corner normals, is duplicated
//    so colours, uvs and normals are right on each side.
//  - Primitive "contact" (the chart's faces) and primitive "rest" (all other
//    faces), both with KHR_materials_unlit materials.
//  - glTF multiplies a vertex colour into the base colour texture, so a
//    primitive cannot show both. With a texture there are two scenes over the
//    same accessors: scene 0 (default) "texture" draws the contact faces with
//    the texture (no COLOR_0 on that primitive), scene 1 "vertex_colors"
//    draws every face with COLOR_0. Without a texture there is one scene,
//    "vertex_colors".
//  - Hotspot markers: root node "hotspots" (scale 0.001) with one child node
//    per hotspot, named "hotspot <id>", translated to its position (mm), extras
//    {"id", "label"}; present in every scene.
//  - asset.extras.clearfit: {"schema", "quantity", "colormap", "range",
//    "unit", "length_unit": "mm", "node_scale": 0.001, "scenes",
//    "no_data_linear"} plus the caller's extras.
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/normals.hpp>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace clearfit {

/// A point to mark on the heatmap (a hotspot's centroid or peak).
struct HeatmapMarker {
  int id = 0;
  Vec3 position_mm = Vec3::Zero();  ///< part frame
  std::string label;                ///< e.g. "peak 12.3 kPa"
};

/// A per-vertex scalar written as a glTF vertex attribute (float).
struct VertexScalar {
  std::string name;           ///< must start with '_' (glTF application attribute), e.g. "_PRESSURE_KPA"
  std::vector<float> values;  ///< one per mesh vertex; NaN written as 0
};

/// Everything one heatmap shows. The pointers are non-owning and must outlive
/// the call.
struct HeatmapInput {
  const Mesh* mesh = nullptr;              ///< required; part frame, mm
  const CornerNormals* normals = nullptr;  ///< nullptr: compute_corner_normals(*mesh)
  const Chart* chart = nullptr;            ///< nullptr: every face is "contact", no uvs, no texture
  /// The quantity that colours the mesh, one per mesh vertex (NaN = no data).
  std::vector<float> values;
  /// Per mesh vertex 0/1: was it measured. Empty: seen where `values` is finite.
  std::vector<char> seen;
  std::vector<VertexScalar> scalars;  ///< e.g. {"_PRESSURE_KPA", p}, {"_BLANCH", y}
  /// Field on the chart texel grid rendered through the colormap into the
  /// embedded PNG texture (NaN texels: no-data grey). Requires `chart`.
  const ChartField* texture = nullptr;
  std::string quantity = "pressure_kpa";  ///< "pressure_kpa" | "signal" | "pressure_difference_kpa" | ...
  std::string unit = "kPa";               ///< "" for the signal
  double range_lo = 0, range_hi = 30;     ///< values mapped to the colormap's ends (clamped beyond)
  std::string colormap = "viridis";       ///< a Colormap::get name
  nlohmann::json extras = nlohmann::json::object();  ///< added to asset.extras.clearfit
  std::vector<HeatmapMarker> hotspots;

  /// Throws std::invalid_argument naming the field when sizes disagree with
  /// the mesh, the range is not finite lo < hi, a scalar name is not
  /// "_"-prefixed (or is "_SEEN"), `texture` is given without `chart`, a
  /// hotspot position is not finite, or an extras key would replace one of
  /// the reserved keys; InputError for an unknown colormap name.
  void validate() const;
};

/// Writes `input` as a binary glTF (.glb) through tinygltf, atomically
/// (write_path_atomically). Throws InputError naming `path` when it cannot be written.
void write_heatmap_glb(const HeatmapInput& input, const std::filesystem::path& path);

/// A signed difference (B − A, e.g. for `clearfit compare`): `input.values`
/// (and texture) hold the difference; writes it with the diverging "coolwarm"
/// colormap over the symmetric range [-max_abs, max_abs] (max_abs > 0; taken
/// from the finite values, vertex and texture, when 0) and quantity
/// "<quantity>" unchanged. Overrides `input.colormap` unless it is already a
/// diverging map.
void write_difference_glb(HeatmapInput input, double max_abs, const std::filesystem::path& path);

}  // namespace clearfit
