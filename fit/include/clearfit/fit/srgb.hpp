#pragma once
// sRGB transfer function (IEC 61966-2-1): camera images are sRGB-encoded; the
// skin model and the blanching signal work in linear light.
#include <cstdint>

namespace clearfit::srgb {

/// Encoded value in [0, 1] → linear light in [0, 1] (exact piecewise curve).
double to_linear(double encoded);
/// Linear light in [0, 1] → encoded value in [0, 1]; inputs are clamped to [0, 1].
double from_linear(double linear);
/// Table of to_linear(v / 255) for every 8-bit code v.
const float* to_linear_table8();
/// Table of to_linear(v / 65535) for every 16-bit code v (16-bit PNG/TIFF frames, 10-bit video).
const float* to_linear_table16();

}  // namespace clearfit::srgb
