// The bundled calibration session (samples/calibration-session) run exactly as README.md prints
// it — simulate-session, presses, calibrate-pressure, then assess on the wristband with that
// calibration — and held to issue 13's targets against the simulator's truth: p50 and width
// within 5 %, the predicted pressure's RMSE at most 5 % of the 5–60 kPa range, the clock's
// offset and drift within 3 σ of the truth, the wristband's hotspot peaks within 10 %.
#include "cli_support.hpp"
#include "targets.hpp"

#include <cstdlib>
#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

const fs::path kSamples = fs::path(CLEARFIT_SAMPLES_DIR);
const char* const kHeading = "### The bundled session: samples/calibration-session";

/// The first ```sh block after `heading` in README.md, as one script (its lines as printed).
std::string readme_block(const std::string& heading) {
  const std::string readme = read_text(kSamples.parent_path() / "README.md");
  const auto at = readme.find("\n" + heading + "\n");
  if (at == std::string::npos) throw std::runtime_error("README.md has no heading '" + heading + "'");
  const auto open = readme.find("```sh\n", at);
  const auto close = readme.find("\n```", open + 6);
  if (open == std::string::npos || close == std::string::npos) throw std::runtime_error("no ```sh block after '" + heading + "'");
  return readme.substr(open + 6, close + 1 - (open + 6));
}

nlohmann::json read_json(const fs::path& p) { return nlohmann::json::parse(read_text(p)); }

class CalibrationSample : public CliTest {};

TEST_F(CalibrationSample, ReadmeChainMeetsTheIssueTargets) {
  // The sample's files (and the wristband's) in a scratch copy of the repository's samples/ folder;
  // `clearfit` found on PATH, as a user who installed it types it.
  for (const char* f : {"wristband/scene.yaml", "wristband/wristband.obj", "wristband/camera.cameramodel", "calibration-session/session.toml"}) {
    fs::create_directories((work() / "samples" / f).parent_path());
    fs::copy_file(kSamples / f, work() / "samples" / f);
  }
  const std::string path = clearfit_exe().parent_path().string() + ":" + (std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin");
  ASSERT_EQ(setenv("PATH", path.c_str(), 1), 0);
  const std::string script = readme_block(kHeading);
  ASSERT_NE(script.find(" presses --video"), std::string::npos) << script;
  const RunResult r = run_clearfit({"-e", "-o", "pipefail", "-c", script}, work(), root() / "capture", 400, "/bin/bash");
  std::printf("README chain: %.1f s\n%s", r.seconds, r.out.c_str());
  ASSERT_EQ(r.exit_code, 0) << r;

  const fs::path out = work() / "samples" / "calibration-session" / "out";
  const auto truth = read_json(out / "session" / "truth.json");
  // The clock: offset and drift within 3 σ of the truth (σ as `presses` reports it).
  const auto clock = read_json(out / "session" / "report" / "session.json").at("clock");
  const double offset = clock.at("offset_s"), offset_sigma = clock.at("offset_sigma_s"), t_offset = truth.at("clock").at("offset_s");
  const double drift = clock.at("drift_ppm"), drift_sigma = clock.at("drift_sigma_ppm"), t_drift = truth.at("clock").at("drift_ppm");
  std::printf("clock offset %.4f +- %.4f s (truth %.4f: %.2f sigma), drift %.1f +- %.1f ppm (truth %.1f: %.2f sigma)\n", offset, offset_sigma,
              t_offset, std::abs(offset - t_offset) / offset_sigma, drift, drift_sigma, t_drift, std::abs(drift - t_drift) / drift_sigma);
  EXPECT_GT(offset_sigma, 0);
  EXPECT_GT(drift_sigma, 0);
  EXPECT_LE(std::abs(offset - t_offset), 3 * offset_sigma);
  EXPECT_LE(std::abs(drift - t_drift), 3 * drift_sigma);

  // The person: p50 and width within 5 %, the predicted pressure's RMSE ≤ 5 % of 5–60 kPa.
  const auto cal = read_json(out / "session" / "calibration.json").at("parameters");
  const auto& person = truth.at("person");
  const double p50 = cal.at("p50_kpa"), t_p50 = person.at("p50_kpa"), w = cal.at("width_kpa"), t_w = person.at("width_kpa");
  int n = 0;
  const double rmse = predicted_pressure_rmse_kpa(person, cal, n);
  std::printf("p50 %.3f kPa (truth %.3f: %+.2f %%), width %.3f kPa (truth %.3f: %+.2f %%), RMSE %.3f kPa over %d pressures (%.2f %% of 55 kPa)\n",
              p50, t_p50, 100 * (p50 / t_p50 - 1), w, t_w, 100 * (w / t_w - 1), rmse, n, 100 * rmse / 55);
  EXPECT_NEAR(p50, t_p50, 0.05 * t_p50);
  EXPECT_NEAR(w, t_w, 0.05 * t_w);
  ASSERT_GT(n, 10);
  EXPECT_LE(rmse, 0.05 * 55);

  // The session's person is the wristband's wearer, so the calibration carries over.
  const auto wristband = read_json(out / "wristband" / "truth.json");
  for (const char* k : {"y_max", "p50_kpa", "width_kpa"})
    EXPECT_DOUBLE_EQ(wristband.at("calibration").at(k).get<double>(), person.at(k).get<double>()) << k;
  // The wristband assessed with it: each true hotspot found, its peak within 10 %.
  const auto report = read_json(out / "assessment" / "report.json");
  for (const auto& th : wristband.at("hotspots")) {
    const NearestHotspot h = nearest_hotspot(report, th);
    const double true_peak = th.at("peak_kpa");
    std::printf("hotspot peak %.2f kPa (truth %.2f: %+.1f %%), centre of pressure %.3f mm from the truth's\n", h.peak_kpa, true_peak,
                100 * (h.peak_kpa / true_peak - 1), h.distance_mm);
    EXPECT_LT(h.distance_mm, 0.3);
    EXPECT_NEAR(h.peak_kpa, true_peak, 0.1 * true_peak);
  }
}

}  // namespace
}  // namespace clearfit::cli_test
