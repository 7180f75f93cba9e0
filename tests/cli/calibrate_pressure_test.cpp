// End-to-end tests of `clearfit calibrate-pressure`: a small presses CSV
// written here (logistic truth + deterministic noise) → calibration file,
// report and plot; bad CSVs → exit 2 naming the file and line, nothing written.
#include "cli_support.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

namespace clearfit::cli_test {
namespace {

constexpr double kYMax = 0.05, kP50 = 8.0, kW = 2.0;  // the truth of the written presses
double truth(double p) {
  auto sig = [](double z) { return 1 / (1 + std::exp(-z)); };
  return kYMax * (sig((p - kP50) / kW) - sig(-kP50 / kW)) / (1 - sig(-kP50 / kW));
}

// 10 levels × 3 repetitions with a 3 mm indenter. Rows alternate between a
// given mean pressure and force-only rows (mean_pressure_kpa empty).
std::string presses_csv(unsigned seed = 42) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0, 1);
  std::string csv = "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal\n";
  int trial = 0;
  const double area_mm2 = M_PI * 1.5 * 1.5;
  for (double level : {0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 16.0, 22.0, 30.0})
    for (int r = 0; r < 3; ++r) {
      const double force = level * area_mm2 / 1000 * (1 + 0.01 * n01(rng));
      const double p = 1000 * force / area_mm2;
      const double y = truth(p) + 0.0015 * n01(rng);
      char line[160];
      if (++trial % 2) std::snprintf(line, sizeof line, "%d,3,%.9g,%.9g,%.9g\n", trial, force, p, y);
      else std::snprintf(line, sizeof line, "%d,3,%.9g,,%.9g\n", trial, force, y);
      csv += line;
    }
  return csv;
}

class CalibratePressure : public CliTest {};

TEST_F(CalibratePressure, WritesCalibrationReportAndPlot) {
  write_text(work() / "presses.csv", presses_csv());
  const fs::path camera = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband" / "camera.cameramodel";
  const RunResult r = run({"calibrate-pressure", "--presses", "presses.csv", "--person", "P07", "--camera", camera.string(),
                           "--out", "cal.json", "--report", "report.json", "--plot", "fit.png"});
  ASSERT_EQ(r.exit_code, 0) << r;
  for (const char* s : {"p50_kpa", "width_kpa", "RMSE", "0.439", "logistic", "linear", "wrote cal.json"})
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r;
  EXPECT_EQ(r.out.find("nan"), std::string::npos) << r;
  const auto cal = nlohmann::json::parse(read_text(work() / "cal.json"));
  EXPECT_EQ(cal.at("schema"), "clearfit.pressure-calibration/1");
  EXPECT_EQ(cal.at("person"), "P07");
  EXPECT_EQ(cal.at("model"), "logistic");
  EXPECT_EQ(cal.at("camera_intrinsics_hash").get<std::string>().size(), 16u);
  const auto& params = cal.at("parameters");
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  EXPECT_EQ(report.at("schema"), "clearfit.pressure-calibration-report/1");
  const auto& se = report.at("logistic").at("standard_errors");
  EXPECT_NEAR(params.at("p50_kpa").get<double>(), kP50, 3 * se.at("p50_kpa").get<double>());
  EXPECT_NEAR(params.at("width_kpa").get<double>(), kW, 3 * se.at("width_kpa").get<double>());
  EXPECT_NEAR(params.at("y_max").get<double>(), kYMax, 3 * se.at("y_max").get<double>());
  EXPECT_GT(report.at("logistic").at("r2").get<double>(), report.at("linear").at("r2").get<double>());
  EXPECT_EQ(report.at("residuals").size(), 30u);
  EXPECT_EQ(report.at("linear").at("study_mean_r2"), 0.439);
  // Force-only rows got their pressure from F / (pi r^2): row 2 of the file.
  const auto& row2 = report.at("residuals").at(1);
  EXPECT_EQ(row2.at("trial"), "2");
  EXPECT_NEAR(row2.at("pressure_kpa").get<double>(), 0.0, 0.1);
  EXPECT_LT(report.at("rmse_kpa").get<double>(), 1.5);
  const std::string png = read_text(work() / "fit.png");
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

TEST_F(CalibratePressure, LinearModelAndWarnings) {
  // Only 4 levels, none above 8 kPa: too few levels and no saturation.
  std::string csv = "trial,mean_pressure_kpa,signal\n";
  int t = 0;
  for (double p : {0.0, 3.0, 6.0, 8.0})
    for (double e : {-0.001, 0.0, 0.001}) csv += std::to_string(++t) + "," + std::to_string(p) + "," + std::to_string(truth(p) + e) + "\n";
  write_text(work() / "few.csv", csv);
  const RunResult r = run({"calibrate-pressure", "--presses", "few.csv", "--person", "P1", "--out", "lin.json", "--model", "linear"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.err.find("too few pressure levels"), std::string::npos) << r;
  EXPECT_NE(r.err.find("saturation not reached"), std::string::npos) << r;
  const auto cal = nlohmann::json::parse(read_text(work() / "lin.json"));
  EXPECT_EQ(cal.at("model"), "linear");
  EXPECT_TRUE(cal.at("parameters").contains("slope_per_kpa"));
  EXPECT_TRUE(cal.at("camera_intrinsics_hash").is_null());
}

TEST_F(CalibratePressure, BadCsvIsRefusedWithFileAndLine) {
  const std::string good = presses_csv();
  // Missing column: the header names neither a pressure nor a force.
  write_text(work() / "nocol.csv", "trial,indenter_diameter_mm,signal\n1,3,0.01\n");
  expect_input_error({"calibrate-pressure", "--presses", "nocol.csv", "--person", "P1", "--out", "cal.json"},
                     {"nocol.csv", "line 1", "mean_pressure_kpa"});
  // Text in a number on line 5.
  std::string text = good;
  std::size_t pos = 0;
  for (int k = 0; k < 4; ++k) pos = text.find('\n', pos) + 1;
  text.replace(pos, text.find('\n', pos) - pos, "4,3,abc,,0.01");
  write_text(work() / "text.csv", text);
  expect_input_error({"calibrate-pressure", "--presses", "text.csv", "--person", "P1", "--out", "cal.json", "--report", "r.json",
                      "--plot", "p.png"},
                     {"text.csv", "line 5", "force_n", "'abc'"});
  // Negative force on line 3.
  write_text(work() / "neg.csv", "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal\n1,3,0,0,0\n2,3,-0.2,,0.01\n");
  expect_input_error({"calibrate-pressure", "--presses", "neg.csv", "--person", "P1", "--out", "cal.json"},
                     {"neg.csv", "line 3", "negative"});
  // Force, diameter and mean pressure that disagree.
  write_text(work() / "bad.csv", "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal\n1,3,0.1,30,0.01\n");
  expect_input_error({"calibrate-pressure", "--presses", "bad.csv", "--person", "P1", "--out", "cal.json"},
                     {"bad.csv", "line 2", "disagrees"});
  // A signal that falls with pressure.
  std::string falling = "trial,mean_pressure_kpa,signal\n";
  for (int k = 0; k < 8; ++k) falling += std::to_string(k) + "," + std::to_string(4 * k) + "," + std::to_string(-0.005 * k) + "\n";
  write_text(work() / "falling.csv", falling);
  expect_input_error({"calibrate-pressure", "--presses", "falling.csv", "--person", "P1", "--out", "cal.json"},
                     {"falling.csv", "does not rise"});
  // Missing file, output over the input, a missing output folder, a bad camera.
  expect_input_error({"calibrate-pressure", "--presses", "none.csv", "--person", "P1", "--out", "cal.json"}, {"none.csv"});
  write_text(work() / "good.csv", good);
  expect_input_error({"calibrate-pressure", "--presses", "good.csv", "--person", "P1", "--out", "good.csv"}, {"overwrite"});
  expect_input_error({"calibrate-pressure", "--presses", "good.csv", "--person", "P1", "--out", "nodir/cal.json"}, {"nodir"});
  write_text(work() / "cam.cameramodel", "not a camera\n");
  expect_input_error({"calibrate-pressure", "--presses", "good.csv", "--person", "P1", "--camera", "cam.cameramodel", "--out", "cal.json"},
                     {"cam.cameramodel"});
}

}  // namespace
}  // namespace clearfit::cli_test
