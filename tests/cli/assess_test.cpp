// clearfit assess end to end: captures simulated from a known pressure field
// (clearfit simulate, quarter resolution), the wearer calibrated from the
// simulated presses, then the assessment — hotspots where the truth puts
// them — and the bad inputs the issue names, each refused with exit 2 and no
// output folder.
#include "cli_support.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class AssessCli : public CliTest {
 protected:
  /// Simulated captures shared by the tests of this suite (rendered once).
  static fs::path captures() {
    static const fs::path dir = [] {
      const fs::path d = fs::temp_directory_path() / ("clearfit_assess_captures_" + std::to_string(::getpid()));
      fs::remove_all(d);
      fs::create_directories(d);
      write_text(d / "sim.yaml", "mesh: " + (kWristband / "wristband.obj").string() +
                                     "\ncontact: {group: contact}\ncamera: " + (kWristband / "camera.cameramodel").string() +
                                     "\nmap: {mode: adaptive}\n"
                                     "simulation:\n  seed: 11\n  format: huffyuv\n  scale: 0.25\n"
                                     "  timeline: {fps: 30, baseline_s: 2, press_s: 2.5}\n  skin: {tone: medium}\n"
                                     "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                                     "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
                                     "      - {name: b, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}\n"
                                     "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n");
      const RunResult sim = run_clearfit({"simulate", "sim.yaml", "--out", "captures", "--quiet", "--no-cache"}, d, d, 300);
      if (sim.exit_code != 0) throw std::runtime_error("simulate failed:\n" + sim.err);
      const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "captures/presses.csv", "--person", "wearer-1",
                                          "--camera", "captures/camera.cameramodel", "--out", "captures/calibration.json"},
                                         d, d, 60);
      if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
      return d / "captures";
    }();
    return dir;
  }
  static void TearDownTestSuite() { fs::remove_all(captures().parent_path()); }

  /// A scene in work() using the shared captures; `extra` is appended verbatim.
  fs::path scene(const std::string& captures_yaml, const std::string& extra = "",
                 const std::string& camera = "") {
    const fs::path c = captures();
    const std::string cam = camera.empty() ? (c / "camera.cameramodel").string() : camera;
    write_text(work() / "scene.yaml", "mesh: " + (kWristband / "wristband.obj").string() +
                                          "\ncontact: {group: contact}\ncamera: " + cam +
                                          "\nmap: {mode: adaptive}\noutputs: {folder: out, texel_mm: 0.1}\n" + captures_yaml +
                                          extra);
    return work() / "scene.yaml";
  }
  std::string two_captures(int window = 40) const {
    const fs::path c = captures();
    return "captures: {baseline: " + (c / "baseline.mkv").string() + ", worn: " + (c / "worn.mkv").string() +
           ", window_frames: " + std::to_string(window) + "}\n";
  }
  std::string calibration(const std::string& person = "wearer-1") const {
    return "calibration: {pressure: " + (captures() / "calibration.json").string() + ", person: " + person + "}\n";
  }
  RunResult assess(const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args{"assess", "scene.yaml", "--quiet", "--no-cache", "--no-html"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_clearfit(args, work(), root() / "capture", 120);
  }
  void expect_refused(const RunResult& r, const std::string& needle) {
    EXPECT_EQ(r.exit_code, 2) << r;
    EXPECT_NE(r.err.find(needle), std::string::npos) << "expected '" << needle << "' in\n" << r;
    EXPECT_FALSE(fs::exists(work() / "out")) << "output folder left behind";
  }
};

TEST_F(AssessCli, FindsTheSimulatedHotspotsWhereTheTruthPutsThem) {
  scene(two_captures(), calibration());
  const RunResult r = assess();
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto report = nlohmann::json::parse(read_text(work() / "out" / "report.json"));
  const auto truth = nlohmann::json::parse(read_text(captures() / "truth.json"));
  EXPECT_EQ(report["schema"], "clearfit.report/1");
  for (const char* f : {"heatmap.glb", "heatmap_signal.glb", "chart_pressure.png", "chart_signal.png", "skin_camera.png",
                        "skin_chart.png", "pressure.npy", "signal.npy"})
    EXPECT_TRUE(fs::exists(work() / "out" / f)) << f;
  ASSERT_FALSE(report["pressure"].is_null());
  for (const auto& th : truth["hotspots"]) {
    const Eigen::Vector3d c(th["centroid_part_mm"][0], th["centroid_part_mm"][1], th["centroid_part_mm"][2]);
    double best = 1e9;
    for (const auto& h : report["hotspots"]) {
      if (h["threshold_kpa"].get<double>() != 4.3) continue;
      const Eigen::Vector3d m(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1], h["centre_of_pressure_mm"][2]);
      best = std::min(best, (m - c).norm());
    }
    std::printf("truth hotspot at (%.2f, %.2f, %.2f): nearest measured centre of pressure %.3f mm away\n", c.x(), c.y(), c.z(), best);
    EXPECT_LT(best, 0.3);
  }
  // Provenance: every input hashed.
  for (const auto& in : report["inputs"]) EXPECT_EQ(in["sha256"].get<std::string>().size(), 64u) << in;
}

TEST_F(AssessCli, WithoutCalibrationReportsTheSignal) {
  scene(two_captures());
  const RunResult r = assess();
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto report = nlohmann::json::parse(read_text(work() / "out" / "report.json"));
  EXPECT_TRUE(report["pressure"].is_null());
  EXPECT_GE(report["hotspots"].size(), 2u);
  for (const auto& h : report["hotspots"]) EXPECT_TRUE(h["peak_kpa"].is_null());
}

TEST_F(AssessCli, RefusesBadInputAndLeavesNothing) {
  scene(two_captures(1000), calibration());
  expect_refused(assess(), "fewer than the 1000");
  scene("captures: {baseline: " + (captures() / "baseline.mkv").string() + "}\n");
  expect_refused(assess(), "phase is missing");
  scene("captures: {baseline: x.mkv, worn: y.mkv, windw_frames: 3}\n");
  expect_refused(assess(), "captures.windw_frames");
  scene(two_captures(), "", (kWristband / "camera.cameramodel").string());  // full-size camera, quarter-size frames
  expect_refused(assess(), "does not match the camera's imager");
  scene(two_captures(), calibration("someone-else"));
  expect_refused(assess(), "someone-else");
}

}  // namespace
}  // namespace clearfit::cli_test
