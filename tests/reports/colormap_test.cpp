// Colormaps against published values and their perceptual properties.
#include <gtest/gtest.h>
#include <clearfit/error.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/reports/colormap.hpp>

#include <cmath>
#include <limits>

namespace clearfit {
namespace {

// CIE L* of an sRGB-encoded colour, written out here independently of the
// library: Y from the sRGB primaries (ITU-R BT.709 luminance weights).
double lightness(const Eigen::Vector3d& srgb_colour) {
  double y = 0.2126729 * srgb::to_linear(srgb_colour[0]) + 0.7151522 * srgb::to_linear(srgb_colour[1]) +
             0.0721750 * srgb::to_linear(srgb_colour[2]);
  return y > 216.0 / 24389.0 ? 116 * std::cbrt(y) - 16 : y * 24389.0 / 27.0;
}

TEST(Colormap, ViridisEndpointsAndMiddleMatchPublishedSamples) {
  const Colormap& cm = Colormap::get("viridis");
  EXPECT_EQ(cm.samples(), 256);
  // matplotlib's published viridis: first, sample 128 and last entries.
  EXPECT_NEAR(cm.srgb(0)[0], 0.267004, 1e-6);
  EXPECT_NEAR(cm.srgb(0)[1], 0.004874, 1e-6);
  EXPECT_NEAR(cm.srgb(0)[2], 0.329415, 1e-6);
  EXPECT_NEAR(cm.srgb(128.0 / 255)[1], 0.566949, 1e-6);
  EXPECT_NEAR(cm.srgb(1)[0], 0.993248, 1e-6);
  EXPECT_NEAR(cm.srgb(1)[2], 0.143936, 1e-6);
  EXPECT_EQ(cm.srgb8(1), (Rgb8{253, 231, 37}));
  EXPECT_EQ(cm.srgb8(0), (Rgb8{68, 1, 84}));
  EXPECT_FALSE(cm.diverging());
}

TEST(Colormap, ViridisLightnessRisesMonotonically) {
  const Colormap& cm = Colormap::get("viridis");
  double previous = -1;
  for (int k = 0; k <= 1000; ++k) {
    double l = lightness(cm.srgb(k / 1000.0));
    EXPECT_GT(l, previous) << "t = " << k / 1000.0;
    previous = l;
  }
  EXPECT_NEAR(lightness(cm.srgb(0)), 15.5, 1.0);
  EXPECT_NEAR(lightness(cm.srgb(1)), 91.5, 1.0);
}

TEST(Colormap, InterpolatesLinearlyBetweenSamplesAndClamps) {
  const Colormap& cm = Colormap::get("viridis");
  Eigen::Vector3d a = cm.srgb(10.0 / 255), b = cm.srgb(11.0 / 255);
  EXPECT_TRUE(cm.srgb(10.25 / 255).isApprox(0.75 * a + 0.25 * b, 1e-12));
  EXPECT_EQ(cm.srgb(-3), cm.srgb(0));
  EXPECT_EQ(cm.srgb(7), cm.srgb(1));
}

TEST(Colormap, LinearIsTheDecodedSrgb) {
  for (const std::string& name : Colormap::names()) {
    const Colormap& cm = Colormap::get(name);
    for (double t : {0.0, 0.1, 0.5, 0.77, 1.0}) {
      Eigen::Vector3d s = cm.srgb(t);
      Eigen::Vector3f l = cm.linear(t);
      for (int c = 0; c < 3; ++c)
        EXPECT_FLOAT_EQ(l[c], static_cast<float>(srgb::to_linear(s[c]))) << name << t;
    }
  }
}

TEST(Colormap, CoolwarmMatchesMorelandsTableAsPublishedByMatplotlib) {
  const Colormap& cm = Colormap::get("coolwarm");
  EXPECT_TRUE(cm.diverging());
  // matplotlib 3.6's "coolwarm" (a piecewise-linear fit through Moreland's
  // 33-entry table, tabulated at t = k / 255): cm(k / 255)[:3].
  struct Ref {
    double t, r, g, b;
  };
  for (const Ref& ref : {Ref{0.0 / 255, 0.2298, 0.2987, 0.7537}, Ref{32.0 / 255, 0.3837, 0.5102, 0.9178},
                         Ref{64.0 / 255, 0.5543, 0.6901, 0.9955}, Ref{96.0 / 255, 0.7240, 0.8149, 0.9757},
                         Ref{127.0 / 255, 0.8634, 0.8651, 0.8676}, Ref{160.0 / 255, 0.9595, 0.7670, 0.6741},
                         Ref{192.0 / 255, 0.9567, 0.5980, 0.4773}, Ref{224.0 / 255, 0.8654, 0.3711, 0.2958},
                         Ref{255.0 / 255, 0.7057, 0.0156, 0.1502}}) {
    Eigen::Vector3d c = cm.srgb(ref.t);
    EXPECT_NEAR(c[0], ref.r, 0.004) << "t = " << ref.t;
    EXPECT_NEAR(c[1], ref.g, 0.004) << "t = " << ref.t;
    EXPECT_NEAR(c[2], ref.b, 0.004) << "t = " << ref.t;
  }
}

TEST(Colormap, CoolwarmLightnessPeaksAtTheNeutralCentre) {
  const Colormap& cm = Colormap::get("coolwarm");
  EXPECT_NEAR(lightness(cm.srgb(0.5)), 88.0, 0.2);
  Eigen::Vector3d centre = cm.srgb(0.5);
  EXPECT_NEAR(centre[0], centre[2], 0.01);  // grey: no hue
  double previous = 0;
  for (int k = 0; k <= 500; ++k) {  // rises to the centre ...
    double l = lightness(cm.srgb(k / 1000.0));
    EXPECT_GT(l, previous) << k;
    previous = l;
  }
  for (int k = 501; k <= 1000; ++k) {  // ... and falls after it
    double l = lightness(cm.srgb(k / 1000.0));
    EXPECT_LT(l, previous) << k;
    previous = l;
  }
  // Equal lightness at equal distance from the centre (within 3 L*).
  for (double d : {0.1, 0.25, 0.4, 0.5}) {
    EXPECT_NEAR(lightness(cm.srgb(0.5 - d)), lightness(cm.srgb(0.5 + d)), 3.0) << d;
  }
}

TEST(Colormap, NoDataIsGreyAndDistinctFromTheMap) {
  for (const std::string& name : Colormap::names()) {
    const Colormap& cm = Colormap::get(name);
    Rgb8 grey = cm.no_data_srgb8();
    EXPECT_EQ(grey.r, grey.g);
    EXPECT_EQ(grey.g, grey.b);
    EXPECT_EQ(cm.srgb8(std::numeric_limits<double>::quiet_NaN()), grey);
    for (int k = 0; k <= 100; ++k) {  // at least 20 levels away from every colour of the map
      Rgb8 c = cm.srgb8(k / 100.0);
      int distance = std::abs(c.r - grey.r) + std::abs(c.g - grey.g) + std::abs(c.b - grey.b);
      EXPECT_GT(distance, 20) << name << " t = " << k / 100.0;
    }
  }
}

TEST(Colormap, UnknownNameIsAnInputErrorAndRangesAreChecked) {
  EXPECT_THROW(Colormap::get("jet"), InputError);
  EXPECT_DOUBLE_EQ(normalise_to_range(5, 0, 20), 0.25);
  EXPECT_DOUBLE_EQ(normalise_to_range(-5, 0, 20), 0.0);
  EXPECT_DOUBLE_EQ(normalise_to_range(50, 0, 20), 1.0);
  EXPECT_TRUE(std::isnan(normalise_to_range(std::nan(""), 0, 20)));
  EXPECT_THROW(normalise_to_range(1, 2, 2), std::invalid_argument);
  EXPECT_THROW(normalise_to_range(1, 0, std::numeric_limits<double>::infinity()), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit
