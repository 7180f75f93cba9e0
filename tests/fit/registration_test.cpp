// Motion registration (registration.hpp) on rendered skin (the simulator's
// slab scene, 320 × 240): strong blanching does not read as motion wherever it
// is, simulated drift, tremor and rotation are recovered against their truth,
// and a patch covered in glare is left out.
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/registration.hpp>
#include <clearfit/fit/simulate.hpp>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numbers>
#include <unistd.h>

#include "../support/slab_view.hpp"

namespace clearfit {
namespace {

namespace fs = std::filesystem;

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

/// Largest error of a measured motion against a true one, over the roi's corners and centre.
double motion_error(const Similarity& measured, const Vec2& shift, double angle, const Vec2& image_centre, const cv::Rect& roi) {
  double worst = 0;
  for (const Vec2& q : {Vec2(roi.x, roi.y), Vec2(roi.br().x, roi.y), Vec2(roi.x, roi.br().y), Vec2(roi.br().x, roi.br().y), centre_of(roi)}) {
    const Vec2 r = q - image_centre;
    const Vec2 truth = image_centre + Vec2(std::cos(angle) * r.x() - std::sin(angle) * r.y(), std::sin(angle) * r.x() + std::cos(angle) * r.y()) + shift - q;
    worst = std::max(worst, (measured.displacement(q) - truth).norm());
  }
  return worst;
}

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
      const int frames = 6;
      std::vector<Vec2> mean(4, Vec2::Zero());
      const cv::Rect& roi = v.roi;
      const std::vector<Vec2> corners{Vec2(roi.x, roi.y), Vec2(roi.br().x, roi.y), Vec2(roi.x, roi.br().y), Vec2(roi.br().x, roi.br().y)};
      for (int f = 1; f <= frames; ++f) {
        const RegistrationResult m = reg.measure(r->render(1.0 + f / 30.0, 1.0, Vec2::Zero(), f), Similarity{});
        ASSERT_TRUE(m.found);
        const double moved = m.motion.max_displacement(v.roi);
        worst = std::max(worst, moved);
        EXPECT_LE(moved, 0.15) << tone << ", press " << k << ", frame " << f << ": " << m.patches_used << " patches kept";
        for (std::size_t c = 0; c < corners.size(); ++c) mean[c] += m.motion.displacement(corners[c]) / frames;
      }
      for (const Vec2& c : mean) {
        worst_mean = std::max(worst_mean, c.norm());
        EXPECT_LE(c.norm(), 0.05) << tone << ", press " << k << ": mean motion read over " << frames << " frames";
      }
    }
    std::printf("%s skin (texture seed %u), strong blanching in each of %zu patches and in all: motion read at most %.4f px "
                "in a frame, %.4f px on average\n",
                tone.c_str(), texture_seed, probe.patches().size(), worst, worst_mean);
  }
}

TEST(Registration, RecoversSimulatedDriftTremorAndRotation) {
  const SkinView v;
  const SkinParameters skin = strong_skin("light", 9);
  sim::CameraSettings cam;
  cam.motion_drift_px_per_s = 2.5;
  cam.motion_tremor_px = 0.6, cam.motion_tremor_hz = 9;
  cam.motion_rotation_deg = 0.4;
  cam.motion_step_px = 0.03;
  const auto r = pressed(v, {v.uv_at(centre_of(v.roi))}, skin, 31, cam);
  sim::Timeline tl;
  tl.fps = 30, tl.baseline_s = 1, tl.press_s = 1;
  const fs::path dir = fs::temp_directory_path() / ("clearfit_registration_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const sim::CaptureSummary truth = sim::render_captures(*r, skin, tl, cam, sim::VideoFormat::png, dir, 31);
  MotionRegistration reg(cv::Size(v.map.width, v.map.height), v.roi, {});
  const Vec2 image_centre(0.5 * (v.map.width - 1), 0.5 * (v.map.height - 1));
  Similarity previous;
  double worst = 0, largest = 0;
  int frame = 0;
  for (const std::string stem : {"baseline", "worn"})
    for (int k = 0;; ++k, ++frame) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%05d.png", k);
      const cv::Mat img = cv::imread((dir / stem / name).string());
      if (img.empty()) break;
      if (!reg.has_reference()) {
        reg.set_reference(img);
        continue;
      }
      const RegistrationResult m = reg.measure(img, previous);
      ASSERT_TRUE(m.found) << "frame " << frame;
      previous = m.motion;
      const double err = motion_error(m.motion, truth.shift_px[frame], truth.angle_rad[frame], image_centre, v.roi);
      worst = std::max(worst, err);
      largest = std::max(largest, motion_error(Similarity{}, truth.shift_px[frame], truth.angle_rad[frame], image_centre, v.roi));
      EXPECT_LE(err, 0.05) << "frame " << frame;
    }
  fs::remove_all(dir);
  EXPECT_EQ(frame, tl.baseline_frames() + tl.press_frames());
  std::printf("drift, tremor, rotation (true motion up to %.2f px at the roi's corners): error at most %.4f px over %d frames\n",
              largest, worst, frame);
  EXPECT_GT(largest, 3.0);  // the motion was real
}

TEST(Registration, APatchCoveredInGlareIsLeftOut) {
  const SkinView v;
  const SkinParameters skin = strong_skin("dark", 12);
  const auto r = pressed(v, {v.uv_at(centre_of(v.roi))}, skin, 41);
  MotionRegistration reg(cv::Size(v.map.width, v.map.height), v.roi, {});
  reg.set_reference(r->render(0.0, 0.0, Vec2::Zero(), 0));
  const std::size_t glared = 5;
  const Vec2 shift(1.3, -0.7);
  cv::Mat img = r->render(0.1, 1.0, shift, 1);
  const cv::Rect p = reg.patches()[glared] + cv::Point(1, -1);
  cv::circle(img, cv::Point(p.x + p.width / 2, p.y + p.height / 2), p.width / 4, cv::Scalar(255, 255, 255), cv::FILLED);
  const RegistrationResult m = reg.measure(img, Similarity{});
  ASSERT_TRUE(m.found);
  EXPECT_TRUE(m.glare[glared]);
  EXPECT_FALSE(m.inlier[glared]);
  EXPECT_FALSE(std::isfinite(m.patch_shift[glared].x()));
  for (std::size_t k = 0; k < m.glare.size(); ++k)
    if (k != glared) {
      EXPECT_FALSE(m.glare[k]) << "patch " << k;
    }
  EXPECT_LE(motion_error(m.motion, shift, 0, Vec2::Zero(), v.roi), 0.05);
  // Glare in the reference frame: that patch is never used.
  MotionRegistration reg2(cv::Size(v.map.width, v.map.height), v.roi, {});
  reg2.set_reference(img);
  const RegistrationResult m2 = reg2.measure(r->render(0.2, 1.0, shift, 2), Similarity{});
  EXPECT_FALSE(std::isfinite(m2.patch_shift[glared].x()));
  EXPECT_EQ(m2.patches, static_cast<int>(reg2.patches().size()) - 1);
  EXPECT_LE(m2.motion.max_displacement(v.roi), 0.05);
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
