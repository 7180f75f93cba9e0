#pragma once
// PNG pictures of a field on the contact chart for people: the pressure (or
// blanching signal) heatmap with hotspot outlines, a colour bar in the field's
// unit, a scale bar in mm and a title (chart_pressure.png, chart_signal.png).
#include <clearfit/fit/chart_field.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace clearfit {

struct ChartImageInput {
  const ChartField* field = nullptr;   ///< required; NaN texels are drawn in the colormap's no-data grey
  double range_lo = 0, range_hi = 30;  ///< field values mapped to the colour bar's ends (clamped beyond)
  std::string colormap = "viridis";    ///< a Colormap::get name
  std::string unit;                    ///< colour bar label, e.g. "kPa"; "" for the unitless signal
  /// Optional, one per texel of field->grid (row-major like the field): the
  /// hotspot id covering the texel, 0 = none. Each id's region is outlined
  /// and labelled with the id.
  std::vector<int> hotspot_labels;
  std::string title;
  int min_chart_width_px = 800;   ///< the chart is upscaled (nearest texel) to at least this width
  int max_chart_width_px = 2400;  ///< ... and downscaled to at most this one
  /// Throws std::invalid_argument naming the field when something does not
  /// fit (no field, empty grid, label count, range not finite lo < hi, widths).
  void validate() const;
};

/// Where things are in the written image, in pixels (x right, y down from the
/// top-left pixel), for tests and for pages that annotate the picture.
struct ChartImageLayout {
  int width = 0, height = 0;                               ///< image size
  int chart_x = 0, chart_y = 0, chart_w = 0, chart_h = 0;  ///< the chart area
  int bar_x = 0, bar_y = 0, bar_w = 0,
      bar_h = 0;            ///< the colour bar (range_hi at the top row, range_lo at the bottom)
  double px_per_mm = 0;     ///< chart scale
  double scale_bar_mm = 0;  ///< length of the drawn scale bar
  int scale_bar_x = 0, scale_bar_y = 0, scale_bar_px = 0;  ///< its left end and length in pixels
  std::vector<double> ticks;                               ///< colour bar tick values
};

/// Draws the field as an 8-bit sRGB PNG and writes it atomically to `path`.
/// The chart is shown as seen from the skin side: u to the right and v up
/// (grid row 0 at the bottom), each texel a block of px_per_mm * texel_mm
/// pixels. Hotspot outlines (cv::findContours of each id's region) are drawn
/// black and white so they show on any colour, with the id beside them.
/// Used for both chart_pressure.png (unit "kPa") and chart_signal.png (unit "").
/// Throws InputError naming `path` if it cannot be written.
ChartImageLayout write_chart_heatmap_png(const ChartImageInput& input, const std::filesystem::path& path);

/// "Nice" tick values (1, 2 or 5 times a power of ten apart) inside [lo, hi],
/// about `target` of them (at least 2 when lo < hi).
std::vector<double> nice_ticks(double lo, double hi, int target = 6);

}  // namespace clearfit
