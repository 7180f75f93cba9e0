#include <algorithm>
#include <array>
#include <clearfit/fit/srgb.hpp>
#include <cmath>
#include <vector>

namespace clearfit::srgb {

double to_linear(double encoded) {
  return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

double from_linear(double linear) {
  const double l = std::clamp(linear, 0.0, 1.0);
  return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
}

const float* to_linear_table8() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int v = 0; v < 256; ++v) t[v] = static_cast<float>(to_linear(v / 255.0));
    return t;
  }();
  return table.data();
}

const float* to_linear_table16() {
  static const std::vector<float> table = [] {
    std::vector<float> t(65536);
    for (int v = 0; v < 65536; ++v) t[v] = static_cast<float>(to_linear(v / 65535.0));
    return t;
  }();
  return table.data();
}

}  // namespace clearfit::srgb
