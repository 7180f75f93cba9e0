// clearfit assess with its default motion compensation on a still camera and
// still skin whose blanching is strong (a quarter of the green): no motion is
// read into the press, the assessment succeeds and finds the hotspot where the
// truth puts it.
#include "cli_support.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class MotionCli : public CliTest {
 protected:
  /// Simulates into work()/captures (quarter resolution) and calibrates the wearer.
  void simulate(const std::string& motion) {
    const std::string part = "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\nmap: {mode: adaptive}\n";
    // The assessment reads the simulated (quarter-size) camera.
    write_text(work() / "scene.yaml", part + "camera: captures/camera.cameramodel\noutputs: {folder: out, texel_mm: 0.1}\n"
                                             "captures: {baseline: captures/baseline.mkv, worn: captures/worn.mkv, window_frames: 40}\n"
                                             "calibration: {pressure: captures/calibration.json, person: wearer-1}\n");
    write_text(work() / "sim.yaml",
               part + "camera: " + (kWristband / "camera.cameramodel").string() + "\n"
                   "simulation:\n  seed: 23\n  format: huffyuv\n  scale: 0.25\n"
                   "  timeline: {fps: 30, baseline_s: 1.5, press_s: 2.5}\n"
                   "  skin: {tone: dark, k_green: 0.3, texture_seed: 5}\n" + motion +
                   "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                   "      - {name: a, type: gaussian, center_part_mm: [-5, 2, 30], peak_kpa: 30, sigma_mm: 1.8}\n"
                   "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n");
    const RunResult sim = run_clearfit({"simulate", "sim.yaml", "--out", "captures", "--quiet", "--no-cache"}, work(), root() / "capture", 120);
    ASSERT_EQ(sim.exit_code, 0) << sim;
    const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "captures/presses.csv", "--person", "wearer-1",
                                        "--camera", "captures/camera.cameramodel", "--out", "captures/calibration.json"},
                                       work(), root() / "capture", 60);
    ASSERT_EQ(cal.exit_code, 0) << cal;
  }
  /// Assesses with the defaults; returns the report and the distance of the nearest hotspot to the truth's.
  std::pair<nlohmann::json, double> assess() {
    const RunResult r =
        run_clearfit({"assess", "scene.yaml", "--quiet", "--no-cache", "--no-html"},
                     work(), root() / "capture", 120);
    EXPECT_EQ(r.exit_code, 0) << r;
    if (r.exit_code != 0) return {nullptr, 1e9};
    const auto report = nlohmann::json::parse(read_text(work() / "out" / "report.json"));
    const auto truth = nlohmann::json::parse(read_text(work() / "captures" / "truth.json"));
    EXPECT_EQ(truth["hotspots"].size(), 1u);
    const auto& th = truth["hotspots"][0];
    const Eigen::Vector3d c(th["centroid_part_mm"][0], th["centroid_part_mm"][1], th["centroid_part_mm"][2]);
    double best = 1e9;
    for (const auto& h : report["hotspots"]) {
      if (h["threshold_kpa"].get<double>() != 4.3) continue;
      const Eigen::Vector3d m(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1], h["centre_of_pressure_mm"][2]);
      best = std::min(best, (m - c).norm());
    }
    return {report, best};
  }
};

TEST_F(MotionCli, StillStronglyBlanchingCaptureIsNotReadAsMotion) {
  simulate("");
  const auto [report, distance] = assess();
  ASSERT_FALSE(report.is_null());
  for (const char* phase : {"baseline", "worn"}) {
    const double motion = report["captures"][phase]["motion_px_max"];
    std::printf("%s: motion read %.4f px\n", phase, motion);
    // Per-frame noise of the reading at quarter resolution; a green registration reads the press as pixels.
    EXPECT_LE(motion, 0.5) << phase;
  }
  std::printf("hotspot found %.3f mm from the truth's centroid\n", distance);
  EXPECT_LE(distance, 0.1);
}

}  // namespace
}  // namespace clearfit::cli_test
