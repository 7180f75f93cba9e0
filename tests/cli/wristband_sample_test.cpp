// The bundled wristband sample (samples/wristband) run as the README's first command runs it —
// simulate, calibrate-pressure, assess, each with the scene as shipped and no options — at half the
// camera's resolution, and held to its own targets against the simulator's truth. The scene uses
// the realistic preset (a hand-held phone: motion, glare, exposure and white-balance steps,
// flicker, the worn skin slid and bulged, the band held 1 mm off the skin when not worn; the scene
// films losslessly, replacing the preset's H.264), so
// this is where every real-capture correction is checked together with its defaults:
// every true hotspot found, its centre within 0.15 mm and its peak within 10 %; no false place;
// per-vertex Pearson with the truth at least 0.97; the held baseline's gap within 0.1 mm; the
// glare masked; the skin's displacement field written.
#include "cli_support.hpp"
#include "targets.hpp"

#include <clearfit/fit/simulate.hpp>

#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

const fs::path kSample = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

nlohmann::json read_json(const fs::path& p) { return nlohmann::json::parse(read_text(p)); }

class WristbandSample : public CliTest {};

TEST_F(WristbandSample, ReadmeCommandMeetsItsTargetsWithTheRealisticPreset) {
  for (const char* f : {"scene.yaml", "wristband.obj", "camera.cameramodel"}) {
    fs::create_directories(work() / "wristband");
    fs::copy_file(kSample / f, work() / "wristband" / f);
  }
  const fs::path s = work() / "wristband", caps = s / "captures";
  // What scripts/bootstrap.sh sample runs, at half resolution (the captures' camera is the sample's, scaled).
  RunResult r = run_clearfit({"simulate", "scene.yaml", "--scale", "0.5", "--quiet"}, s, root() / "capture", 400);
  ASSERT_EQ(r.exit_code, 0) << r;
  const auto truth = read_json(caps / "truth.json");
  ASSERT_EQ(truth.at("preset").at("name"), "realistic");
  ASSERT_TRUE(fs::exists(caps / "worn.mkv"));
  r = run_clearfit({"calibrate-pressure", "--presses", "captures/presses.csv", "--person", "wearer-1", "--camera", "captures/camera.cameramodel",
                    "--out", "captures/calibration.json"},
                   s, root() / "capture", 120);
  ASSERT_EQ(r.exit_code, 0) << r;
  r = run_clearfit({"assess", "scene.yaml", "--camera", "captures/camera.cameramodel", "--quiet", "--no-html"}, s, root() / "capture", 400);
  ASSERT_EQ(r.exit_code, 0) << r;
  std::printf("assess: %.1f s\n", r.seconds);
  const fs::path out = s / "out" / "assessment";
  const auto report = read_json(out / "report.json");

  // Every true hotspot found: its centre within 0.15 mm, its peak within 10 %.
  for (const auto& th : truth.at("hotspots")) {
    const NearestHotspot h = nearest_hotspot(report, th);
    const double true_peak = th.at("peak_kpa");
    std::printf("hotspot of %.1f kPa: centre of pressure %.3f mm from the truth's, peak %.2f kPa (%+.1f %%)\n", true_peak, h.distance_mm,
                h.peak_kpa, 100 * (h.peak_kpa / true_peak - 1));
    EXPECT_LE(h.distance_mm, 0.15);
    EXPECT_NEAR(h.peak_kpa, true_peak, 0.1 * true_peak);
  }
  // No false place: every place at 4.3 kPa lies within 1 mm of a true hotspot.
  for (const auto& h : report.at("hotspots")) {
    if (h.at("threshold_kpa").get<double>() != 4.3) continue;
    const auto& mc = h.at("centre_of_pressure_mm");
    const Eigen::Vector3d m(mc[0], mc[1], mc[2]);
    double best = INFINITY;
    for (const auto& th : truth.at("hotspots")) {
      const auto& tc = th.at("centroid_part_mm");
      best = std::min(best, (m - Eigen::Vector3d(tc[0], tc[1], tc[2])).norm());
    }
    EXPECT_LE(best, 1.0) << "a false place: " << h.dump();
  }
  int vertices = 0;
  const double rho = sim::vertex_pressure_pearson(out / "vertices.csv", caps / "truth_vertex_pressure.npy", &vertices);
  std::printf("per-vertex Pearson %.4f over %d vertices\n", rho, vertices);
  EXPECT_GT(vertices, 500);
  EXPECT_GE(rho, 0.97);

  // The corrections that ran, each with its figure: the gap, the glare, the skin's displacement.
  const auto& b = report.at("baseline_geometry");
  std::printf("gap %.3f +- %.3f mm (truth %.3f)\n", b.at("gap_mm").get<double>(), b.at("gap_sigma_mm").get<double>(),
              truth.at("baseline").at("gap_mm").get<double>());
  EXPECT_NEAR(b.at("gap_mm").get<double>(), truth.at("baseline").at("gap_mm").get<double>(), 0.1);
  EXPECT_GT(report.at("glare").at("fraction_of_seen_pixels").get<double>(), 0.0);
  EXPECT_TRUE(fs::exists(out / "displacement.npy"));
}

}  // namespace
}  // namespace clearfit::cli_test
