// Motion registration (registration.hpp) on rendered skin (the simulator's
// slab scene, 320 × 240): strong blanching does not read as motion wherever it
// is (a registration on green reads it as tens of px).
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/fit/simulate.hpp>
#include <gtest/gtest.h>


#include <cmath>
#include <memory>

#include "../support/slab_view.hpp"

namespace clearfit {
namespace {

/// The slab scene and the roi of the pixels that see the skin.
struct SkinView : test::SlabView {
  cv::Rect roi;
  SkinView() {
    int x0 = map.width, y0 = map.height, x1 = -1, y1 = -1;
    for (int y = 0; y < map.height; ++y)
      for (int x = 0; x < map.width; ++x)
        if (map.status[map.index(x, y)] == PixelStatus::valid && map.chart_uv[map.index(x, y)].allFinite())
          x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
    roi = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
  }
  /// The chart uv seen at pixel (x, y).
  Vec2 uv_at(const Vec2& p) const {
    const auto c = map.chart_uv[map.index(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())))];
    return c.cast<double>();
  }
};

/// Skin with strong blanching: a green change of about a quarter at full press (k_green 0.25).
SkinParameters strong_skin(const std::string& tone, std::uint32_t texture_seed) {
  SkinParameters skin;
  skin.tone = SkinTone::preset(tone);
  skin.absorption = Eigen::Vector3d(0.2, 1.0, 0.3) * 0.25;
  skin.texture_seed = texture_seed;
  return skin;
}

/// A renderer of `skin` pressed by 40 kPa Gaussians (σ 1.5 mm) at the chart points `centres`.
std::unique_ptr<sim::CaptureRenderer> pressed(const SkinView& v, const std::vector<Vec2>& centres, const SkinParameters& skin,
                                              std::uint64_t seed, const sim::CameraSettings& cam = {}) {
  sim::PressureFieldSpec spec;
  for (const Vec2& c : centres) {
    sim::PressureSource s;
    s.name = "press";
    s.center_uv_mm = c;
    s.peak_kpa = 40, s.sigma_mm = 1.5;
    spec.sources.push_back(s);
  }
  const sim::PressureTruth truth = sim::make_pressure_truth(v.part.mesh, v.part.contact, v.chart, spec);
  return std::make_unique<sim::CaptureRenderer>(v.map, skin_drive(skin, truth.pressure), skin, cam, seed);
}

Vec2 centre_of(const cv::Rect& r) { return Vec2(r.x + 0.5 * r.width, r.y + 0.5 * r.height); }

TEST(Registration, StrongBlanchingInEveryPatchIsNotMotion) {
  const SkinView v;
  for (const auto& [tone, texture_seed] : {std::pair<std::string, std::uint32_t>{"light", 7}, {"dark", 8}}) {
    const SkinParameters skin = strong_skin(tone, texture_seed);
    const MotionRegistration probe(cv::Size(v.map.width, v.map.height), v.roi, {});
    // One press in each patch in turn, then presses in all of them at once.
    std::vector<std::vector<Vec2>> cases;
    std::vector<Vec2> all;
    for (const cv::Rect& r : probe.patches()) {
      cases.push_back({v.uv_at(centre_of(r))});
      all.push_back(cases.back()[0]);
    }
    cases.push_back(all);
    double worst = 0, worst_mean = 0;
    for (std::size_t k = 0; k < cases.size(); ++k) {
      const auto r = pressed(v, cases[k], skin, 100 + k);
      MotionRegistration reg(cv::Size(v.map.width, v.map.height), v.roi, {});
      reg.set_reference(r->render(0.0, 0.0, Vec2::Zero(), 0));
      // Fully pressed frames; the skin holds still. Each frame's reading carries the noise of
      // its patches (35 px at half resolution here); their mean is what the averages see.
      const int frames = 4;
      std::vector<Vec2> mean(4, Vec2::Zero());
      const cv::Rect& roi = v.roi;
      const std::vector<Vec2> corners{Vec2(roi.x, roi.y), Vec2(roi.br().x, roi.y), Vec2(roi.x, roi.br().y), Vec2(roi.br().x, roi.br().y)};
      for (int f = 1; f <= frames; ++f) {
        const RegistrationResult m = reg.measure(r->render(1.0 + f / 30.0, 1.0, Vec2::Zero(), f), Similarity{});
        ASSERT_TRUE(m.found);
        const double moved = m.motion.max_displacement(v.roi);
        worst = std::max(worst, moved);
        EXPECT_LE(moved, 0.2) << tone << ", press " << k << ", frame " << f << ": " << m.patches_used << " patches kept";
        for (std::size_t c = 0; c < corners.size(); ++c) mean[c] += m.motion.displacement(corners[c]) / frames;
      }
      for (const Vec2& c : mean) {
        worst_mean = std::max(worst_mean, c.norm());
        EXPECT_LE(c.norm(), 0.1) << tone << ", press " << k << ": mean motion read over " << frames << " frames";
      }
    }
    std::printf("%s skin (texture seed %u), strong blanching in each of %zu patches and in all: motion read at most %.4f px "
                "in a frame, %.4f px on average\n",
                tone.c_str(), texture_seed, probe.patches().size(), worst, worst_mean);
  }
}

TEST(Registration, RefusesBadOptions) {
  RegistrationOptions o;
  o.green_ratio = 1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.highpass_sigma_px = 0;
  EXPECT_THROW(MotionRegistration(cv::Size(320, 240), cv::Rect(0, 0, 320, 240), o), std::invalid_argument);
  EXPECT_THROW(MotionRegistration(cv::Size(320, 240), cv::Rect(400, 0, 20, 20), {}), std::invalid_argument);
}

}  // namespace
}  // namespace clearfit
