// clearfit assess on captures whose skin slid and bulged between the phases
// (clearfit simulate's simulation.skin_motion, quarter resolution), with the
// default phase registration and without it (--no-phase-registration), against
// the simulation's truth: the hotspots' centroids, the per-vertex pressure
// (Pearson), and the recovered displacement field against truth_displacement.npy;
// a still capture, where the registration must change nothing.
#include <clearfit/npy.hpp>
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <map>

#include "cli_support.hpp"

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class PhaseRegistrationCli : public CliTest {
 protected:
  static fs::path dir() {
    static const fs::path d = [] {
      const fs::path p = fs::temp_directory_path() / ("clearfit_phase_registration_" + std::to_string(::getpid()));
      fs::remove_all(p);
      fs::create_directories(p);
      return p;
    }();
    return d;
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }

  /// Renders the wristband (two Gaussian hotspots) with `motion` (simulation keys) into dir()/name.
  static fs::path render(const std::string& name, const std::string& motion, int seed, int texture_seed, bool presses = false) {
    const fs::path d = dir();
    write_text(d / (name + ".yaml"),
               "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\ncamera: " +
                   (kWristband / "camera.cameramodel").string() + "\nmap: {mode: adaptive}\n"
                   "simulation:\n  seed: " + std::to_string(seed) + "\n  format: huffyuv\n  scale: 0.25\n"
                   "  timeline: {fps: 30, baseline_s: 1.2, press_s: 1.8}\n"
                   "  skin: {tone: light, texture_seed: " + std::to_string(texture_seed) + "}\n"
                   "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                   "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
                   "      - {name: b, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}\n"
                   "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n" + motion);
    std::vector<std::string> args{"simulate", name + ".yaml", "--out", name, "--quiet", "--no-cache"};
    if (!presses) args.push_back("--no-presses");
    const RunResult sim = run_clearfit(args, d, d, 300);
    if (sim.exit_code != 0) throw std::runtime_error("simulate failed:\n" + sim.err);
    return d / name;
  }
  /// Renders (with presses) and calibrates the wearer from them.
  static fs::path render_calibrated(const std::string& name, const std::string& motion, int seed, int texture_seed) {
    const fs::path p = render(name, motion, seed, texture_seed, true);
    const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", name + "/presses.csv", "--person", "wearer-1", "--camera",
                                        name + "/camera.cameramodel", "--out", name + "/calibration.json"},
                                       dir(), dir(), 60);
    if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
    return p;
  }
  RunResult assess(const fs::path& caps, const std::string& out_name, const std::vector<std::string>& extra = {}) {
    write_text(work() / (out_name + ".yaml"),
               "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\ncamera: " +
                   (caps / "camera.cameramodel").string() + "\nmap: {mode: adaptive}\noutputs: {folder: " + out_name +
                   ", texel_mm: 0.1}\ncaptures: {baseline: " + (caps / "baseline.mkv").string() + ", worn: " +
                   (caps / "worn.mkv").string() + ", window_frames: 30}\ncalibration: {pressure: " +
                   (caps / "calibration.json").string() + ", person: wearer-1}\nassess: {smoothing_mm: 0.5}\n");
    std::vector<std::string> args{"assess", out_name + ".yaml", "--quiet", "--no-cache", "--no-html", "--no-timeseries"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_clearfit(args, work(), root() / "capture", 120);
  }
  nlohmann::json report(const std::string& out_name) { return nlohmann::json::parse(read_text(work() / out_name / "report.json")); }

  /// Per truth hotspot: the distance to the nearest measured 4.3 kPa hotspot's centre of pressure, mm.
  static std::vector<double> centroid_errors(const nlohmann::json& r, const fs::path& caps) {
    const auto truth = nlohmann::json::parse(read_text(caps / "truth.json"));
    std::vector<double> out;
    for (const auto& t : truth["hotspots"]) {
      const Eigen::Vector3d c(t["centroid_part_mm"][0], t["centroid_part_mm"][1], t["centroid_part_mm"][2]);
      double best = 1e9;
      for (const auto& h : r["hotspots"])
        if (h["threshold_kpa"].get<double>() == 4.3)
          best = std::min(best, (Eigen::Vector3d(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1],
                                                 h["centre_of_pressure_mm"][2]) - c).norm());
      out.push_back(best);
    }
    return out;
  }
  static int hotspots_at(const nlohmann::json& r, double kpa) {
    int n = 0;
    for (const auto& h : r["hotspots"]) n += h["threshold_kpa"].get<double>() == kpa;
    return n;
  }
  /// Per-vertex pressure (vertices.csv; NaN where not given).
  std::vector<double> vertex_pressure(const std::string& out_name) {
    std::istringstream in(read_text(work() / out_name / "vertices.csv"));
    std::string line;
    std::getline(in, line);  // vertex,x_mm,y_mm,z_mm,contact,seen,pressure_kpa,signal
    std::vector<double> p;
    while (std::getline(in, line)) {
      std::vector<std::string> cells;
      std::stringstream row(line);
      for (std::string c; std::getline(row, c, ',');) cells.push_back(c);
      p.push_back(cells.size() > 6 && !cells[6].empty() ? std::stod(cells[6]) : NAN);
    }
    return p;
  }
  /// Pearson correlation of the per-vertex pressure with the truth's, over vertices with both.
  double pearson_with_truth(const std::string& out_name, const fs::path& caps) {
    const npy::Float32Array t = npy::read_float32(caps / "truth_vertex_pressure.npy");
    const std::vector<double> m = vertex_pressure(out_name);
    EXPECT_EQ(t.values.size(), m.size());
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    for (std::size_t v = 0; v < std::min(t.values.size(), m.size()); ++v) {
      const double x = t.values[v], y = m[v];
      if (!std::isfinite(x) || !std::isfinite(y)) continue;
      sa += x, sb += y, saa += x * x, sbb += y * y, sab += x * y, n += 1;
    }
    EXPECT_GT(n, 500);
    return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
  }
  /// Median and 95th percentile of |recovered − true| displacement over the texels the report defines (mm):
  /// the truth (on the simulation's chart grid) is read at each report texel's chart uv (nearest texel).
  std::pair<double, double> field_error(const std::string& out_name, const fs::path& caps) {
    const npy::Float32Array d = npy::read_float32(work() / out_name / "displacement.npy");
    const npy::Float32Array t = npy::read_float32(caps / "truth_displacement.npy");
    const auto r = report(out_name), truth = nlohmann::json::parse(read_text(caps / "truth.json"));
    const double tex = r["chart"]["texel_mm"], u0 = r["chart"]["uv_min_mm"][0], v0 = r["chart"]["uv_min_mm"][1];
    const auto& tg = truth["chart_grid"];
    const double ttex = tg["texel_mm"], tu0 = tg["uv_origin_mm"][0], tv0 = tg["uv_origin_mm"][1];
    const int h = static_cast<int>(d.shape[0]), w = static_cast<int>(d.shape[1]);
    const int th = static_cast<int>(t.shape[0]), tw = static_cast<int>(t.shape[1]);
    std::vector<double> e;
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i) {
        const float dx = d.values[2 * (j * w + i)], dy = d.values[2 * (j * w + i) + 1];
        if (!std::isfinite(dx) || !std::isfinite(dy)) continue;
        const int ti = std::clamp(static_cast<int>(std::lround((u0 + tex * i - tu0) / ttex)), 0, tw - 1);
        const int tj = std::clamp(static_cast<int>(std::lround((v0 + tex * j - tv0) / ttex)), 0, th - 1);
        e.push_back(std::hypot(dx - t.values[2 * (tj * tw + ti)], dy - t.values[2 * (tj * tw + ti) + 1]));
      }
    EXPECT_GT(e.size(), 1000u);
    std::sort(e.begin(), e.end());
    return {e[e.size() / 2], e[e.size() * 95 / 100]};
  }
};

TEST_F(PhaseRegistrationCli, SlideAndBulgesAreRegistered) {
  const fs::path caps = render_calibrated("slide", "  skin_motion: {slide_mm: [0.3, 0.0], bulge_mm: 0.2, bulge_width_mm: 1.0}\n", 21, 1);
  const RunResult on = assess(caps, "registered");
  ASSERT_EQ(on.exit_code, 0) << on;
  const RunResult off = assess(caps, "unregistered", {"--no-phase-registration"});
  ASSERT_EQ(off.exit_code, 0) << off;
  const auto ron = report("registered"), roff = report("unregistered");
  const auto e_on = centroid_errors(ron, caps), e_off = centroid_errors(roff, caps);
  const double p_on = pearson_with_truth("registered", caps), p_off = pearson_with_truth("unregistered", caps);
  const auto [median, p95] = field_error("registered", caps);
  std::printf("centroid errors registered %.3f, %.3f mm; unregistered %.3f, %.3f mm\n", e_on[0], e_on[1], e_off[0], e_off[1]);
  std::printf("per-vertex Pearson registered %.4f, unregistered %.4f; hotspots >= 4.3 kPa %d vs %d\n", p_on, p_off,
              hotspots_at(ron, 4.3), hotspots_at(roff, 4.3));
  std::printf("field error median %.4f mm, p95 %.4f mm; reported magnitude median %.3f p95 %.3f max %.3f mm; %.0f ms\n", median,
              p95, ron["phase_registration"]["magnitude_mm"]["median"].get<double>(),
              ron["phase_registration"]["magnitude_mm"]["p95"].get<double>(), ron["phase_registration"]["magnitude_mm"]["max"].get<double>(),
              ron["phase_registration"]["time_ms"].get<double>());
  ASSERT_EQ(e_on.size(), 2u);
  for (double e : e_on) EXPECT_LE(e, 0.15);
  // The 0.97. With the places' tails read (AssessmentOptions::hysteresis_sigmas) the registered run
  // measured 0.976 and the unregistered one 0.848 (0.92 and 0.72 when the tails were read as 0 kPa).
  EXPECT_GE(p_on, 0.97);
  EXPECT_LT(p_off, 0.9);
  EXPECT_GT(p_on - p_off, 0.1);
  EXPECT_LE(median, 0.03);
  EXPECT_LE(p95, 0.1);
  // Unregistered, the slid texture left 59 false places before the signal's noise held the texture that does
  // not cancel between the phases (BlanchingOptions::local_spatial_noise, on with a held baseline); it still
  // misplaces the true ones (above), and registration must not add places.
  EXPECT_LE(hotspots_at(ron, 4.3), hotspots_at(roff, 4.3));
  EXPECT_EQ(hotspots_at(ron, 4.3), 2);
  EXPECT_NEAR(ron["phase_registration"]["magnitude_mm"]["median"].get<double>(), 0.3, 0.03);
  EXPECT_TRUE(fs::exists(work() / "registered" / "displacement.npy"));
  EXPECT_FALSE(fs::exists(work() / "unregistered" / "displacement.npy"));
  EXPECT_TRUE(roff["phase_registration"].is_null());
}

TEST_F(PhaseRegistrationCli, AnotherSlideDirectionAndSeed) {
  // Not tuned on: another direction and size of slide, weaker and wider bulges, other noise and texture.
  const fs::path caps = render_calibrated("oblique", "  skin_motion: {slide_mm: [-0.15, 0.22], bulge_mm: 0.12, bulge_width_mm: 1.5}\n", 33, 4);
  const RunResult on = assess(caps, "registered");
  ASSERT_EQ(on.exit_code, 0) << on;
  const auto r = report("registered");
  const auto e = centroid_errors(r, caps);
  const double p = pearson_with_truth("registered", caps);
  const auto [median, p95] = field_error("registered", caps);
  std::printf("centroid errors %.3f, %.3f mm; per-vertex Pearson %.4f; field error median %.4f p95 %.4f mm\n", e[0], e[1], p, median, p95);
  for (double x : e) EXPECT_LE(x, 0.15);
  EXPECT_GE(p, 0.92);
  EXPECT_LE(median, 0.03);
  EXPECT_LE(p95, 0.1);
}

TEST_F(PhaseRegistrationCli, StillCaptureIsLeftAlone) {
  const fs::path caps = render_calibrated("still", "", 21, 1);
  const RunResult on = assess(caps, "registered");
  ASSERT_EQ(on.exit_code, 0) << on;
  const RunResult off = assess(caps, "unregistered", {"--no-phase-registration"});
  ASSERT_EQ(off.exit_code, 0) << off;
  const auto ron = report("registered"), roff = report("unregistered");
  const auto& m = ron["phase_registration"]["magnitude_mm"];
  const double p_on = pearson_with_truth("registered", caps), p_off = pearson_with_truth("unregistered", caps);
  const auto e_on = centroid_errors(ron, caps), e_off = centroid_errors(roff, caps);
  std::printf("still: field median %.4f p95 %.4f max %.4f mm; Pearson %.4f registered, %.4f not; centroids %.3f/%.3f vs %.3f/%.3f mm\n",
              m["median"].get<double>(), m["p95"].get<double>(), m["max"].get<double>(), p_on, p_off, e_on[0], e_on[1], e_off[0], e_off[1]);
  // The default baseline is held 1 mm off the skin and seen through its own map: the field's noise is
  // largest at the band's oblique sides (fewest pixels per mm), 0.07 mm p95 and 0.14 mm at most here.
  EXPECT_LE(m["p95"].get<double>(), 0.08);
  EXPECT_LE(m["max"].get<double>(), 0.15);
  EXPECT_NEAR(p_on, p_off, 0.005);
  // 0.035 mm, not 0.03: the second hotspot's difference was 0.030 mm before 38300ff (the adaptive map's
  // drawn checks) and 0.031 after, with maps within 1 um of each other: the bound sat at the noise.
  for (std::size_t k = 0; k < e_on.size(); ++k) EXPECT_NEAR(e_on[k], e_off[k], 0.035);
  EXPECT_EQ(hotspots_at(ron, 5.5), hotspots_at(roff, 5.5));
  for (const auto& w : ron["warnings"]) EXPECT_EQ(w.get<std::string>().find("registration of the phases"), std::string::npos) << w;
}

}  // namespace
}  // namespace clearfit::cli_test
