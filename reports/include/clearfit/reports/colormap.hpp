#pragma once
// Perceptual colormaps for heatmaps: value → colour, as sRGB for images and as
// linear RGB for glTF vertex colours (glTF COLOR_0 and textures' factors are
// linear; PNG pixels are sRGB-encoded).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace clearfit {

struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb8&) const = default;
};

/// A colormap sampled at N evenly spaced points t_k = k / (N - 1) over [0, 1],
/// interpolated linearly (per sRGB-encoded component) between neighbours.
///  - "viridis" (default, sequential): 256 samples of the viridis map (CC0;
///    van der Walt, Smith, Firing 2015); lightness L* rises monotonically.
///  - "coolwarm" (diverging, for signed differences): Moreland's smooth
///    cool-to-warm map ("Diverging Color Maps for Scientific Visualization",
///    ISVC 2009), computed here from its two end colours by interpolation in
///    his Msh space through a light grey centre (L* = 88 at t = 0.5); 257 samples.
class Colormap {
 public:
  /// The colormap called `name` ("viridis", "coolwarm"); throws InputError
  /// (element "colormap") for any other name, listing the known ones.
  static const Colormap& get(std::string_view name);
  /// The names `get` accepts.
  static std::vector<std::string> names();

  const std::string& name() const { return name_; }
  bool diverging() const { return diverging_; }
  int samples() const { return static_cast<int>(table_.size()); }

  /// sRGB-encoded colour (components in [0, 1]) at t; t is clamped to [0, 1].
  /// A NaN t gives the no-data colour.
  Eigen::Vector3d srgb(double t) const;
  /// The same rounded to 8 bits.
  Rgb8 srgb8(double t) const;
  /// Linear-light RGB at t: srgb::to_linear applied to srgb(t) (for glTF COLOR_0).
  Eigen::Vector3f linear(double t) const;

  /// The colour for "no data" (not seen, off the contact surface): a light
  /// grey (sRGB 200) for sequential maps, a dark grey (sRGB 80) for diverging
  /// maps, whose centre is a light grey itself.
  Rgb8 no_data_srgb8() const { return no_data_; }
  Eigen::Vector3f no_data_linear() const;

  Colormap(std::string name, bool diverging, std::vector<std::array<float, 3>> srgb_table, Rgb8 no_data);

 private:
  std::string name_;
  bool diverging_ = false;
  std::vector<std::array<float, 3>> table_;  ///< sRGB-encoded samples
  Rgb8 no_data_;
};

/// Where `value` lies in [lo, hi], as t = (value - lo) / (hi - lo) clamped to
/// [0, 1]; NaN stays NaN. Throws std::invalid_argument unless lo < hi (both finite).
double normalise_to_range(double value, double lo, double hi);

}  // namespace clearfit
