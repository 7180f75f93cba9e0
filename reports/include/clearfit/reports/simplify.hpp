#pragma once
// Simplifying a triangle mesh to a triangle budget (report.html's 3D view,
// HtmlReportOptions::max_view_triangles) by OpenMesh's decimater: halfedge
// collapses ordered by error quadrics (Garland & Heckbert 1997).
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace clearfit::reports {

/// Triangles of a simplified mesh, indexing the ORIGINAL vertex array.
struct SimplifiedTriangles {
  std::vector<std::uint32_t> triangles;  ///< 3 per triangle, original vertex indices, orientation kept
  std::vector<std::uint32_t>
      source_face;  ///< per triangle: the original triangle it was (its corners may have moved)
};

/// Simplifies the triangle mesh (`position_mm`: 3 floats per vertex;
/// `triangles`: 3 vertex indices per triangle) to at most `max_triangles`
/// triangles by quadric-ordered halfedge collapses (OpenMesh DecimaterT with a
/// ModQuadricT-derived module that also vetoes any collapse turning a face by
/// more than 60° or leaving it without area, so nothing flips).
/// - Boundary vertices are locked: the rim of the part, and the seams where the
///   heatmap duplicates vertices (contact/rest split, crease normals), which the
///   indices see as boundaries, keep every vertex, so the outline is exact and
///   seams cannot open.
/// - `colour` (optional, `colour_components` floats per vertex, e.g. COLOR_0)
///   adds |Δcolour|²·|edge|⁴ to a collapse's error (Δcolour: the removed
///   vertex's colour minus what the new faces interpolate at its place), so that
///   flat regions (zero quadric error) lose first the vertices their neighbours'
///   colours already give; and both ends of every edge whose colours differ by
///   more than 0.2 (a jump, e.g. seen/unseen) are locked, so jumps keep their
///   place and shape.
/// - Triangles OpenMesh cannot take (non-manifold edges, repeated corners) are
///   kept as they are, with their vertices locked.
/// When the budget is at least the triangle count the triangles come back
/// unchanged (source_face = 0..n-1). The result exceeds the budget only when
/// too few collapses are legal (locked vertices, topology). Throws
/// std::invalid_argument when an index is out of range or the sizes are not
/// multiples of 3 (resp. colour_components).
SimplifiedTriangles simplify_triangles(std::span<const float> position_mm,
                                       std::span<const std::uint32_t> triangles, std::size_t max_triangles,
                                       std::span<const float> colour = {}, int colour_components = 3);

}  // namespace clearfit::reports
