// The skin's blur has one value per person: calibrate-pressure's field fit assumes one (--skin-blur-mm, alias
// --blur-mm) and writes it into the calibration (skin_blur_mm); assess undoes the calibration's blur unless the scene
// file or the command line gives one, and warns when a blur given differs from the calibration's (fit/skin_blur.hpp,
// cli/assess_setup.cpp). Checked end to end on a small simulated slab with one narrow place (10 kPa, σ 1.5 mm), where
// the blur undone changes the peak: the pressure assessed with the calibration's blur taken is the one assessed with
// that blur given, bit for bit, and differs from the one assessed with another blur.
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <clearfit/npy.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace clearfit::cli_test {
namespace {

class SkinBlurCli : public CliTest {
 protected:
  /// Simulated captures and presses of the slab in work()/captures (once per test).
  void simulate() {
    write_slab_part(work());
    write_text(work() / "sim.yaml", "mesh: slab.obj\nior: 1.49\ncontact: {group: contact}\ncamera: cam.cameramodel\n"
                                    "simulation:\n  seed: 21\n  format: huffyuv\n"
                                    "  timeline: {fps: 30, baseline_s: 1, press_s: 1.5}\n  skin: {tone: medium}\n"
                                    "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                                    "      - {name: a, type: gaussian, center_uv_mm: [12, 9], peak_kpa: 10, sigma_mm: 1.5}\n"
                                    "  presses: {diameters_mm: [3], levels: 9, repetitions: 2}\n");
    const RunResult sim = run_clearfit({"simulate", "sim.yaml", "--out", "captures", "--quiet", "--no-cache"}, work(), root() / "capture", 120);
    ASSERT_EQ(sim.exit_code, 0) << sim;
  }
  RunResult calibrate(const std::string& out, const std::vector<std::string>& extra) {
    std::vector<std::string> args{"calibrate-pressure", "--presses", "captures/presses.csv", "--person", "wearer-1", "--out", out};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_clearfit(args, work(), root() / "capture", 60);
  }
  /// Assesses with `calibration` into `out`; `assess_yaml` is the scene's assess section.
  nlohmann::json assess(const std::string& calibration, const std::string& out, const std::vector<std::string>& extra = {},
                        const std::string& assess_yaml = "") {
    write_text(work() / "scene.yaml", "mesh: slab.obj\nior: 1.49\ncontact: {group: contact}\ncamera: cam.cameramodel\n"
                                      "outputs: {folder: " + out + ", texel_mm: 0.1}\n"
                                      "captures: {baseline: captures/baseline.mkv, worn: captures/worn.mkv, window_frames: 20}\n"
                                      "calibration: {pressure: " + calibration + ", person: wearer-1}\n" + assess_yaml);
    std::vector<std::string> args{"assess", "scene.yaml", "--quiet", "--no-cache", "--no-html"};
    args.insert(args.end(), extra.begin(), extra.end());
    const RunResult r = run_clearfit(args, work(), root() / "capture", 120);
    EXPECT_EQ(r.exit_code, 0) << r;
    return nlohmann::json::parse(read_text(work() / out / "report.json"));
  }
  static std::string blur_warnings(const nlohmann::json& report) {
    std::string out;
    for (const auto& w : report["warnings"])
      if (w.get<std::string>().find("skin's blur") != std::string::npos) out += w.get<std::string>() + "\n";
    return out;
  }
};

TEST_F(SkinBlurCli, TheCalibrationRecordsItsBlurAndTheAssessmentUndoesIt) {
  simulate();
  if (HasFatalFailure()) return;
  // calibrate-pressure: the blur written into the calibration; --blur-mm is the same option.
  ASSERT_EQ(calibrate("cal.json", {"--skin-blur-mm", "0.45"}).exit_code, 0);
  ASSERT_EQ(calibrate("alias.json", {"--blur-mm", "0.45"}).exit_code, 0);
  ASSERT_EQ(calibrate("uniform.json", {"--pressure-field", "uniform"}).exit_code, 0);
  const auto cal = nlohmann::json::parse(read_text(work() / "cal.json")), alias = nlohmann::json::parse(read_text(work() / "alias.json"));
  EXPECT_EQ(cal["skin_blur_mm"], 0.45);
  EXPECT_EQ(alias["parameters"], cal["parameters"]);
  EXPECT_EQ(alias["skin_blur_mm"], 0.45);
  EXPECT_TRUE(nlohmann::json::parse(read_text(work() / "uniform.json"))["skin_blur_mm"].is_null());
  const RunResult bad = calibrate("bad.json", {"--skin-blur-mm", "9"});
  EXPECT_EQ(bad.exit_code, 2) << bad;
  EXPECT_NE(bad.err.find("--skin-blur-mm"), std::string::npos) << bad;

  // assess: the calibration's blur when none is given; the same pressure as with that blur given.
  const auto taken = assess("cal.json", "taken");
  EXPECT_EQ(taken["options"]["skin_blur_mm"], 0.45);
  EXPECT_EQ(taken["options"]["skin_blur_from"], "calibration");
  EXPECT_EQ(blur_warnings(taken), "");
  const auto given = assess("cal.json", "given", {"--skin-blur-mm", "0.45"});
  EXPECT_EQ(given["options"]["skin_blur_from"], "command line");
  EXPECT_EQ(blur_warnings(given), "");
  EXPECT_EQ(read_text(work() / "given" / "pressure.npy"), read_text(work() / "taken" / "pressure.npy"));  // bit for bit
  const npy::Float32Array p_taken = npy::read_float32(work() / "taken" / "pressure.npy");

  // Another blur given: kept, and a warning names both blurs and the calibration. Undoing less blur lowers the peak.
  const auto other = assess("cal.json", "other", {"--skin-blur-mm", "0.2"});
  EXPECT_EQ(other["options"]["skin_blur_mm"], 0.2);
  const std::string w = blur_warnings(other);
  for (const char* text : {"--skin-blur-mm 0.20 mm) differs from the 0.45 mm the calibration cal.json was fitted with", "peaks read low",
                           "calibrate-pressure --skin-blur-mm 0.20"})
    EXPECT_NE(w.find(text), std::string::npos) << text << "\n" << w;
  EXPECT_NE(read_text(work() / "other" / "pressure.npy"), read_text(work() / "taken" / "pressure.npy"));
  const npy::Float32Array p_other = npy::read_float32(work() / "other" / "pressure.npy");
  auto peak = [](const npy::Float32Array& a) {
    float m = 0;
    for (float v : a.values) m = std::isfinite(v) ? std::max(m, v) : m;
    return m;
  };
  std::printf("peak with the calibration's 0.45 mm undone %.2f kPa, with 0.2 mm %.2f kPa (truth 10)\n", peak(p_taken), peak(p_other));
  EXPECT_LT(peak(p_other), peak(p_taken));
  // The same from the scene file: named by its line.
  const auto in_file = assess("cal.json", "in_file", {}, "assess: {skin_blur_mm: 0.2}\n");
  EXPECT_EQ(in_file["options"]["skin_blur_from"], "scene file");
  EXPECT_NE(blur_warnings(in_file).find("scene.yaml: line 8, key 'assess.skin_blur_mm' 0.20 mm) differs from the 0.45 mm"), std::string::npos)
      << blur_warnings(in_file);
  // A calibration that models no blur (uniform): the default, no warning.
  const auto uniform = assess("uniform.json", "uniform", {"--skin-blur-mm", "0.2"});
  EXPECT_EQ(uniform["options"]["skin_blur_from"], "command line");
  EXPECT_EQ(blur_warnings(uniform), "");
}

}  // namespace
}  // namespace clearfit::cli_test
