#pragma once
// Hotspots: connected regions of the chart above a threshold, with what a
// designer needs to act on them (peak, mean, area, where on the part, which
// faces, how sure). Also the chart raster that ties texels back to the mesh.
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/geometry/contact.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace clearfit {

/// Per texel of a chart grid: the contact face whose chart triangle holds the
/// texel centre, its barycentrics, the point on the part (mm) and the skin
/// area the texel stands for (texel area × the face's 3D/2D area ratio).
struct ChartRaster {
  ChartGrid grid;
  std::vector<std::int32_t> face;  ///< -1 outside the chart
  std::vector<Vec3> point;         ///< part frame, mm (NaN outside)
  std::vector<float> area_mm2;     ///< 0 outside
};

/// Rasterises the chart's triangles onto `grid` (texel centres, edges shared
/// by neighbouring triangles go to one of them).
ChartRaster rasterize_chart(const Mesh& mesh, const Chart& chart, const ChartGrid& grid);

struct Hotspot {
  int id = 0;                         ///< 1-based, by decreasing peak
  double threshold = 0;               ///< in the field's unit
  double peak = 0, mean = 0;          ///< field values
  double peak_sigma = 0, mean_sigma = 0;  ///< 1-σ uncertainties (NaN if no sigma field)
  double area_mm2 = 0;
  Vec3 centroid_mm = Vec3::Zero();    ///< area-weighted, part frame
  Vec3 centre_of_pressure_mm = Vec3::Zero();  ///< field-weighted, part frame
  Vec2 centroid_uv_mm = Vec2::Zero();
  std::vector<int> faces;             ///< mesh faces covered (ascending)
  long long texels = 0;
  long long flagged_texels = 0;       ///< texels flagged saturated inside the region
};

struct HotspotOptions {
  std::vector<double> thresholds;     ///< one set of regions per threshold
  double min_area_mm2 = 0.05;         ///< smaller regions are dropped (noise specks)
  /// Independent samples per mm² of the field (for the mean's uncertainty):
  /// 1 / (4π σ²) for a field smoothed with a Gaussian of σ mm.
  double samples_per_mm2 = 1.0;
};

/// Regions of `field` ≥ threshold (8-connected on the texel grid), per
/// threshold, sorted by threshold then decreasing peak; ids run 1.. across all.
/// `sigma` (optional) gives per-texel uncertainties; `flags` (optional, 1 =
/// saturated) counts flagged texels. `labels` (optional) receives one image
/// per threshold: the hotspot id per texel (0 = none), for drawing outlines.
std::vector<Hotspot> find_hotspots(const ChartField& field, const ChartField* sigma, const std::vector<std::uint8_t>* flags,
                                   const ChartRaster& raster, const HotspotOptions& options,
                                   std::vector<std::vector<int>>* labels = nullptr);

}  // namespace clearfit
