// The worn phase over time, end to end: clearfit simulate renders one video holding the
// baseline, the press and the skin refilling after the part's removal (quarter resolution,
// 30 fps), with the onset and refill time constants as truth (truth.json); clearfit assess
// follows the place over time. The refill τ is recovered within 10 % (τ of 0.3, 0.45, 1.3,
// 2.7 and 3.0 s: the ends of the 0.3–3 s range and between), the onset within two frames, the time above the threshold against the truth
// h(t) at the place's measured level; a refill too short to measure and a worn phase too
// short for its window say so.
#include <nlohmann/json.hpp>

#include <cmath>

#include "cli_support.hpp"

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class TimelineCli : public CliTest {
 protected:
  struct Case {
    double tau_on_s = 0.25, tau_off_s = 1.5, press_s = 2.5, release_s = 4;
    int window_frames = 20;
    /// The captures hold no motion (simulation preset none): motion compensation, which took 27 of the
    /// 30 s of CPU of SlowestRefill's assessment (435 frames), is left on in one case (FastRefill) only,
    /// so that the timeline is still followed through it; off, the refill τ there came out the same
    /// (2.953 against 2.949 s, σ 0.070 s).
    bool motion_compensation = false;
  };
  /// Simulates and assesses `c` in work(); returns the assess run.
  RunResult run_case(const Case& c) {
    const std::string common = "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\nmap: {mode: adaptive}\n";
    std::ostringstream sim;
    sim << common << "camera: " << (kWristband / "camera.cameramodel").string()
        << "\nsimulation:\n  seed: 5\n  format: huffyuv\n  scale: 0.25\n"
        << "  timeline: {fps: 30, baseline_s: 1.5, press_s: " << c.press_s << ", release_s: " << c.release_s << ", single_video: true}\n"
        << "  skin: {tone: light, tau_on_s: " << c.tau_on_s << ", tau_off_s: " << c.tau_off_s << "}\n"
        << "  pressure:\n    texel_mm: 0.1\n    sources:\n"
        << "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 25, sigma_mm: 3.5}\n";
    write_text(work() / "sim.yaml", sim.str());
    const RunResult s = run_clearfit({"simulate", "sim.yaml", "--out", "sim", "--quiet", "--no-cache", "--no-presses"}, work(), root() / "capture", 120);
    EXPECT_EQ(s.exit_code, 0) << s;
    write_text(work() / "assess.yaml", common + "camera: sim/camera.cameramodel\noutputs: {folder: out, texel_mm: 0.1}\n"
                                                "captures: {both: sim/capture.mkv, window_frames: " + std::to_string(c.window_frames) +
                                                ", motion_compensation: " + (c.motion_compensation ? "true" : "false") + "}\nassess: {smoothing_mm: 0.3, timeseries: {cell_px: 2}}\n");
    return run_clearfit({"assess", "assess.yaml", "--quiet", "--no-cache", "--no-html"}, work(), root() / "capture", 120);
  }
  nlohmann::json read_json(const std::string& name) { return nlohmann::json::parse(read_text(work() / name)); }

  /// Checks one refill case against the truth.
  void check_refill(const Case& c) {
    const RunResult r = run_case(c);
    ASSERT_EQ(r.exit_code, 0) << r;
    const nlohmann::json truth = read_json("sim/truth.json"), report = read_json("out/report.json");
    const nlohmann::json& t = report["timeline"];
    ASSERT_TRUE(t.is_object()) << report.dump(1);
    ASSERT_FALSE(t["places"].empty());
    const nlohmann::json& place = t["places"][0];
    const double fps = 30, tp = truth["video"]["press_time_s"], tr = truth["video"]["release_time_s"];
    // Removal found, refill τ within 10 %.
    ASSERT_TRUE(t["release_s"].is_number());
    EXPECT_NEAR(t["release_s"].get<double>(), tr, 0.5 * c.tau_off_s + 3 / fps);
    ASSERT_TRUE(place["refill"]["fitted"].get<bool>()) << place.dump(1);
    std::cerr << "refill tau " << place["refill"]["tau_s"].get<double>() << " +- " << place["refill"]["tau_sigma_s"].get<double>()
              << " s (truth " << c.tau_off_s << " s)\n";
    EXPECT_NEAR(place["refill"]["tau_s"].get<double>(), c.tau_off_s, 0.10 * c.tau_off_s) << place.dump(1);
    EXPECT_GT(place["refill"]["tau_sigma_s"].get<double>(), 0);
    // Onset within two frames.
    ASSERT_TRUE(place["onset"]["fitted"].get<bool>()) << place.dump(1);
    EXPECT_NEAR(place["onset"]["t0_s"].get<double>(), tp, 2 / fps) << place.dump(1);
    // Time above the threshold: y(t) = Y·h(t) with Y the place's level in the worn average.
    const double thr = report["thresholds_signal"][0], y = report["hotspots"][0]["levels"][0]["mean_signal"];
    ASSERT_GT(y, thr);
    const double h_release = 1 - std::exp(-(tr - tp) / c.tau_on_s);
    const double rise = tp - c.tau_on_s * std::log(1 - thr / y), fall = tr + c.tau_off_s * std::log(h_release * y / thr);
    const nlohmann::json& level = place["thresholds"][0];
    ASSERT_TRUE(level["reached"].get<bool>());
    EXPECT_NEAR(level["first_above_s"].get<double>(), rise, 3 / fps) << level.dump(1);
    EXPECT_NEAR(level["time_above_s"].get<double>(), fall - rise, std::max(3 / fps, 0.08 * (fall - rise))) << level.dump(1);
    // The outputs.
    for (const char* f : {"out/timeline.csv", "out/timeline_time_s.npy", "out/timeline_texels_signal.npy", "out/timeline_place_1.png"})
      EXPECT_TRUE(fs::is_regular_file(work() / f)) << f;
    const std::string csv = read_text(work() / "out/timeline.csv");
    EXPECT_EQ(csv.rfind("place,t_s,frames,signal", 0), 0u);
  }
};

TEST_F(TimelineCli, FastRefill) {
  check_refill({.tau_on_s = 0.2, .tau_off_s = 0.45, .release_s = 2.5, .motion_compensation = true});
}
TEST_F(TimelineCli, MediumRefill) { check_refill({.tau_on_s = 0.35, .tau_off_s = 1.3, .release_s = 5.5}); }
TEST_F(TimelineCli, SlowRefill) { check_refill({.tau_on_s = 0.25, .tau_off_s = 2.7, .release_s = 9.5}); }
// The ends of the 0.3–3 s range of refill time constants.
TEST_F(TimelineCli, FastestRefill) { check_refill({.tau_on_s = 0.2, .tau_off_s = 0.3, .release_s = 2.5}); }
TEST_F(TimelineCli, SlowestRefill) { check_refill({.tau_on_s = 0.25, .tau_off_s = 3.0, .release_s = 10.5}); }

TEST_F(TimelineCli, RefillTooShortSaysSo) {
  const RunResult r = run_case({.tau_off_s = 2.0, .release_s = 1.0});
  ASSERT_EQ(r.exit_code, 0) << r;
  const nlohmann::json report = read_json("out/report.json");
  const nlohmann::json& refill = report["timeline"]["places"][0]["refill"];
  EXPECT_FALSE(refill["fitted"].get<bool>());
  EXPECT_NE(refill["note"].get<std::string>().find("after the part's removal"), std::string::npos) << refill.dump(1);
  bool warned = false;
  for (const auto& w : report["warnings"]) warned = warned || w.get<std::string>().find("refill not measured") != std::string::npos;
  EXPECT_TRUE(warned) << report["warnings"].dump(1);
}

TEST_F(TimelineCli, WornPhaseTooShortForTheWindow) {
  const RunResult r = run_case({.press_s = 0.9, .release_s = 2, .window_frames = 25});
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("fewer than the 25 asked for"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(work() / "out" / "report.json"));
}

}  // namespace
}  // namespace clearfit::cli_test
