// clearfit simulate: a small scene renders videos, truth and presses; bad
// `simulation:` keys are named with their line, exit 2, nothing written.
#include <clearfit/camera/camera_model.hpp>
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
