// clearfit simulate: a small scene renders videos, truth and presses; bad
// `simulation:` keys are named with their line, exit 2, nothing written.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "slab_part.hpp"

using namespace clearfit;
using namespace clearfit::cli_test;

namespace {
class Simulate : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_slab_part(work());
  }
  void scene(const std::string& simulation) {
    write_text(work() / "scene.yaml", std::string("mesh: slab.obj\nior: 1.49\ncontact:\n  group: contact\ncamera: cam.cameramodel\n") +
                                          "simulation:\n" + simulation);
  }
};

const char* kGood = R"(  seed: 3
  format: png
  timeline: {fps: 10, baseline_s: 0.5, press_s: 0.4}
  skin: {tone: dark}
  pressure:
    texel_mm: 0.1
    sources:
      - {name: a, type: gaussian, center_uv_mm: [12, 9], peak_kpa: 15, sigma_mm: 2}
      - {name: b, type: punch, center_part_mm: [-6, 4, -0.5], radius_mm: 1.5, force_n: 0.1}
  presses: {diameters_mm: [2, 4], levels: 8, repetitions: 3, profile: uniform}
)";
}  // namespace

TEST_F(Simulate, WritesCapturesTruthAndPresses) {
  scene(kGood);
  const RunResult r = run({"simulate", "scene.yaml", "--out", "sim", "--no-cache"});
  ASSERT_EQ(r.exit_code, 0) << r;
  for (const char* f : {"baseline/frame_00004.png", "worn/frame_00003.png", "truth.json", "truth_pressure.npy",
                        "truth_vertex_pressure.npy", "presses.csv", "presses-truth.json"})
    EXPECT_TRUE(fs::exists(work() / "sim" / f)) << f << "\n" << r;
  EXPECT_FALSE(fs::exists(work() / "sim" / "baseline" / "frame_00005.png"));
  const auto j = nlohmann::json::parse(read_text(work() / "sim" / "truth.json"));
  EXPECT_EQ(j["video"]["baseline_frames"], 5);
  EXPECT_EQ(j["video"]["press_frames"], 4);
  EXPECT_EQ(j["pressure_sources"].size(), 2u);
  EXPECT_NEAR(j["pressure_sources"][1]["center_part_mm"][2].get<double>(), 0, 1e-9);  // moved onto the contact face
  EXPECT_EQ(j["skin"]["tone"], "dark");
  const std::string csv = read_text(work() / "sim" / "presses.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 2 * 8 * 3);
  EXPECT_NE(r.err.find("frame 9/9"), std::string::npos) << r;
}

// Rendered at half resolution, the scaled camera model keeps the projection uncertainty, each σ scaled as its
// pixels are (the scaled model's fx over the original's), the grid (here an older model's cells) and distance as they were.
TEST_F(Simulate, ScaledCameraKeepsItsProjectionUncertaintyInItsPixels) {
  const CameraModel cam = read_cameramodel(work() / "cam.cameramodel");
  ProjectionUncertainty u;
  u.nx = 2, u.ny = 1, u.distance_mm = 60, u.px = {0.4, 0.8}, u.layout = ProjectionUncertainty::Layout::cells;
  write_cameramodel(cam, u, work() / "cam.cameramodel");
  scene(kGood);
  const RunResult r = run({"simulate", "scene.yaml", "--out", "sim", "--no-cache", "--no-presses", "--scale", "0.5", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const CameraModel scaled = read_cameramodel(work() / "sim" / "camera.cameramodel");
  const double ratio = scaled.intrinsics[0] / cam.intrinsics[0];
  EXPECT_NEAR(ratio, 0.5, 1e-12);
  const auto v = read_projection_uncertainty(work() / "sim" / "camera.cameramodel");
  ASSERT_TRUE(v.has_value()) << read_text(work() / "sim" / "camera.cameramodel");
  EXPECT_EQ(v->layout, ProjectionUncertainty::Layout::cells);
  EXPECT_EQ(v->nx, 2);
  EXPECT_EQ(v->ny, 1);
  EXPECT_EQ(v->distance_mm, 60);
  ASSERT_EQ(v->px.size(), 2u);
  for (int k = 0; k < 2; ++k) EXPECT_NEAR(v->px[k], ratio * u.px[k], 1e-12) << k;
}

TEST_F(Simulate, BadKeysAreNamedWithTheirLine) {
  scene("  seed: 3\n  timeline: {fps: 10, baseline_s: 0.5, pres_s: 0.4}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 8", "simulation.timeline.pres_s", "unknown key"});
  scene("  skin:\n    tone: purple\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 8", "simulation.skin.tone", "purple"});
  scene("  pressure:\n    sources:\n      - {type: gaussian, peak_kpa: high, center_uv_mm: [1, 2]}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 9", "simulation.pressure.sources[0].peak_kpa", "high"});
  scene("  pressure:\n    sources:\n      - {type: gaussian, peak_kpa: 5}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 9", "center_uv_mm"});
  scene("  format: avi\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 7", "simulation.format"});
  scene("  camera: {supersample: 9}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 7", "simulation.camera.supersample"});
  scene("  presses: {levels: 1}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim"}, {"line 7", "simulation.presses.levels"});
  scene("  pressure:\n    sources:\n      - {type: gaussian, center_part_mm: [0, 0, -30]}\n");
  expect_input_error({"simulate", "scene.yaml", "--out", "sim", "--no-cache"}, {"scene.yaml", "from the contact surface"});
}

// simulation.preset: realistic renders every effect at the strengths README.md documents
// ("The realistic preset"); the scene's own keys replace the preset's; other presets are refused.
TEST_F(Simulate, RealisticPresetResolvesAndSceneKeysOverride) {
  const std::string base = std::string(kGood).substr(0, std::string(kGood).find("  presses:"));
  scene("  preset: realistic\n" + base);
  RunResult r = run({"simulate", "scene.yaml", "--out", "sim", "--no-cache", "--no-presses"});
  ASSERT_EQ(r.exit_code, 0) << r;
  auto p = nlohmann::json::parse(read_text(work() / "sim" / "truth.json"))["preset"];
  EXPECT_EQ(p["name"], "realistic");
  EXPECT_DOUBLE_EQ(p["motion"]["drift_px_per_s"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(p["motion"]["tremor_px"].get<double>(), 0.3);
  EXPECT_DOUBLE_EQ(p["motion"]["rotation_deg"].get<double>(), 0.3);
  EXPECT_DOUBLE_EQ(p["flicker"]["amplitude"].get<double>(), 0.03);
  EXPECT_DOUBLE_EQ(p["flicker"]["drift_hz_per_s"].get<double>(), 0.2);
  ASSERT_EQ(p["glare"].size(), 2u);
  EXPECT_EQ(p["glare"][1]["phases"], "worn");
  ASSERT_EQ(p["exposure"]["steps"].size(), 2u);
  EXPECT_DOUBLE_EQ(p["exposure"]["steps"][0]["gain"][0].get<double>(), 1.03);
  EXPECT_TRUE(fs::exists(work() / "sim" / "truth_gains.csv")) << r;
  EXPECT_TRUE(fs::exists(work() / "sim" / "truth_glare_worn.npy")) << r;
  // The skin slides and bulges (its truth written); the scene's `format: png` replaces the preset's H.264.
  EXPECT_DOUBLE_EQ(p["skin_motion"]["slide_mm"][0].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(p["skin_motion"]["bulge_mm"].get<double>(), 0.1);
  EXPECT_TRUE(fs::exists(work() / "sim" / "truth_displacement.npy")) << r;
  EXPECT_EQ(p["video"]["format"], "png");
  // The scene's keys win: one motion key, the glare list and the flicker amplitude; the rest stays the preset's.
  scene("  preset: realistic\n  motion: {tremor_px: 0}\n  glare: []\n  flicker: {amplitude: 0.01}\n" + base);
  r = run({"simulate", "scene.yaml", "--out", "sim2", "--no-cache", "--no-presses"});
  ASSERT_EQ(r.exit_code, 0) << r;
  p = nlohmann::json::parse(read_text(work() / "sim2" / "truth.json"))["preset"];
  EXPECT_DOUBLE_EQ(p["motion"]["tremor_px"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(p["motion"]["drift_px_per_s"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(p["flicker"]["amplitude"].get<double>(), 0.01);
  EXPECT_DOUBLE_EQ(p["flicker"]["drift_hz_per_s"].get<double>(), 0.2);
  EXPECT_EQ(p["glare"].size(), 0u);
  EXPECT_EQ(p["exposure"]["steps"].size(), 2u);
  // Without a format key the preset films as a phone does: H.264 at CRF 23.
  std::string no_format = base;
  no_format.erase(no_format.find("  format: png\n"), std::string("  format: png\n").size());
  scene("  preset: realistic\n" + no_format);
  r = run({"simulate", "scene.yaml", "--out", "sim5", "--no-cache", "--no-presses"});
  ASSERT_EQ(r.exit_code, 0) << r;
  p = nlohmann::json::parse(read_text(work() / "sim5" / "truth.json"))["preset"];
  EXPECT_EQ(p["video"]["format"], "h264");
  EXPECT_EQ(p["video"]["crf"].get<int>(), 23);
  EXPECT_TRUE(fs::exists(work() / "sim5" / "worn.mp4")) << r;
  // Without a preset: none, nothing added.
  scene(base);
  r = run({"simulate", "scene.yaml", "--out", "sim3", "--no-cache", "--no-presses"});
  ASSERT_EQ(r.exit_code, 0) << r;
  p = nlohmann::json::parse(read_text(work() / "sim3" / "truth.json"))["preset"];
  EXPECT_EQ(p["name"], "none");
  EXPECT_DOUBLE_EQ(p["motion"]["tremor_px"].get<double>(), 0.0);
  EXPECT_EQ(p["glare"].size(), 0u);
  // An unknown preset: exit 2, the key named, nothing written.
  scene("  preset: cinematic\n" + base);
  expect_input_error({"simulate", "scene.yaml", "--out", "sim4"}, {"line 7", "simulation.preset", "cinematic", "realistic"});
  EXPECT_FALSE(fs::exists(work() / "sim4"));
}

// Captures read from folders of images have no frame rate: report.json says null (not 0, which reads as a
// rate of zero frames a second), as report.html shows "— (images)".
TEST_F(Simulate, ImageFolderCapturesHaveNoFrameRateInTheReport) {
  write_text(work() / "scene.yaml", slab_scene(", motion_compensation: false", "", "  motion: {step_px: 0}\n"));
  RunResult r = run({"simulate", "scene.yaml", "--out", "sim", "--no-cache", "--no-presses", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r;
  ASSERT_TRUE(fs::is_directory(work() / "sim" / "baseline")) << "the slab's simulation writes png folders";
  r = run({"assess", "scene.yaml", "--no-cache", "--no-html", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto report = nlohmann::json::parse(read_text(work() / "out" / "report.json"));
  for (const char* phase : {"baseline", "worn"}) {
    const auto& c = report.at("captures").at(phase);
    ASSERT_TRUE(c.contains("fps")) << phase;
    EXPECT_TRUE(c["fps"].is_null()) << phase << ": " << c.dump();
  }
}
