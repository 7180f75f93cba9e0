// The simulator's photometric effects (glare per phase, gain and white-balance
// steps and drifts, drifting flicker) against their closed forms, and their
// truth files. Noiseless renders of a slab seen by a 320 × 240 camera.
#include <clearfit/fit/simulate.hpp>
#include <clearfit/fit/simulate_photometric.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <unistd.h>

#include "../support/slab_view.hpp"

namespace clearfit::sim {
namespace {
namespace fs = std::filesystem;

using Slab = test::SlabView;

// Mean linear value of channel c (0 B, 1 G, 2 R) over a (2r+1)² block.
double mean_linear(const cv::Mat& bgr, int c, int cx, int cy, int r) {
  const float* lin = srgb::to_linear_table8();
  double sum = 0;
  for (int y = cy - r; y <= cy + r; ++y)
    for (int x = cx - r; x <= cx + r; ++x) sum += lin[bgr.at<cv::Vec3b>(y, x)[c]];
  return sum / ((2 * r + 1) * (2 * r + 1));
}

TEST(SimulatePhotometric, GainsAndGlareFollowTheirClosedForms) {
  const Slab s;
  PressureFieldSpec spec;  // no pressure: only the light changes
  const PressureTruth truth = make_pressure_truth(s.part.mesh, s.part.contact, s.chart, spec);
  SkinParameters skin;
  skin.pulse_amplitude = 0;
  CameraSettings cam;
  cam.texture_mm = 0.04;
  cam.read_noise_e = 0, cam.full_well_e = 1e12;  // noiseless (8-bit quantisation only)
  cam.specular_peak = 0;
  cam.flicker_amplitude = 0.04, cam.flicker_hz = 100;
  const CaptureRenderer r(s.map, skin_drive(skin, truth.pressure), skin, cam, 3);
  Timeline tl;
  tl.fps = 30, tl.baseline_s = 1, tl.press_s = 1;
  PhotometricEffects fx;
  GlareBlob worn_only;
  worn_only.center = Vec2(0.6, 0.5), worn_only.sigma = 0.02, worn_only.peak = 0.2, worn_only.phases = GlareBlob::Phases::worn;
  fx.glare = {worn_only};
  fx.steps = {{0.5, {1.04, 0.95, 1.08}}};
  fx.drift_per_s = {0.0, 0.02, 0.0};
  fx.flicker_drift_hz_per_s = 0.5;
  const PhotometricSchedule sched(fx, cam, tl, cv::Size(r.width(), r.height()));

  // Gains: the flicker with its drifting frequency, the step from 0.5 s, the drift.
  for (int k : {0, 7, 14, 15, 22, 40}) {
    const double t = k / tl.fps;
    const double flick = 1 + 0.04 * std::sin(2 * std::numbers::pi * (100 * t + 0.25 * t * t));
    const FrameLight l = sched.frame(k);
    EXPECT_NEAR(l.gain[1], flick * (1 + 0.02 * t) * (t >= 0.5 ? 0.95 : 1), 1e-12) << k;
    EXPECT_NEAR(l.gain[2] / l.gain[1], (t >= 0.5 ? 1.08 / 0.95 : 1) / (1 + 0.02 * t), 1e-12) << k;
    EXPECT_EQ(l.glare != nullptr, true);
  }
  // Rendered: each channel scales by its gain away from the glare (the ratio of two frames).
  const int ax = 100, ay = 120;  // skin, far from the blob at (192, 120)
  const FrameLight l0 = sched.frame(3), l1 = sched.frame(40);  // baseline, worn
  const cv::Mat f0 = r.render(3 / tl.fps, 0, Vec2::Zero(), 3, &l0), f1 = r.render(40 / tl.fps, 0, Vec2::Zero(), 40, &l1);
  for (int c = 0; c < 3; ++c)  // c: B, G, R in the frame; gains are R, G, B
    EXPECT_NEAR(mean_linear(f1, c, ax, ay, 6) / mean_linear(f0, c, ax, ay, 6), l1.gain[2 - c] / l0.gain[2 - c], 0.004) << c;
  // The glare is white light added before the gains: worn − baseline at the blob centre,
  // each frame divided by its gain, is the blob's peak in every channel.
  const int gx = static_cast<int>(0.6 * r.width()), gy = static_cast<int>(0.5 * r.height());
  for (int c = 0; c < 3; ++c) {
    const double added = mean_linear(f1, c, gx, gy, 1) / l1.gain[2 - c] - mean_linear(f0, c, gx, gy, 1) / l0.gain[2 - c];
    EXPECT_NEAR(added, 0.2 * std::exp(-1.0 / (2 * 0.02 * 0.02 * 320 * 320)) , 0.006) << c;  // (±1 px block)
  }
  // Without a schedule the frame is the renderer's own (the flicker alone): unchanged defaults.
  FrameLight flicker_only;
  flicker_only.gain.fill(1 + 0.04 * std::sin(2 * std::numbers::pi * 100 * (3 / tl.fps)));
  EXPECT_EQ(cv::norm(r.render(3 / tl.fps, 0, Vec2::Zero(), 3), r.render(3 / tl.fps, 0, Vec2::Zero(), 3, &flicker_only), cv::NORM_INF), 0);

  // Truth files: gains per frame as the schedule gives them, glare images per phase.
  const fs::path dir = fs::temp_directory_path() / ("clearfit_sim_photometric_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto files = sched.write_truth(dir);
  EXPECT_EQ(files.size(), 4u);
  std::ifstream csv(dir / "truth_gains.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "frame,t_s,phase,gain_r,gain_g,gain_b");
  int rows = 0;
  while (std::getline(csv, line)) {
    int k;
    double t, gr, gg, gb;
    char phase[16];
    ASSERT_EQ(std::sscanf(line.c_str(), "%d,%lf,%15[a-z],%lf,%lf,%lf", &k, &t, phase, &gr, &gg, &gb), 6) << line;
    EXPECT_NEAR(gg, sched.frame(k).gain[1], 1e-8);
    EXPECT_STREQ(phase, k < 30 ? "baseline" : "worn");
    ++rows;
  }
  EXPECT_EQ(rows, 60);
  const cv::Mat gw = read_npy_2d(dir / "truth_glare_worn.npy"), gb = read_npy_2d(dir / "truth_glare_baseline.npy");
  EXPECT_EQ(gw.rows, 240);
  EXPECT_EQ(gw.cols, 320);
  double max_w, max_b;
  cv::minMaxLoc(gw, nullptr, &max_w);
  cv::minMaxLoc(gb, nullptr, &max_b);
  EXPECT_NEAR(max_w, 0.2, 0.01);
  EXPECT_EQ(max_b, 0.0);
  const auto j = nlohmann::json::parse(std::ifstream(dir / "truth_photometric.json"));
  EXPECT_EQ(j["glare"][0]["phases"], "worn");
  fs::remove_all(dir);
}

TEST(SimulatePhotometric, RefusesBadEffects) {
  PhotometricEffects fx;
  EXPECT_FALSE(fx.any());
  fx.glare.push_back({});
  EXPECT_TRUE(fx.any());
  fx.glare[0].sigma = 0;
  EXPECT_THROW(fx.validate(), std::invalid_argument);
  fx.glare[0].sigma = 0.03;
  fx.steps.push_back({-1, {1, 1, 1}});
  EXPECT_THROW(fx.validate(), std::invalid_argument);
  fx.steps[0].t_s = 1;
  EXPECT_NO_THROW(fx.validate());
}

}  // namespace
}  // namespace clearfit::sim
