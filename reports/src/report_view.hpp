#pragma once
// Internal to reports/: the triangle budget of report.html's 3D view
// (HtmlReportOptions::max_view_triangles). A heatmap larger than the budget is
// simplified for the page only (clearfit/reports/simplify.hpp). A halfedge
// collapse keeps one endpoint, so the simplified mesh uses a subset of the
// original vertices and every per-vertex attribute (COLOR_0, NORMAL, TEXCOORD_0,
// _BLANCH, ...) carries over by index.
#include "report_html_glb.hpp"

#include <clearfit/reports/simplify.hpp>

#include <cstddef>
#include <optional>

namespace clearfit::reports::detail {

/// The heatmap `g` for the page: its vertex-coloured mesh simplified to at most
/// `max_triangles` triangles (simplify_triangles, coloured by COLOR_0), every
/// primitive keeping its own triangles, the vertex accessors shared by the
/// primitives compacted to the vertices still used (POSITION min/max
/// recomputed), and g's arrays (position_mm, normal, seen, triangles) to match.
/// Every mesh of the model that uses the same vertex set (e.g. the texture
/// scene's "heatmap_texture") follows, since it shares the index accessors.
/// Textures, materials, nodes and scenes are kept. Returns nullopt when the
/// model cannot be rewritten safely (sparse accessors, a primitive on the
/// vertex set with indices of its own, a primitive left empty); the caller
/// then shows the full mesh.
std::optional<HeatmapGlb> simplify_heatmap_for_view(const HeatmapGlb& g, std::size_t max_triangles);

}  // namespace clearfit::reports::detail
