#pragma once
// Hotspots: connected regions of the chart above a threshold, with what a
// designer needs to act on them (peak, mean, area, where on the part, which
// faces, how sure). Also the chart raster that ties texels back to the mesh.
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/geometry/contact.hpp>

#include <cstdint>
#include <limits>
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

/// A place at one threshold: the part of it at or above the threshold.
struct HotspotLevel {
  double threshold = 0;          ///< in the field's unit
  double area_mm2 = 0;           ///< seen skin at or above the threshold
  /// 1-σ of the area: the outline moves by σ/|∇v| where it crosses the threshold. The noise's share of σ
  /// (σ² − shared²) is shared along the outline over the correlation length ℓ = 1/√samples_per_mm2, so it adds
  /// σ_n² ℓ / |∇v|² per mm of outline in variance; the shared share (HotspotOptions::shared_sigma) moves the
  /// whole outline at once and adds ∫ σ_s / |∇v| along it in σ, and the model's residual r (HotspotOptions::residual)
  /// |∫ r / |∇v|| in σ. Summed over the texels within ±σ of the
  /// threshold (a band 2σ/|∇v| wide); 0 without a sigma field.
  double area_sigma_mm2 = 0;
  /// Over that area (NaN σ without a sigma field). mean_sigma: the noise's share, its mean over the area
  /// divided by √(independent samples in it); the shared share's mean over the area, undivided; the model's
  /// residual's mean over the area (HotspotOptions::residual), its size; and the outline's motion,
  /// (mean − threshold) · area_sigma / area; in quadrature.
  double mean = 0, mean_sigma = 0;
  long long texels = 0;
};

/// One place: a connected region at the lowest threshold (thresholds nest, so
/// each higher level lies inside one place), with its levels.
struct Hotspot {
  int id = 0;                         ///< 1-based, by decreasing peak
  double threshold = 0;               ///< the lowest threshold (the place's outline)
  double peak = 0, mean = 0;          ///< field values (mean over the place)
  double peak_sigma = 0, mean_sigma = 0;  ///< 1-σ uncertainties (NaN if no sigma field)
  double area_mm2 = 0;                ///< skin area of the place (its lowest level)
  /// Seen skin area of the place at or above half its peak (the full width at
  /// half maximum, as an area): the size of a place that does not depend on
  /// the threshold, e.g. of significant blanching without a calibration.
  double half_peak_area_mm2 = 0;
  Vec3 centroid_mm = Vec3::Zero();    ///< on the contact surface: the point of it nearest to centroid_mean_mm
  Vec3 centroid_mean_mm = Vec3::Zero();  ///< area-weighted 3D mean (inside a curved surface)
  /// The 3D mean weighted by the field above the place's outline level (v − HotspotOptions::outline_level, or
  /// the lowest threshold), moved onto the surface likewise: the centre of the pressure above the outline. A
  /// texel enters or leaves the place with weight 0, so the outline's motion with the noise does not move it
  /// (weighted by v, each texel the outline takes carries the threshold's weight at the place's widest lever
  /// arm). Equal to the field-weighted mean for a place symmetric about its centre.
  Vec3 centre_of_pressure_mm = Vec3::Zero();
  /// 1-σ of the centre of pressure (mm, the root of its covariance's trace: the rms distance to the true
  /// centre) from the per-texel σ, linearly propagated, the texels correlated over HotspotOptions::samples_per_mm2
  /// (texels without σ, e.g. saturated, add nothing; the outline's texels weigh 0, so its motion adds nothing to
  /// first order); NaN without a sigma field.
  double centre_of_pressure_sigma_mm = std::numeric_limits<double>::quiet_NaN();
  /// 1-σ of the centroid (mm, likewise the rms distance to the true one): it moves only with the outline
  /// (texels within σ of the lowest threshold move it by σ/|∇v|, their noise shared along it over the
  /// correlation length); NaN without a sigma field.
  double centroid_sigma_mm = std::numeric_limits<double>::quiet_NaN();
  Vec2 centroid_uv_mm = Vec2::Zero();
  std::vector<int> faces;             ///< mesh faces covered (ascending)
  long long texels = 0;
  long long flagged_texels = 0;       ///< texels flagged saturated inside the region
  /// Contact surface the camera does not see within HotspotOptions::unseen_reach_mm
  /// of the place (a bump's wall seen edge-on): it may be pressed too; the
  /// place's figures count only what was seen.
  double unseen_area_mm2 = 0;
  std::vector<HotspotLevel> levels;   ///< one per threshold, ascending
  bool touches_mask = false;          ///< borders texels left out (glare): it may extend under the mask
};

struct HotspotOptions {
  std::vector<double> thresholds;     ///< nested levels; sorted ascending inside
  double min_area_mm2 = 0.05;         ///< smaller places are dropped (noise specks)
  /// Independent samples per mm² of the field (for the mean's uncertainty):
  /// 1 / (4π σ²) for a field smoothed with a Gaussian of σ mm.
  double samples_per_mm2 = 1.0;
  /// Optional, on the field's grid: the part of each texel's σ that is the same error over a whole place
  /// rather than noise (with a calibration: its parameters' covariance, PressureSigmaParts::shared; without one
  /// the blur's first-order term). It is not averaged down in a place's mean and it moves the whole outline at
  /// once. Null: all of σ is noise (less model_sigma).
  const ChartField* shared_sigma = nullptr;
  /// Optional, on the field's grid: a part of each texel's σ that is neither noise nor the same error over a
  /// place, a per-texel allowance for the field's model (with a calibration: the blur's first-order term,
  /// PressureSigmaParts::blur). It is taken out of the noise and left out of a place's mean and area, which take
  /// `residual` instead. Null: none.
  const ChartField* model_sigma = nullptr;
  /// Optional, on the field's grid, signed, in the field's unit: what the model leaves in the field (with a
  /// calibration: the deblur's residual, PressureSigmaParts::residual; NaN where unknown, counted 0). Its mean over
  /// a place is one error of the place's mean, and its sum over the outline's band one motion of the outline.
  const ChartField* residual = nullptr;
  /// Unseen contact texels (NaN in the field) this close to a place (chart mm)
  /// join it as unseen: they connect the seen parts around them (the face and
  /// the plate beside a bump's wall are one place) and count in unseen_area_mm2,
  /// never as pressure 0.
  double unseen_reach_mm = 1.0;
  /// The field's level at the places' outline when it is gated above the lowest threshold (NaN: the lowest
  /// threshold): a calibrated lossy capture's pressure is 0 below its detection gate and reads a detected
  /// place's tail down to DetectionLimit::tail_kpa only, so a place's texels start there. The centre of
  /// pressure weighs each texel by its value above the larger of the two.
  double outline_level = std::numeric_limits<double>::quiet_NaN();
  /// Optional, on the field's grid (1 = seed): a place must hold a seed, a texel significant by its own σ, to be
  /// reported (the places keep their extent at the thresholds). Null: every place at the thresholds counts.
  const std::vector<std::uint8_t>* seeds = nullptr;
};

/// Places of `field` (8-connected on the texel grid at the lowest threshold,
/// through unseen texels within reach), sorted by decreasing peak, each with
/// its area, mean and σ at every threshold. `sigma` (optional) gives per-texel
/// uncertainties; `flags` (optional, 1 = saturated) counts flagged texels.
/// `labels` (optional) receives the place id per texel (0 = none; seen texels
/// at or above the lowest threshold), for drawing outlines. `mesh` (optional,
/// the raster's mesh) puts the centroids on the surface exactly; without it
/// they snap to the nearest texel centre.
std::vector<Hotspot> find_hotspots(const ChartField& field, const ChartField* sigma, const std::vector<std::uint8_t>* flags,
                                   const ChartRaster& raster, const HotspotOptions& options,
                                   std::vector<int>* labels = nullptr, const Mesh* mesh = nullptr);

/// |∇v| of `field` at texel (i, j), per mm: central differences, one-sided beside undefined texels, 0
/// when neither neighbour is defined.
double gradient_norm(const ChartField& field, int i, int j);
/// The gradient itself (per mm along the chart's u and v), by the same differences.
Eigen::Vector2d gradient(const ChartField& field, int i, int j);

/// Barycentric weights of the point of triangle abc closest to p (Ericson,
/// Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closest_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace clearfit
