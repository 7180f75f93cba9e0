#include <clearfit/error.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/reports/colormap.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace clearfit {
namespace detail {
extern const std::array<std::array<float, 3>, 256> kViridisSrgb;  // colormap_viridis.cpp
}

namespace {

using Vec3d = Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

// CIELAB with the D65 white of sRGB (the reference white Moreland uses).
const Vec3d kWhiteD65(0.95047, 1.0, 1.08883);

double lab_f(double t) {
  constexpr double d = 6.0 / 29.0;
  return t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
}
double lab_f_inv(double f) {
  constexpr double d = 6.0 / 29.0;
  return f > d ? f * f * f : 3 * d * d * (f - 4.0 / 29.0);
}

Vec3d srgb_to_lab(const Vec3d& srgb) {
  Eigen::Matrix3d xyz_from_rgb;
  xyz_from_rgb << 0.4124564, 0.3575761, 0.1804375,  //
      0.2126729, 0.7151522, 0.0721750,              //
      0.0193339, 0.1191920, 0.9503041;
  Vec3d lin(srgb::to_linear(srgb[0]), srgb::to_linear(srgb[1]), srgb::to_linear(srgb[2]));
  Vec3d xyz = xyz_from_rgb * lin;
  double fx = lab_f(xyz[0] / kWhiteD65[0]), fy = lab_f(xyz[1] / kWhiteD65[1]),
         fz = lab_f(xyz[2] / kWhiteD65[2]);
  return {116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)};
}

Vec3d lab_to_srgb(const Vec3d& lab) {
  Eigen::Matrix3d rgb_from_xyz;
  rgb_from_xyz << 3.2404542, -1.5371385, -0.4985314,  //
      -0.9692660, 1.8760108, 0.0415560,               //
      0.0556434, -0.2040259, 1.0572252;
  double fy = (lab[0] + 16) / 116;
  Vec3d xyz(kWhiteD65[0] * lab_f_inv(fy + lab[1] / 500), kWhiteD65[1] * lab_f_inv(fy),
            kWhiteD65[2] * lab_f_inv(fy - lab[2] / 200));
  Vec3d lin = rgb_from_xyz * xyz;
  return {srgb::from_linear(lin[0]), srgb::from_linear(lin[1]), srgb::from_linear(lin[2])};
}

// Moreland's Msh: M = |Lab|, s = angle from the L axis, h = hue angle.
Vec3d lab_to_msh(const Vec3d& lab) {
  double m = lab.norm();
  return {m, m > 0 ? std::acos(lab[0] / m) : 0.0, std::atan2(lab[2], lab[1])};
}
Vec3d msh_to_lab(const Vec3d& msh) {
  return {msh[0] * std::cos(msh[1]), msh[0] * std::sin(msh[1]) * std::cos(msh[2]),
          msh[0] * std::sin(msh[1]) * std::sin(msh[2])};
}

// Hue for an unsaturated colour of magnitude m_unsat next to `saturated`, so
// the hue spins smoothly towards it (Moreland 2009, section 5).
double adjust_hue(const Vec3d& saturated, double m_unsat) {
  if (saturated[0] >= m_unsat) return saturated[2];
  double spin = saturated[1] * std::sqrt(m_unsat * m_unsat - saturated[0] * saturated[0]) /
                (saturated[0] * std::sin(saturated[1]));
  return saturated[2] > -kPi / 3 ? saturated[2] + spin : saturated[2] - spin;
}

// Moreland's diverging interpolation between two saturated end colours.
Vec3d diverging_srgb(const Vec3d& srgb1, const Vec3d& srgb2, double t) {
  Vec3d msh1 = lab_to_msh(srgb_to_lab(srgb1)), msh2 = lab_to_msh(srgb_to_lab(srgb2));
  if (msh1[1] > 0.05 && msh2[1] > 0.05 && std::abs(msh1[2] - msh2[2]) > kPi / 3) {
    double m_mid = std::max({msh1[0], msh2[0], 88.0});
    if (t < 0.5) {
      msh2 = {m_mid, 0, 0};
      t = 2 * t;
    } else {
      msh1 = {m_mid, 0, 0};
      t = 2 * t - 1;
    }
  }
  if (msh1[1] < 0.05 && msh2[1] > 0.05) {
    msh1[2] = adjust_hue(msh2, msh1[0]);
  } else if (msh2[1] < 0.05 && msh1[1] > 0.05) {
    msh2[2] = adjust_hue(msh1, msh2[0]);
  }
  return lab_to_srgb(msh_to_lab((1 - t) * msh1 + t * msh2));
}

std::vector<std::array<float, 3>> coolwarm_table() {
  // Moreland's end colours: blue (59, 76, 192) and red (180, 4, 38), 8-bit sRGB.
  const Vec3d cool = Vec3d(59, 76, 192) / 255.0, warm = Vec3d(180, 4, 38) / 255.0;
  constexpr int n = 257;  // odd, so t = 0.5 is a sample
  std::vector<std::array<float, 3>> table(n);
  for (int k = 0; k < n; ++k) {
    Vec3d c = diverging_srgb(cool, warm, static_cast<double>(k) / (n - 1));
    table[k] = {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2])};
  }
  return table;
}

std::uint8_t to_byte(double v) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255));
}

Eigen::Vector3f linear_of(const Rgb8& c) {
  const float* lut = srgb::to_linear_table8();
  return {lut[c.r], lut[c.g], lut[c.b]};
}

}  // namespace

Colormap::Colormap(std::string name, bool diverging, std::vector<std::array<float, 3>> srgb_table,
                   Rgb8 no_data)
    : name_(std::move(name)), diverging_(diverging), table_(std::move(srgb_table)), no_data_(no_data) {
  if (table_.size() < 2) throw std::invalid_argument("Colormap: needs at least two samples");
}

const Colormap& Colormap::get(std::string_view name) {
  static const Colormap viridis("viridis", false, {detail::kViridisSrgb.begin(), detail::kViridisSrgb.end()},
                                Rgb8{200, 200, 200});
  static const Colormap coolwarm("coolwarm", true, coolwarm_table(), Rgb8{80, 80, 80});
  if (name == "viridis") return viridis;
  if (name == "coolwarm") return coolwarm;
  throw InputError("", "colormap", "unknown colormap '" + std::string(name) + "'",
                   "use one of: viridis, coolwarm");
}

std::vector<std::string> Colormap::names() { return {"viridis", "coolwarm"}; }

Eigen::Vector3d Colormap::srgb(double t) const {
  if (std::isnan(t)) return Eigen::Vector3d(no_data_.r, no_data_.g, no_data_.b) / 255.0;
  double x = std::clamp(t, 0.0, 1.0) * static_cast<double>(table_.size() - 1);
  auto k = std::min(static_cast<std::size_t>(x), table_.size() - 2);
  double w = x - static_cast<double>(k);
  Eigen::Vector3d out;
  for (int c = 0; c < 3; ++c) out[c] = (1 - w) * table_[k][c] + w * table_[k + 1][c];
  return out;
}

Rgb8 Colormap::srgb8(double t) const {
  Eigen::Vector3d c = srgb(t);
  return {to_byte(c[0]), to_byte(c[1]), to_byte(c[2])};
}

Eigen::Vector3f Colormap::linear(double t) const {
  if (std::isnan(t)) return no_data_linear();
  Eigen::Vector3d c = srgb(t);
  return {static_cast<float>(srgb::to_linear(c[0])), static_cast<float>(srgb::to_linear(c[1])),
          static_cast<float>(srgb::to_linear(c[2]))};
}

Eigen::Vector3f Colormap::no_data_linear() const { return linear_of(no_data_); }

double normalise_to_range(double value, double lo, double hi) {
  if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi)) {
    throw std::invalid_argument("normalise_to_range: need finite lo < hi, got [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "]");
  }
  if (std::isnan(value)) return value;
  return std::clamp((value - lo) / (hi - lo), 0.0, 1.0);
}

}  // namespace clearfit
