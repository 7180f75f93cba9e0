// sRGB transfer function against the standard's published anchor values.
#include <clearfit/fit/srgb.hpp>
#include <gtest/gtest.h>

namespace clearfit {

TEST(Srgb, MatchesTheStandardsAnchors) {
  // IEC 61966-2-1: the linear segment ends at 0.04045 ↔ 0.0031308; mid grey 0.5 ↔ 0.21404.
  EXPECT_NEAR(srgb::to_linear(0.04045), 0.0031308, 1e-7);
  EXPECT_NEAR(srgb::to_linear(0.5), 0.214041, 1e-6);
  EXPECT_DOUBLE_EQ(srgb::to_linear(1.0), 1.0);
  EXPECT_DOUBLE_EQ(srgb::to_linear(0.0), 0.0);
}

TEST(Srgb, RoundTripsAndTableAgrees) {
  for (int v = 0; v < 256; ++v) {
    const double e = v / 255.0;
    EXPECT_NEAR(srgb::from_linear(srgb::to_linear(e)), e, 1e-12) << v;
    EXPECT_FLOAT_EQ(srgb::to_linear_table8()[v], static_cast<float>(srgb::to_linear(e))) << v;
  }
  EXPECT_DOUBLE_EQ(srgb::from_linear(2.0), 1.0);
  EXPECT_DOUBLE_EQ(srgb::from_linear(-1.0), 0.0);
}

}  // namespace clearfit
