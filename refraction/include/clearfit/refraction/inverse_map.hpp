#pragma once
// The inverse refraction map, for resampling camera images onto the contact
// chart: per chart texel (mm) the camera pixel that sees that skin point
// through the part, as float maps cv::remap consumes directly.
//
// Conventions. Texel (i, j) (column i, row j, row-major at j * width + i) has
// its centre at chart uv = uv_origin + texel_mm * (i, j); the grid covers
// [uv_origin - texel_mm/2, uv_origin + texel_mm * (size - 1/2)]. Pixel
// coordinates are mrcal's and cv::remap's: (0, 0) is the centre of the
// top-left pixel. Invalid texels hold kInvalidPixel (−1) in map_x and map_y,
// which cv::remap with BORDER_CONSTANT turns into the border value for
// INTER_NEAREST, INTER_LINEAR and INTER_CUBIC (every tap with a non-zero
// weight lies outside the image); `valid` is the authoritative mask.
//
// Every valid texel lies inside a pixel cell whose four corners are valid
// forward-map pixels, so cv::remap's bilinear taps (INTER_LINEAR) only read
// pixels that see the contact surface.
#include <clearfit/refraction/map.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

namespace clearfit {

constexpr float kInvalidPixel = -1.0f;

struct InverseMapOptions {
  double texel_mm = 0.05;  ///< texel edge on the chart, mm
  /// Texel grid bounds on the chart (mm), both or neither. Unset: the bounds
  /// of the forward map's valid chart_uv, widened outwards to multiples of
  /// texel_mm, so maps of one chart with one texel_mm share texel centres.
  /// Set them to Chart::uv_min / uv_max for a grid over the whole chart.
  std::optional<Vec2> uv_min, uv_max;
  /// A step between neighbouring pixels whose chart length exceeds this many
  /// times the neighbouring steps along the same image row (column) is a
  /// discontinuity (a chart seam, an occlusion edge); cells across it are not
  /// used. Must be > 1.
  double max_step_ratio = 4.0;
  long long max_texels = 50'000'000;  ///< larger grids (9 bytes a texel) throw InputError
  bool compute_errors = true;         ///< fill InverseMap::error (a second pass, about as costly as the map)
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

struct InverseMapError {
  /// Texel → pixel → chart: at each valid texel's pixel (map_x, map_y as
  /// stored, float), the forward map's chart_uv interpolated bilinearly,
  /// against the texel's uv. Measures the inversion itself (float rounding).
  double max_uv_um = 0;
  /// Pixel → chart → pixel: for each valid forward pixel whose chart point
  /// falls between four valid texels, map_x / map_y interpolated bilinearly
  /// over the texel grid at that point, against the pixel. Measures how well
  /// the texel-sampled inverse represents the inverse of the forward map.
  double max_px = 0, p99_px = 0, median_px = 0;
  long long pixels_checked = 0;
  long long texels_valid = 0;  ///< always filled
};

struct InverseMap {
  int width = 0, height = 0;  ///< texels
  double texel_mm = 0;
  Vec2 uv_origin = Vec2::Zero();      ///< chart uv (mm) of the centre of texel (0, 0)
  std::vector<float> map_x, map_y;    ///< row-major, width * height; kInvalidPixel where invalid
  std::vector<std::uint8_t> valid;    ///< 1 where the texel has a pixel
  InverseMapError error;              ///< zero unless options.compute_errors (texels_valid always)
  long long cells_used = 0;           ///< usable pixel cells spanning a texel row (rasterised)
  long long cells_rejected_step = 0;  ///< valid cells across a discontinuity (or two contact components)
  long long cells_rejected_fold = 0;  ///< valid cells that are not convex in the chart (folded, degenerate)
  long long texels_overlap = 0;       ///< texels inside cells more than 1 px apart (the map folds; the
                                      ///< first cell in image row-major order is kept)
  double raster_ms = 0, error_ms = 0;

  std::size_t index(int i, int j) const { return static_cast<std::size_t>(j) * width + i; }
  Vec2 uv(int i, int j) const { return uv_origin + texel_mm * Vec2(i, j); }
};

/// Inverts the forward map on a texel grid of the chart. Method: each pixel
/// cell (x..x+1, y..y+1) whose four corners are valid (status valid, finite
/// chart_uv) is the bilinear patch of its corners' chart_uv; cells across a
/// discontinuity (options.max_step_ratio; and, when `contact` is given,
/// cells whose corners lie on different contact components) and cells that
/// are not strictly convex in the chart are skipped. Every texel centre inside
/// a patch gets the pixel (x + s, y + t) whose bilinear chart point it is
/// (Newton on the bilinear map, to ~1e-13 of a cell). Parallel (TBB) over bands
/// of texel rows, race-free and deterministic. Throws std::invalid_argument on
/// bad options or a forward map without chart coordinates (traced without a
/// chart); InputError when the grid would exceed max_texels, or when no pixel
/// sees the contact surface and no bounds are given (with bounds: an
/// all-invalid map).
InverseMap compute_inverse_map(const RefractionMap& forward, const InverseMapOptions& options = {},
                               const ContactSurface* contact = nullptr);

/// The map as a NumPy .npy file: float32, shape (height, width, 2) holding
/// (map_x, map_y) in pixels, NaN where invalid. Written atomically.
void write_inverse_map_npy(const InverseMap& map, const std::filesystem::path& path);

}  // namespace clearfit
