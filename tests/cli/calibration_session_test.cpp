// End-to-end calibration sessions: `clearfit simulate-session` → `clearfit
// presses` → `clearfit calibrate-pressure` on sessions whose parameters the
// method was not tuned on (two skin tones, noise, clock offset and drift,
// overshoot, with and without a slab), against the simulated truth; bad
// inputs exit 2 naming the file and line, nothing written.
#include "cli_support.hpp"
#include "targets.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

/// The indenter as `presses` is told of it: a flat punch of radius_mm, or a sphere's cap of radius_mm.
struct Indenter {
  std::string radius_mm = "2.5", sphere_radius_mm;
};

class CalibrationSession : public CliTest {
 protected:
  nlohmann::json simulate(const std::vector<std::string>& extra) {
    std::vector<std::string> args{"simulate-session", "--out", "s", "--quiet"};
    args.insert(args.end(), extra.begin(), extra.end());
    const RunResult r = run(args, 120);
    EXPECT_EQ(r.exit_code, 0) << r;
    return nlohmann::json::parse(read_text(work() / "s" / "truth.json"));
  }
  RunResult run(const std::vector<std::string>& args, double timeout = 60) {
    return run_clearfit(args, work(), root() / "capture", timeout);
  }
  RunResult presses(const std::string& log, const std::string& slab, const Indenter& indenter = {}) {
    std::vector<std::string> args{"presses", "--video", "s/session.mkv", "--force-log", log, "--camera", "s/camera.cameramodel",
                                  "--indenter-radius-mm", indenter.radius_mm, "--slab-mm", slab, "--out", "presses.csv", "--report", "report"};
    if (!indenter.sphere_radius_mm.empty()) args.insert(args.end(), {"--sphere-radius-mm", indenter.sphere_radius_mm});
    return run(args);
  }

  /// Simulate → presses → calibrate-pressure, then the fitted person against the truth.
  void check_chain(const std::vector<std::string>& sim, const std::string& slab, const Indenter& indenter = {}) {
    const auto truth = simulate(sim);
    const RunResult p = presses("s/force.csv", slab, indenter);
    ASSERT_EQ(p.exit_code, 0) << p;
    const auto session = nlohmann::json::parse(read_text(work() / "report" / "session.json"));
    EXPECT_TRUE(fs::exists(work() / "report" / "session.png"));
    const auto& clock = session.at("clock");
    const double offset = clock.at("offset_s"), t_offset = truth.at("clock").at("offset_s");
    const double drift = clock.at("drift_ppm"), t_drift = truth.at("clock").at("drift_ppm");
    std::printf("clock offset %.4f +- %.4f s (truth %.4f), drift %.1f +- %.1f ppm (truth %.1f), trace fit %s\n", offset,
                clock.at("offset_sigma_s").get<double>(), t_offset, drift, clock.at("drift_sigma_ppm").get<double>(), t_drift,
                clock.value("trace_fit", false) ? "yes" : "no");
    EXPECT_NEAR(offset, t_offset, 0.1);
    EXPECT_NEAR(drift, t_drift, 150.0);
    EXPECT_EQ(session.at("presses").size(), truth.at("presses").size());
    const auto& c_px = session.at("indenter").at("centre_px");
    const auto& t_px = truth.at("indenter").at("centre_px");
    EXPECT_LE(std::hypot(c_px[0].get<double>() - t_px[0].get<double>(), c_px[1].get<double>() - t_px[1].get<double>()), 1.5);
    const RunResult c = run({"calibrate-pressure", "--presses", "presses.csv", "--person", "P", "--out", "cal.json",
                             "--report", "cal-report.json", "--plot", "fit.png"});
    ASSERT_EQ(c.exit_code, 0) << c;
    const bool sphere = !indenter.sphere_radius_mm.empty();
    EXPECT_NE(c.out.find(sphere ? "pressure field: hertz" : "pressure field: punch"), std::string::npos) << c;
    const auto cal = nlohmann::json::parse(read_text(work() / "cal.json")).at("parameters");
    const auto& person = truth.at("person");
    std::printf("p50 %.4f kPa (truth %.4f), width %.4f kPa (truth %.4f)\n", cal.at("p50_kpa").get<double>(),
                person.at("p50_kpa").get<double>(), cal.at("width_kpa").get<double>(), person.at("width_kpa").get<double>());
    if (sphere) {  // the skin's E*, fitted with the calibration
      const auto field = nlohmann::json::parse(read_text(work() / "cal-report.json")).at("pressure_field");
      const double e_star = field.at("e_star_kpa"), t_e_star = truth.at("indenter").at("e_star_kpa");
      std::printf("E* %.2f +- %.2f kPa (truth %.2f)\n", e_star, field.at("e_star_se_kpa").get<double>(), t_e_star);
      EXPECT_TRUE(field.at("e_star_fitted").get<bool>());
      EXPECT_NEAR(e_star, t_e_star, 0.1 * t_e_star);
    }
    EXPECT_NEAR(cal.at("p50_kpa").get<double>(), person.at("p50_kpa").get<double>(), 0.05 * person.at("p50_kpa").get<double>());
    EXPECT_NEAR(cal.at("width_kpa").get<double>(), person.at("width_kpa").get<double>(), 0.05 * person.at("width_kpa").get<double>());
    // Pressure predicted from the true signal over 5–60 kPa (where the fit does not call it saturated).
    int n = 0;
    const double rmse = predicted_pressure_rmse_kpa(person, cal, n);
    ASSERT_GT(n, 10);
    EXPECT_LE(rmse, 0.05 * 55) << "RMSE over " << n << " pressures";
  }
};

// The events' fit alone put this session's offset 0.117 s from the truth (sigma 0.064 s); the whole-trace fit
// puts it within 0.04 s.
TEST_F(CalibrationSession, DarkSkinThroughSlabWithOffsetDriftOvershoot) {
  check_chain({"--size", "128", "96", "--focal-px", "600", "--fps", "10", "--tone", "dark", "--p50-kpa", "11", "--width-kpa", "2.4",
               "--beta", "0.75", "--seed", "21", "--offset-s", "7.3", "--drift-ppm", "-380", "--overshoot", "0.12",
               "--noise-levels", "1.5", "--presses", "13", "--slab-mm", "4", "--slab-ior", "1.53"},
              "4");
}

// A clear sphere (Hertz: the contact radius grows with the force as F^(1/3)), the skin's E* unknown to the
// fit. Developed on a medium-skin session (p50 8, w 2, R 8 mm, E* 150 kPa, seed 1); these parameters were
// not looked at before the test was written.
TEST_F(CalibrationSession, SphereLightSkinThroughSlabWithUnknownModulus) {
  check_chain({"--size", "160", "128", "--focal-px", "600", "--fps", "12", "--tone", "light", "--p50-kpa", "7", "--width-kpa", "1.8",
               "--beta", "0.9", "--seed", "9", "--offset-s", "4.4", "--drift-ppm", "610", "--presses", "12", "--slab-mm", "2",
               "--slab-ior", "1.53", "--indenter-radius-mm", "3", "--sphere-radius-mm", "12", "--e-star-kpa", "250",
               "--min-kpa", "10", "--max-kpa", "22"},
              "2", {"3", "12"});
}

TEST_F(CalibrationSession, LightSkinSeenDirectly) {
  check_chain({"--size", "128", "96", "--focal-px", "600", "--fps", "12", "--tone", "light", "--p50-kpa", "6.5", "--width-kpa", "1.6",
               "--beta", "0.9", "--seed", "5", "--offset-s", "-2.1", "--drift-ppm", "520", "--presses", "15", "--slab-mm", "0",
               "--max-kpa", "30"},
              "0");
}

TEST_F(CalibrationSession, BadInputsExit2NamingFileAndLineWritingNothing) {
  simulate({"--size", "96", "72", "--focal-px", "360", "--fps", "8", "--presses", "12", "--seed", "3"});
  const std::string log = read_text(work() / "s" / "force.csv");
  // Duplicated time.
  const auto second_line = log.find('\n', log.find('\n') + 1);
  write_text(work() / "dup.csv", log.substr(0, second_line + 1) + log.substr(log.find('\n') + 1));
  RunResult r = presses("dup.csv", "3");
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("dup.csv"), std::string::npos) << r;
  EXPECT_NE(r.err.find("line"), std::string::npos) << r;
  // A press after the recording's end: the recording is shorter than the log.
  std::string longer = log;
  double t_end = 0;
  {
    const auto last = log.rfind('\n', log.size() - 2);
    t_end = std::stod(log.substr(last + 1));
  }
  for (int i = 1; i <= 1500; ++i) {
    const double t = t_end + i * 0.02, f = (i > 300 && i < 700) ? 0.5 : 0.0;
    longer += std::to_string(t) + "," + std::to_string(0.05 + f) + "\n";
  }
  write_text(work() / "long.csv", longer);
  r = presses("long.csv", "3");
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("long.csv: line"), std::string::npos) << r;
  EXPECT_NE(r.err.find("shorter than the force log"), std::string::npos) << r;
  // Too few presses: the log cut after its third press.
  std::string cut;
  {
    int presses_seen = 0;
    bool above = false;
    std::size_t pos = log.find('\n') + 1;
    cut = log.substr(0, pos);
    while (pos < log.size()) {
      const auto end = log.find('\n', pos);
      const std::string line = log.substr(pos, end - pos);
      const double f = std::stod(line.substr(line.find(',') + 1));
      if (f > 0.1 && !above) ++presses_seen;
      above = f > 0.1;
      if (presses_seen > 3) break;
      cut += line + "\n";
      pos = end + 1;
    }
  }
  write_text(work() / "few.csv", cut);
  r = presses("few.csv", "3");
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("few.csv"), std::string::npos) << r;
  EXPECT_FALSE(fs::exists(work() / "presses.csv"));
  EXPECT_FALSE(fs::exists(work() / "report"));
}

}  // namespace
}  // namespace clearfit::cli_test
