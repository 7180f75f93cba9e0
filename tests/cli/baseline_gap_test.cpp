// The not-worn capture's own geometry end to end: captures rendered by
// clearfit simulate (quarter resolution) with the part held off the skin by a
// known gap, or absent; clearfit assess with its defaults (baseline held, gap
// auto) recovers the gap and the hotspots against the simulated truth, where
// the single-map assessment (baseline.part: touching) does not; bad gaps are
// refused with exit 2.
#include <clearfit/fit/simulate.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/npy.hpp>
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include "cli_support.hpp"
#include "shared_fixture.hpp"

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class BaselineGapCli : public CliTest {
 protected:
  static fs::path dir() {
    static const fs::path d = [] {
      const fs::path p = fs::temp_directory_path() / ("clearfit_baseline_gap_" + std::to_string(::getpid()));
      fs::remove_all(p);
      fs::create_directories(p);
      return p;
    }();
    return d;
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }

  /// The simulation scene of the wristband (two hotspots) with `baseline` (simulation.baseline keys).
  static std::string simulation(const std::string& baseline, const std::string& skin, const std::string& extra = "") {
    return "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\ncamera: " +
           (kWristband / "camera.cameramodel").string() + "\nmap: {mode: adaptive}\n"
           "simulation:\n  seed: 31\n  format: huffyuv\n  scale: 0.25\n"
           "  timeline: {fps: 30, baseline_s: 1.5, press_s: 2}\n  skin: {tone: light" + skin + "}\n"
           "  baseline: " + baseline + "\n"
           "  pressure:\n    texel_mm: 0.1\n    sources:\n"
           "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
           "      - {name: b, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}\n"
           "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n" + extra;
  }
  /// Renders `yaml` into d/name.
  static fs::path render_in(const fs::path& d, const std::string& name, const std::string& yaml, bool presses) {
    write_text(d / (name + ".yaml"), yaml);
    std::vector<std::string> args{"simulate", name + ".yaml", "--out", name, "--quiet", "--no-cache"};
    if (!presses) args.push_back("--no-presses");
    const RunResult sim = run_clearfit(args, d, d, 300);
    if (sim.exit_code != 0) throw std::runtime_error("simulate failed:\n" + sim.err);
    return d / name;
  }
  /// Renders the wristband with `baseline` (simulation.baseline keys) into dir()/name.
  static fs::path render(const std::string& name, const std::string& baseline, bool presses = false, const std::string& skin = "",
                         const std::string& extra = "") {
    return render_in(dir(), name, simulation(baseline, skin, extra), presses);
  }
  /// The wearer's calibration (from simulated presses, held 2.0 mm), made once for every test process
  /// (shared_fixture.hpp); its captures beside it.
  static fs::path calibration() {
    static const fs::path c = [] {
      const std::string yaml = simulation("{part: held, gap_mm: 2.0}", "");
      const fs::path d = shared_fixture("baseline-gap-held2", yaml, {kWristband / "wristband.obj", kWristband / "camera.cameramodel"},
                                        [&](const fs::path& into) {
        render_in(into, "held2", yaml, true);
        const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "held2/presses.csv", "--person", "wearer-1", "--camera",
                                            "held2/camera.cameramodel", "--out", "held2/calibration.json"},
                                           into, into, 60);
        if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
      });
      return d / "held2" / "calibration.json";
    }();
    return c;
  }
  /// Assesses baseline from `base` and worn from `worn` into work()/out_name (default options plus `extra`).
  RunResult assess(const fs::path& base, const fs::path& worn, const std::string& out_name, const std::vector<std::string>& extra = {},
                   bool calibrated = false) {
    const std::string cal = calibrated ? "calibration: {pressure: " + calibration().string() + ", person: wearer-1}\n" : "";
    write_text(work() / (out_name + ".yaml"),
               "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\ncamera: " +
                   (worn / "camera.cameramodel").string() + "\nmap: {mode: adaptive}\noutputs: {folder: " + out_name +
                   ", texel_mm: 0.1}\ncaptures: {baseline: " + (base / "baseline.mkv").string() + ", worn: " +
                   (worn / "worn.mkv").string() + ", window_frames: 30}\n" + cal + "assess: {smoothing_mm: 0.5}\n");
    std::vector<std::string> args{"assess", out_name + ".yaml", "--quiet", "--no-cache", "--no-html"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_clearfit(args, work(), root() / "capture", 120);
  }
  nlohmann::json report(const std::string& out_name) { return nlohmann::json::parse(read_text(work() / out_name / "report.json")); }
  /// The bundled sample's scene as shipped, rendered at a quarter of its resolution with its own seed, presses
  /// included, and its wearer's calibration from them; made once per test process.
  static fs::path quarter_sample() {
    static const fs::path caps = [] {
      const fs::path c = dir() / "sample_quarter";
      const RunResult sim = run_clearfit({"simulate", (kWristband / "scene.yaml").string(), "--out", c.string(), "--scale", "0.25",
                                          "--quiet", "--no-cache"},
                                         dir(), dir(), 600);
      if (sim.exit_code != 0) throw std::runtime_error("simulate failed:\n" + sim.err);
      const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", (c / "presses.csv").string(), "--person", "wearer-1",
                                          "--camera", (c / "camera.cameramodel").string(), "--out", (c / "calibration.json").string()},
                                         dir(), dir(), 120);
      if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
      return c;
    }();
    return caps;
  }
  /// Assesses the quarter sample with the sample's own scene (its window, texel, smoothing, thresholds and
  /// calibration) into work()/out_name, with `extra` options.
  RunResult assess_sample(const std::string& out_name, const std::vector<std::string>& extra = {}) {
    const fs::path caps = quarter_sample();
    std::string yaml = read_text(kWristband / "scene.yaml");
    auto replace = [&](const std::string& from, const std::string& to) {
      for (std::size_t at = yaml.find(from); at != std::string::npos; at = yaml.find(from, at + to.size())) yaml.replace(at, from.size(), to);
    };
    replace("mesh: wristband.obj", "mesh: " + (kWristband / "wristband.obj").string());
    replace("camera: camera.cameramodel", "camera: " + (caps / "camera.cameramodel").string());
    replace("captures/", caps.string() + "/");
    replace("out/assessment", out_name);
    replace("out/", out_name + "-map/");
    write_text(work() / (out_name + ".yaml"), yaml);
    std::vector<std::string> args{"assess", out_name + ".yaml", "--quiet", "--no-cache", "--no-html"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_clearfit(args, work(), root() / "capture", 300);
  }
  /// Hotspots at 4.3 kPa whose centre of pressure is more than 1 mm from every truth hotspot's centroid.
  static int false_places(const nlohmann::json& r, const fs::path& caps) {
    const auto truth = nlohmann::json::parse(read_text(caps / "truth.json"));
    int n = 0;
    for (const auto& h : r["hotspots"]) {
      if (h["threshold_kpa"].get<double>() != 4.3) continue;
      const Eigen::Vector3d c(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1], h["centre_of_pressure_mm"][2]);
      double best = 1e9;
      for (const auto& t : truth["hotspots"])
        best = std::min(best, (Eigen::Vector3d(t["centroid_part_mm"][0], t["centroid_part_mm"][1], t["centroid_part_mm"][2]) - c).norm());
      n += best > 1.0;
    }
    return n;
  }
  void expect_recovered(double gap);
  static double truth_gap(const fs::path& caps) {
    return nlohmann::json::parse(read_text(caps / "truth.json"))["baseline"]["gap_mm"].get<double>();
  }

  /// Largest distance from a truth hotspot to the nearest measured centre of pressure (4.3 kPa).
  static double worst_centroid_mm(const nlohmann::json& r, const fs::path& caps) {
    const auto truth = nlohmann::json::parse(read_text(caps / "truth.json"));
    double worst = 0;
    for (const auto& t : truth["hotspots"]) {
      const Eigen::Vector3d c(t["centroid_part_mm"][0], t["centroid_part_mm"][1], t["centroid_part_mm"][2]);
      double best = 1e9;
      for (const auto& h : r["hotspots"])
        if (h["threshold_kpa"].get<double>() == 4.3)
          best = std::min(best, (Eigen::Vector3d(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1],
                                                 h["centre_of_pressure_mm"][2]) - c).norm());
      worst = std::max(worst, best);
    }
    return worst;
  }
  /// Pearson correlation of the assessed pressure (chart, sampled at the mesh's contact vertices as the
  /// heatmap is) with the truth per vertex, over vertices seen.
  double vertex_pearson(const std::string& out_name, const fs::path& caps) {
    const nlohmann::json r = report(out_name);
    const Mesh mesh = load_mesh(kWristband / "wristband.obj");
    ContactSelector sel;
    sel.group = "contact";
    const ContactSurface contact = select_contact(mesh, sel);
    const Chart chart = compute_chart(mesh, contact);
    const cv::Mat p = sim::read_npy_2d(work() / out_name / "pressure.npy");
    ChartField f;
    f.grid.width = p.cols, f.grid.height = p.rows, f.grid.texel_mm = r["chart"]["texel_mm"].get<double>();
    f.grid.uv_origin = Vec2(r["chart"]["uv_min_mm"][0].get<double>(), r["chart"]["uv_min_mm"][1].get<double>());
    f.value.assign(p.begin<float>(), p.end<float>());
    const std::vector<float> measured = sample_at_vertices(f, chart);
    const std::vector<float> truth = npy::read_float32(caps / "truth_vertex_pressure.npy").values;
    EXPECT_EQ(truth.size(), measured.size());
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    for (std::size_t v = 0; v < std::min(truth.size(), measured.size()); ++v) {
      const double a = measured[v], b = truth[v];
      if (!std::isfinite(a) || !std::isfinite(b)) continue;
      sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b, ++n;
    }
    EXPECT_GT(n, 100);
    return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
  }
};

/// Renders the part held `gap` mm off the skin and checks the estimate (gaps the method was not developed on: it was on 1.0 and 2.0).
void BaselineGapCli::expect_recovered(double gap) {
  const std::string name = "held" + std::to_string(static_cast<int>(gap * 10));
  const fs::path caps = render(name, "{part: held, gap_mm: " + std::to_string(gap) + "}");
  ASSERT_NEAR(truth_gap(caps), gap, 1e-9);
  const RunResult r = assess(caps, caps, name);
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto b = report(name)["baseline_geometry"];
  std::printf("gap %.2f mm: estimated %.3f ± %.3f mm (texture match %.3f, %.3f mm of skin per mm)\n", gap, b["gap_mm"].get<double>(),
              b["gap_sigma_mm"].get<double>(), b["estimate"]["texture_match"].get<double>(),
              b["estimate"]["shift_mm_per_mm"].get<double>());
  EXPECT_EQ(b["part"], "held");
  EXPECT_EQ(b["gap_source"], "estimated");
  EXPECT_NEAR(b["gap_mm"].get<double>(), gap, 0.1);
  EXPECT_GT(b["gap_sigma_mm"].get<double>(), 0.0);
  EXPECT_LT(b["gap_sigma_mm"].get<double>(), 0.1);
}

TEST_F(BaselineGapCli, RecoversAHalfMillimetreGap) { expect_recovered(0.55); }
TEST_F(BaselineGapCli, RecoversAGapOfOneAndAHalfMillimetres) { expect_recovered(1.45); }
TEST_F(BaselineGapCli, RecoversAThreeMillimetreGap) { expect_recovered(2.95); }

TEST_F(BaselineGapCli, HandlingTheGapKeepsTheHotspotsWhereTheSingleMapDoesNot) {
  const fs::path caps = calibration().parent_path();  // held 2.0 mm
  const RunResult r = assess(caps, caps, "auto", {}, true);
  ASSERT_EQ(r.exit_code, 0) << r;
  // The single map, by default, either refuses the held baseline's parallax (25 px here) as motion or
  // reads it as motion and misplaces the hotspots (what it does depends on how far the registration
  // follows the parallax); allowed to compensate it as motion, it still misplaces them.
  const RunResult by_default = assess(caps, caps, "single_default", {"--baseline-part", "touching"}, true);
  if (by_default.exit_code == 0) {
    // The phase registration (on by default) follows much of the parallax as skin that slid, so the
    // single map's centroids may come out right; its per-vertex agreement does not.
    const double c = worst_centroid_mm(report("single_default"), caps), rho_c = vertex_pearson("single_default", caps);
    std::printf("single map by default: assessed, centroid error %.3f mm, per-vertex Pearson %.4f\n", c, rho_c);
    EXPECT_TRUE(c > 2 * worst_centroid_mm(report("auto"), caps) + 0.1 || rho_c < vertex_pearson("auto", caps) - 0.1)
        << "the single map is not clearly worse";
  } else {
    EXPECT_EQ(by_default.exit_code, 2) << by_default;
    EXPECT_NE(by_default.err.find("moved"), std::string::npos) << by_default;
  }
  const RunResult old = assess(caps, caps, "single", {"--baseline-part", "touching", "--max-motion-px", "40"}, true);
  ASSERT_EQ(old.exit_code, 0) << old;
  const double centroid = worst_centroid_mm(report("auto"), caps), centroid_old = worst_centroid_mm(report("single"), caps);
  const double rho = vertex_pearson("auto", caps), rho_old = vertex_pearson("single", caps);
  std::printf("gap handled: centroid error %.3f mm, per-vertex Pearson %.4f; single map: %.3f mm, %.4f\n", centroid, rho, centroid_old,
              rho_old);
  EXPECT_LE(centroid, 0.15);
  // The same scene rendered and assessed with a touching baseline (no gap at all) reaches 0.949 at this
  // quarter scale and 0.5 mm smoothing: the gap handled leaves the per-vertex agreement where it is.
  EXPECT_GE(rho, 0.95);
  EXPECT_TRUE(rho_old < rho - 0.1 || centroid_old > 2 * centroid + 0.1) << "the single map is not clearly worse";
}

// Each phase is registered to its own first frame, so a move of the camera between the not-worn
// capture's first frame and the worn one's is measured with the gap, which it would otherwise bias
// or make unsure (mild motion was refused: 0.77 ± 0.10 mm for 1 mm). A drift and a tremor
// (strengths and seed not those the method was developed on).
TEST_F(BaselineGapCli, CameraMoveBetweenThePhasesDoesNotBiasTheGap) {
  const fs::path caps = render("moved", "{part: held, gap_mm: 1.3}", false, "", "  motion: {drift_px_per_s: 0.8, tremor_px: 0.2, tremor_hz: 7}\n");
  const auto truth = nlohmann::json::parse(read_text(caps / "truth.json"));
  // The worn capture's first frame follows the 45 not-worn ones (1.5 s at 30 fps).
  const auto& moved = truth["motion"]["shift_px_per_frame"][45];
  const Vec2 expected(-moved[0].get<double>(), -moved[1].get<double>());
  ASSERT_GT(expected.norm(), 0.5);
  const RunResult r = assess(caps, caps, "moved", {}, true);
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto b = report("moved")["baseline_geometry"];
  ASSERT_TRUE(b["phase_shift_px"].is_object()) << b.dump();
  const Vec2 shift(b["phase_shift_px"]["value"][0].get<double>(), b["phase_shift_px"]["value"][1].get<double>());
  const double centroid = worst_centroid_mm(report("moved"), caps);
  std::printf("camera moved (%.3f, %.3f) px between the phases: texture move (%.3f, %.3f) ± (%.3f, %.3f) px; gap %.3f ± %.3f mm; "
              "centroid error %.3f mm, per-vertex Pearson %.4f\n", expected.x(), expected.y(), shift.x(), shift.y(),
              b["phase_shift_px"]["sigma"][0].get<double>(), b["phase_shift_px"]["sigma"][1].get<double>(), b["gap_mm"].get<double>(),
              b["gap_sigma_mm"].get<double>(), centroid, vertex_pearson("moved", caps));
  EXPECT_LT((shift - expected).norm(), 0.25);
  // The worn capture is placed by the contact surface's outline: its first frame moved by `moved` against the
  // pose the map was traced with (the texture between the phases cannot tell that from a slide).
  const auto m = report("moved")["phase_move"];
  ASSERT_TRUE(m["applied"].get<bool>()) << m.dump();
  const Vec2 worn(m["worn_outline_px"][0].get<double>(), m["worn_outline_px"][1].get<double>());
  std::printf("worn outline (%.3f, %.3f) ± (%.3f, %.3f) px against the pose; the camera moved (%.3f, %.3f) px\n", worn.x(), worn.y(),
              m["sigma_px"][0].get<double>(), m["sigma_px"][1].get<double>(), moved[0].get<double>(), moved[1].get<double>());
  // 0.15 px, not the 0.03 px of the unit test (fit/Outline): clearfit simulate draws the outline where the map's
  // pixel centres put it (a straight edge on the pixel grid, up to 0.5 px off the sub-pixel outline the map's
  // seen share gives); the centres of pressure are the bar.
  EXPECT_LT((worn + expected).norm(), 0.15);
  EXPECT_LT(centroid, 0.15);
  EXPECT_EQ(b["gap_source"], "estimated");
  EXPECT_NEAR(b["gap_mm"].get<double>(), 1.3, 0.1);
  EXPECT_LT(b["gap_sigma_mm"].get<double>(), 0.05);
  // Without it the gap search reads the move as parallax.
  const RunResult off = assess(caps, caps, "unmoved", {"--baseline-max-shift-px", "0"}, true);
  if (off.exit_code == 0) {
    const auto bo = report("unmoved")["baseline_geometry"];
    std::printf("without measuring the move: gap %.3f ± %.3f mm\n", bo["gap_mm"].get<double>(), bo["gap_sigma_mm"].get<double>());
    EXPECT_GT(std::abs(bo["gap_mm"].get<double>() - 1.3) + bo["gap_sigma_mm"].get<double>(),
              std::abs(b["gap_mm"].get<double>() - 1.3) + b["gap_sigma_mm"].get<double>());
  } else {
    EXPECT_EQ(off.exit_code, 2) << off;
    EXPECT_NE(off.err.find("baseline.gap_mm"), std::string::npos) << off;
  }
}

// The bundled sample's scene as shipped (the realistic preset: a hand-held phone, glare, the skin slid and
// bulged, the band held 1 mm off the skin when not worn), rendered at a quarter of its resolution with its
// own seed and assessed with its 100-frame window. The skin's texture moved about 1.9 px between the phases,
// more than the gap's own moves: the unshifted textures matched best at 0 mm, where the shift's fit found no
// minimum, and the run was refused (0.00 ± 0.19 mm here; 0.00 ± 1.01 mm with the sample's 0.25 mm smoothing).
// The shift is now sought across the searched range when it cannot be measured at the unshifted best.
TEST_F(BaselineGapCli, TheHandHeldSampleAtAQuarterOfItsResolution) {
  const fs::path caps = quarter_sample();
  const RunResult r = assess(caps, caps, "sample_quarter", {"--window-frames", "100"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto b = report("sample_quarter")["baseline_geometry"];
  ASSERT_TRUE(b["phase_shift_px"].is_object()) << b.dump();
  std::printf("the sample at a quarter of its resolution: gap %.3f ± %.3f mm (truth %.3f), texture move (%.3f, %.3f) px\n",
              b["gap_mm"].get<double>(), b["gap_sigma_mm"].get<double>(), truth_gap(caps), b["phase_shift_px"]["value"][0].get<double>(),
              b["phase_shift_px"]["value"][1].get<double>());
  EXPECT_EQ(b["gap_source"], "estimated");
  EXPECT_NEAR(b["gap_mm"].get<double>(), truth_gap(caps), 0.1);
}

// The gap's σ in each texel's signal σ (GapSearchOptions::sigma_in_signal), on the sample at a quarter of its
// resolution as shipped (seed 7; its gap 0.958 ± 0.037 mm for 1.0). A gap off by about its σ moves where the
// baseline is read by σ times the parallax, largest at the band's oblique ends: there it made a false saturated
// place of 7.2 mm², and 7 false places on 6 of the seeds 8-17 (none with the true gap given). The term is
// checked against that independent run: the signal's change between the estimated and the true gap.
TEST_F(BaselineGapCli, TheGapsSigmaKeepsTheSamplesBandEndsFromMakingPlaces) {
  const fs::path caps = quarter_sample();
  const double truth = truth_gap(caps);
  for (const auto& [name, extra] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"q_default", {}}, {"q_without", {"--no-baseline-gap-sigma"}}, {"q_truth", {"--baseline-gap-mm", std::to_string(truth)}}}) {
    const RunResult r = assess_sample(name, extra);
    ASSERT_EQ(r.exit_code, 0) << name << "\n" << r;
  }
  const auto r = report("q_default"), without = report("q_without"), given = report("q_truth");
  const auto b = r["baseline_geometry"];
  const double gap = b["gap_mm"].get<double>(), sigma = b["gap_sigma_mm"].get<double>();
  const auto term = b["signal_sigma_from_gap"];
  std::printf("quarter sample: gap %.3f ± %.3f mm (truth %.3f); the gap's signal sigma median %.5f, max %.4f, %.2f mm² unseen; "
              "false places %d (without the term %d, the true gap given %d); worst centroid %.3f mm\n", gap, sigma, truth,
              term["median"].get<double>(), term["max"].get<double>(), term["unseen_mm2"].get<double>(), false_places(r, caps),
              false_places(without, caps), false_places(given, caps), worst_centroid_mm(r, caps));
  EXPECT_EQ(false_places(r, caps), 0);
  EXPECT_EQ(false_places(given, caps), 0);
  EXPECT_GE(false_places(without, caps), 1) << "the term is not what keeps the band's ends clear here";
  EXPECT_LT(worst_centroid_mm(r, caps), 0.15);
  EXPECT_LT(term["unseen_mm2"].get<double>(), 0.01 * r["coverage"]["seen_area_mm2"].get<double>());
  // The term against the signal's change when the true gap is given: where it is large the change is of its size
  // (scaled by the gap's error in σ), and where it is under the noise the change is too.
  const cv::Mat y = sim::read_npy_2d(work() / "q_default" / "signal.npy"), y_true = sim::read_npy_2d(work() / "q_truth" / "signal.npy");
  const cv::Mat s = sim::read_npy_2d(work() / "q_default" / "signal_sigma_from_gap.npy");
  ASSERT_EQ(y.size(), y_true.size());
  ASSERT_EQ(y.size(), s.size());
  const double noise = r["signal"]["noise_sigma"].get<double>(), errors = std::abs(gap - truth) / sigma;
  ASSERT_GT(errors, 0.25) << "the estimated gap is too near the truth for its error to show the term";
  std::vector<double> ratio, small_change;
  for (int j = 0; j < y.rows; ++j)
    for (int i = 0; i < y.cols; ++i) {
      const double d = std::abs(y.at<float>(j, i) - y_true.at<float>(j, i)), t = s.at<float>(j, i);
      if (!std::isfinite(d) || !std::isfinite(t)) continue;
      if (t >= 3 * noise) ratio.push_back(d / (t * errors));
      if (t < noise) small_change.push_back(d / noise);
    }
  ASSERT_GT(ratio.size(), 100u);
  ASSERT_GT(small_change.size(), 10000u);
  auto quantile = [](std::vector<double> v, double q) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(q * (v.size() - 1)), v.end());
    return v[static_cast<std::size_t>(q * (v.size() - 1))];
  };
  std::printf("where the term is >= 3 noise sigma (%zu texels): change / (term x %.2f) median %.2f; where it is under the noise: "
              "change p95 %.2f noise sigma\n", ratio.size(), errors, quantile(ratio, 0.5), quantile(small_change, 0.95));
  EXPECT_GT(quantile(ratio, 0.5), 0.3);
  EXPECT_LT(quantile(ratio, 0.5), 3.0);
  EXPECT_LT(quantile(small_change, 0.95), 1.0);
}

TEST_F(BaselineGapCli, AbsentPartIsAssessedThroughStraightRays) {
  const fs::path caps = render("absent", "{part: absent, gap_mm: 1.2}");
  const RunResult r = assess(caps, caps, "absent", {"--baseline-part", "absent"}, true);
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto b = report("absent")["baseline_geometry"];
  std::printf("absent, skin 1.2 mm beyond the contact surface: estimated %.3f ± %.3f mm\n", b["gap_mm"].get<double>(),
              b["gap_sigma_mm"].get<double>());
  EXPECT_EQ(b["part"], "absent");
  EXPECT_NEAR(b["gap_mm"].get<double>(), 1.2, 0.1);
  EXPECT_LT(worst_centroid_mm(report("absent"), caps), 0.3);
}

TEST_F(BaselineGapCli, BadGapsAreRefusedWithExitTwo) {
  const fs::path caps = calibration().parent_path();
  RunResult r = assess(caps, caps, "negative", {"--baseline-gap-mm", "-0.5"});
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("--baseline-gap-mm"), std::string::npos) << r;
  EXPECT_NE(r.err.find("from 0 to 20 mm"), std::string::npos) << r;
  r = assess(caps, caps, "words", {"--baseline-gap-mm", "wide"});
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("auto or a length in mm"), std::string::npos) << r;
  // Another wearer's skin in the not-worn capture: no gap makes the textures agree, and the gap matters here.
  const fs::path other = render("other_skin", "{part: held, gap_mm: 1.0}", false, ", texture_seed: 9");
  r = assess(other, caps, "mismatch");
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("cannot be estimated"), std::string::npos) << r;
  EXPECT_NE(r.err.find("baseline.gap_mm"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(work() / "mismatch")) << "output folder left behind";
  // Without --quiet the error starts a line of its own, not the end of the progress line it interrupts.
  const RunResult loud = run_clearfit({"assess", "mismatch.yaml", "--no-cache", "--no-html"}, work(), root() / "capture", 120);
  EXPECT_EQ(loud.exit_code, 2) << loud;
  EXPECT_NE(loud.err.find("estimating the baseline's gap\nclearfit: error: "), std::string::npos) << loud;
  // Given, the gap is used as it is and reported as given.
  r = assess(caps, caps, "given", {"--baseline-gap-mm", "2"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(report("given")["baseline_geometry"]["gap_source"], "given");
}

TEST_F(BaselineGapCli, SkinWithoutTextureIsRefusedNamingTheCaptureAndTheKey) {
  // No ridges, no mottling: nothing to register the not-worn capture's skin by.
  const fs::path caps = render("flat_skin", "{part: held, gap_mm: 1.0}", false, ", ridge_amplitude: 0, mottling_amplitude: 0");
  const RunResult r = assess(caps, caps, "flat_skin");
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find((caps / "baseline.mkv").string()), std::string::npos) << r;
  EXPECT_NE(r.err.find("cannot be estimated"), std::string::npos) << r;
  EXPECT_NE(r.err.find("give baseline.gap_mm"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(work() / "flat_skin")) << "output folder left behind";
  // Given, the same captures are assessed.
  const RunResult given = assess(caps, caps, "flat_given", {"--baseline-gap-mm", "1"});
  EXPECT_EQ(given.exit_code, 0) << given;
}

}  // namespace
}  // namespace clearfit::cli_test
