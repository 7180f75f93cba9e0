// clearfit assess on phone-like H.264 captures (clearfit simulate --format h264 at CRF 23,
// quarter resolution, yuv420p, limited range, BT.709): no false hotspot, the 4.9 mm hotspot
// found where the truth has it, the report names the codec and its noise holds the
// compression's spatial term.
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include "cli_support.hpp"

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

Eigen::Vector3d vec3(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

class LossyCli : public CliTest {};

TEST_F(LossyCli, H264CaptureFindsTheHotspotsAndNoFalseOne) {
  const std::string part = "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\nmap: {mode: adaptive}\n";
  write_text(work() / "sim.yaml",
             part + "camera: " + (kWristband / "camera.cameramodel").string() +
                 "\nsimulation:\n  seed: 23\n  scale: 0.25\n"
                 "  timeline: {fps: 30, baseline_s: 1.5, press_s: 2}\n  skin: {tone: medium}\n"
                 "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                 "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
                 "      - {name: b, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}\n"
                 "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n");
  // The format from the command line (the scene's simulation.format works too).
  const RunResult sim =
      run_clearfit({"simulate", "sim.yaml", "--out", "caps", "--format", "h264", "--crf", "23", "--quiet", "--no-cache"}, work(), work(), 300);
  ASSERT_EQ(sim.exit_code, 0) << sim;
  const auto truth = nlohmann::json::parse(read_text(work() / "caps" / "truth.json"));
  EXPECT_EQ(truth["video"]["format"], "h264");
  EXPECT_EQ(truth["video"]["codec"]["crf"], 23);
  ASSERT_TRUE(fs::exists(work() / "caps" / "worn.mp4"));
  const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "caps/presses.csv", "--person", "wearer-1", "--camera",
                                      "caps/camera.cameramodel", "--out", "caps/calibration.json"},
                                     work(), work(), 60);
  ASSERT_EQ(cal.exit_code, 0) << cal;
  write_text(work() / "assess.yaml",
             part + "camera: caps/camera.cameramodel\noutputs: {folder: out, texel_mm: 0.1}\n"
                    "captures: {baseline: caps/baseline.mp4, worn: caps/worn.mp4, window_frames: 30}\n"
                    "calibration: {pressure: caps/calibration.json, person: wearer-1}\nassess: {smoothing_mm: 0.5}\n");
  const RunResult r = run_clearfit({"assess", "assess.yaml", "--quiet", "--no-cache", "--no-html"}, work(), work(), 120);
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto rep = nlohmann::json::parse(read_text(work() / "out" / "report.json"));
  EXPECT_EQ(rep["captures"]["worn"]["codec"], "h264");
  EXPECT_TRUE(rep["captures"]["worn"]["lossy"].get<bool>());
  EXPECT_TRUE(rep["captures"]["worn"]["limited_range"].get<bool>());
  EXPECT_EQ(rep["captures"]["worn"]["colour_matrix"], "bt709");
  bool warned = false;
  for (const auto& w : rep["warnings"])
    warned = warned || (w.get<std::string>().find("lossy") != std::string::npos && w.get<std::string>().find("h264") != std::string::npos);
  EXPECT_TRUE(warned) << rep["warnings"].dump();
  const double spatial = rep["signal"]["noise_sigma_spatial"], temporal = rep["signal"]["noise_sigma_temporal"];
  std::printf("noise sigma: temporal %.5f, spatial term %.5f, total %.5f\n", temporal, spatial, rep["signal"]["noise_sigma"].get<double>());
  EXPECT_GT(spatial, 0.0);
  // Hotspots at 4.3 kPa against the truth: none farther than 1 mm from a truth hotspot; the truth hotspots
  // of 4 mm or more (equivalent diameter at 4.3 kPa) found within 0.25 mm.
  std::vector<Eigen::Vector3d> found;
  std::vector<double> found_sigma;  // their reported centre-of-pressure σ (the rms distance to the true centre)
  for (const auto& h : rep["hotspots"])
    if (h["threshold_kpa"].get<double>() == 4.3) {
      found.push_back(vec3(h["centre_of_pressure_mm"]));
      found_sigma.push_back(h["centre_of_pressure_sigma_mm"].is_number() ? h["centre_of_pressure_sigma_mm"].get<double>() : NAN);
    }
  for (const Eigen::Vector3d& m : found) {
    double best = 1e9;
    for (const auto& t : truth["hotspots"]) best = std::min(best, (m - vec3(t["centroid_part_mm"])).norm());
    EXPECT_LE(best, 1.0) << "false hotspot at " << m.transpose();
  }
  int large = 0;
  for (const auto& t : truth["hotspots"]) {
    const double diameter = 2 * std::sqrt(t["area_ge_4_3_kpa_mm2"].get<double>() / M_PI);
    if (diameter < 3) continue;
    ++large;
    double best = 1e9, sigma = NAN;
    for (std::size_t i = 0; i < found.size(); ++i)
      if (const double d = (found[i] - vec3(t["centroid_part_mm"])).norm(); d < best) best = d, sigma = found_sigma[i];
    std::printf("truth hotspot of %.1f mm: centroid error %.3f mm, its sigma %.3f mm\n", diameter, best, sigma);
    // At 480x270 the 3.1 mm hotspot (10 kPa) stays under the compression's detection limit (README, bench-lossy).
    // 0.25 mm, not 0.2: the 4.9 mm hotspot's centroid error moved from 0.165 to 0.183, 0.188 and 0.200 mm
    // between refraction maps that differ by less than their 1 um tolerance (the adaptive criterion of
    // fc35ba4 and three draws of its checks after it): the simulated H.264 capture re-encodes differently,
    // so the bound sat inside the run-to-run spread. Weighted by the pressure above the outline (2026-11-29) it is
    // 0.187 mm (0.207 weighted by the pressure): 0.2 would still sit inside that spread.
    // The reported σ covers it: within the 95 % disc (radius 1.73 σ, σ the rms distance); 0.259 mm, 0.72 σ.
    if (diameter >= 4) {
      EXPECT_LE(best, 0.25);
      EXPECT_LE(best, 1.73 * sigma);
    }
  }
  EXPECT_EQ(large, 2);
}

}  // namespace
}  // namespace clearfit::cli_test
