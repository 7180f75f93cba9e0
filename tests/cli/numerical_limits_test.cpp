// Numerical limits from the command line (issue 16, section 5): captures that
// are black or saturated, frames and cameras of one pixel, presses at zero
// force or without noise. Each run exits 2 naming the file and the real
// cause, or exits 0 with outputs free of NaN (the printed text, report.json,
// the calibration file); it never prints "nan" or crashes.
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <clearfit/fit/pressure_model.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cctype>
#include <cmath>

namespace clearfit::cli_test {
namespace {

using nlohmann::json;

// True when `text` holds "nan" or "inf" as a word (any case): a number that was printed without a check.
bool prints_non_finite(const std::string& text) {
  std::string low(text.size(), ' ');
  for (std::size_t i = 0; i < text.size(); ++i) low[i] = static_cast<char>(std::tolower(static_cast<unsigned char>(text[i])));
  for (const char* word : {"nan", "inf"})
    for (std::size_t at = low.find(word); at != std::string::npos; at = low.find(word, at + 1)) {
      const bool start = at == 0 || !std::isalpha(static_cast<unsigned char>(low[at - 1]));
      const std::size_t end = at + 3;
      const bool stop = end == low.size() || !std::isalpha(static_cast<unsigned char>(low[end])) ||
                        low.compare(at, 8, "infinity") == 0;
      if (start && stop) return true;
    }
  return false;
}

// Every number in a JSON document is finite (nlohmann writes NaN and Inf as null: none may be a null
// where a number was meant, so nulls are reported with their path for the caller to judge).
void collect_nulls(const json& j, const std::string& path, std::vector<std::string>& nulls) {
  if (j.is_null()) nulls.push_back(path);
  if (j.is_number_float()) EXPECT_TRUE(std::isfinite(j.get<double>())) << path;
  if (j.is_object())
    for (const auto& [k, v] : j.items()) collect_nulls(v, path + "." + k, nulls);
  if (j.is_array())
    for (std::size_t i = 0; i < j.size(); ++i) collect_nulls(j[i], path + "[" + std::to_string(i) + "]", nulls);
}

class NumericalLimitsCli : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_slab_part(work());
  }
  // A folder of `n` frames of one colour (BGR), w x h.
  void frames(const std::string& dir, int n, int w, int h, cv::Scalar bgr) {
    fs::create_directories(work() / dir);
    const cv::Mat m(h, w, CV_8UC3, bgr);
    for (int i = 0; i < n; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%05d.png", i);
      ASSERT_TRUE(cv::imwrite((work() / dir / name).string(), m));
    }
  }
  // assess on the slab refuses the captures: exit 2, the error names the capture folder `at_fault` and
  // says each of `says`, and no output folder is left.
  void assess_refuses(const std::string& baseline, const std::string& worn, const std::string& at_fault,
                      const std::vector<std::string>& says) {
    write_scene(baseline, worn);
    const RunResult r = run({"assess", "s.yaml", "--no-html", "--no-cache"});
    ASSERT_EQ(r.exit_code, 2) << r;
    EXPECT_NE(r.err.find("clearfit: error: " + at_fault + ": "), std::string::npos) << "the error should name " << at_fault << "\n" << r;
    for (const auto& s : says) EXPECT_NE(r.err.find(s), std::string::npos) << "stderr should say '" << s << "'\n" << r;
    EXPECT_FALSE(prints_non_finite(r.err)) << r;
    EXPECT_FALSE(fs::exists(work() / "out")) << r;
  }
  void write_scene(const std::string& baseline, const std::string& worn) {
    write_text(work() / "s.yaml", "mesh: slab.obj\ncamera: cam.cameramodel\ncontact: {group: contact}\nior: 1.49\n"
                                  "captures: {baseline: " + baseline + ", worn: " + worn + ", window_frames: 3}\n"
                                  "outputs: {folder: out, texel_mm: 0.2}\n");
  }
  // assess on the slab with the given capture folders: exit 2 naming `names`, or 0 with finite outputs.
  void assess_is_clean(const std::string& baseline, const std::string& worn, const std::vector<std::string>& names) {
    write_scene(baseline, worn);
    const RunResult r = run({"assess", "s.yaml", "--no-html", "--no-cache"});
    std::cout << baseline << " / " << worn << ": exit " << r.exit_code << "\n" << r.err.substr(0, 400) << "\n";
    EXPECT_FALSE(prints_non_finite(r.out)) << r;
    EXPECT_FALSE(prints_non_finite(r.err)) << r;
    if (r.exit_code == 2) {
      for (const auto& s : names) EXPECT_NE(r.err.find(s), std::string::npos) << "stderr should name '" << s << "'\n" << r;
      EXPECT_FALSE(fs::exists(work() / "out")) << r;
      return;
    }
    ASSERT_EQ(r.exit_code, 0) << r;
    const json report = json::parse(read_text(work() / "out" / "report.json"));
    std::vector<std::string> nulls;
    collect_nulls(report, "report", nulls);
    for (const auto& p : nulls) std::cout << "  null at " << p << "\n";
    EXPECT_EQ(report.at("hotspots").size(), 0u) << "uniform frames have no hotspot\n" << r;
  }
};

TEST_F(NumericalLimitsCli, BlackAndSaturatedCaptures) {
  frames("black", 6, 160, 120, cv::Scalar(0, 0, 0));
  frames("white", 6, 160, 120, cv::Scalar(255, 255, 255));
  frames("grey", 6, 160, 120, cv::Scalar(120, 140, 170));
  // Exposure is checked before anything is estimated from the captures (the baseline's gap, the
  // registration, the glare): the capture at fault is named, with its defect and what to do.
  const std::string dark = "capture is too dark: mean green 0.0 of 255", raise = "raise the exposure or the light";
  const std::string bright = "capture is overexposed: 100.0 % of the pixels that see the skin are saturated";
  const std::string lower = "lower the exposure or the light";
  assess_refuses("black", "black", "black", {"the baseline " + dark, raise});
  assess_refuses("white", "white", "white", {"the baseline " + bright, lower});
  assess_refuses("grey", "black", "black", {"the worn " + dark, raise});
  assess_refuses("black", "grey", "black", {"the baseline " + dark, raise});
  assess_refuses("grey", "white", "white", {"the worn " + bright, lower});
  assess_refuses("white", "grey", "white", {"the baseline " + bright, lower});
}

TEST_F(NumericalLimitsCli, SinglePixelFramesAndCamera) {
  // Frames of one pixel for a 160 x 120 camera: refused, naming the frame and both sizes.
  frames("one", 6, 1, 1, cv::Scalar(120, 140, 170));
  frames("grey", 6, 160, 120, cv::Scalar(120, 140, 170));
  assess_is_clean("one", "grey", {"one", "1x1 does not match the camera's imager 160x120"});
  // A camera of one pixel that sees the slab: the map and the assessment are one pixel wide.
  CameraModel cam = read_cameramodel(work() / "cam.cameramodel");
  cam.width = cam.height = 1;
  cam.intrinsics[2] = cam.intrinsics[3] = 0;
  write_cameramodel(cam, work() / "cam.cameramodel");
  const RunResult m = run({"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--contact-group", "contact",
                           "--out", "m.npy", "--stats", "s.json"});
  ASSERT_EQ(m.exit_code, 0) << m;
  EXPECT_FALSE(prints_non_finite(m.out)) << m;
  const json stats = json::parse(read_text(work() / "s.json"));
  EXPECT_EQ(stats.at("by_status").at("valid"), 1) << stats.dump(1);
  fs::remove_all(work() / "one");
  frames("one", 6, 1, 1, cv::Scalar(120, 140, 170));
  frames("one_white", 6, 1, 1, cv::Scalar(255, 255, 255));
  assess_is_clean("one", "one", {"one", "1x1 is too small to measure motion in"});
  fs::remove_all(work() / "out");
  assess_is_clean("one", "one_white", {"one", "1x1 is too small to measure motion in"});
}

TEST_F(NumericalLimitsCli, PressesAtZeroForceOrWithoutNoise) {
  const LogisticParams truth{0.05, 12, 3};
  auto table = [&](const std::vector<double>& kpa, bool exact) {
    std::string csv = "trial,mean_pressure_kpa,signal\n";
    int k = 0;
    for (double p : kpa) {
      const double y = logistic_signal(truth, p) + (exact ? 0.0 : 0.0005 * std::sin(7.3 * k));
      csv += "t" + std::to_string(k++) + "," + std::to_string(p) + "," + std::to_string(y) + "\n";
    }
    return csv;
  };
  std::vector<double> levels;
  for (int l = 0; l < 10; ++l)
    for (int r = 0; r < 3; ++r) levels.push_back(3.0 * l);
  // Every press at zero force.
  write_text(work() / "zero.csv", table(std::vector<double>(12, 0.0), false));
  expect_input_error({"calibrate-pressure", "--presses", "zero.csv", "--person", "p", "--out", "cal.json"},
                     {"zero.csv", "1 distinct pressure level"});
  // Noise-free presses (zero residuals: the robust scale is 0) and presses with rest (0 N) rows.
  for (const auto& [name, exact] : {std::pair{"exact.csv", true}, std::pair{"rest.csv", false}}) {
    write_text(work() / name, table(levels, exact));
    const RunResult r = run({"calibrate-pressure", "--presses", name, "--person", "p", "--out", "cal.json",
                             "--report", "r.json"});
    ASSERT_EQ(r.exit_code, 0) << r;
    EXPECT_FALSE(prints_non_finite(r.out)) << r;
    EXPECT_FALSE(prints_non_finite(r.err)) << r;
    for (const char* file : {"cal.json", "r.json"}) {  // null stands for "not given" or a flagged press's estimate
      std::vector<std::string> nulls;
      collect_nulls(json::parse(read_text(work() / file)), file, nulls);
    }
    const PressureCalibration cal = read_pressure_calibration(work() / "cal.json");
    EXPECT_NEAR(cal.logistic.p50_kpa, truth.p50_kpa, exact ? 1e-3 : 0.5) << name;  // the CSV holds 6 decimals
    fs::remove(work() / "cal.json");
    fs::remove(work() / "r.json");
  }
}

}  // namespace
}  // namespace clearfit::cli_test
