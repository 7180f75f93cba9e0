// clearfit compare end to end: two hand-made assessment folders, the outputs,
// the Khronos validator on difference.glb, and refusals on bad input.
#include <clearfit/reports/compare.hpp>

#include "../reports/report_fixture.hpp"
#include "cli_support.hpp"

namespace clearfit::cli_test {
namespace {

using report_test::FixtureOptions;
using report_test::make_assessment_folder;

const fs::path kSourceDir = fs::path(CLEARFIT_TEST_DATA_DIR).parent_path().parent_path();

class CompareCli : public CliTest {};

TEST_F(CompareCli, WritesTheComparisonAndSaysWhatGotBetter) {
  FixtureOptions b;
  b.bumps = {{-8, 4, 14, 3}, {10, -5, 9, 2.5}};
  make_assessment_folder(work() / "a");
  make_assessment_folder(work() / "b", b);
  const RunResult r = run({"compare", "a", "b", "--out", "cmp"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("hotspot A#1 -> B#1: better"), std::string::npos) << r;
  EXPECT_NE(r.out.find("hotspot A#2 -> B#2: unchanged"), std::string::npos) << r;
  EXPECT_NE(r.err.find("same mesh"), std::string::npos) << r;
  for (const char* f : {"compare.json", "difference.glb", "compare.html"}) EXPECT_TRUE(fs::exists(work() / "cmp" / f)) << f;
  const auto summary = nlohmann::json::parse(read_text(work() / "cmp" / "compare.json"));
  EXPECT_EQ(summary["schema"], "clearfit.compare/1");

  // Every .glb passes the Khronos glTF validator (web/node_modules, installed by npm ci in web/).
  ASSERT_TRUE(fs::exists(kSourceDir / "web/node_modules/gltf-validator")) << "run `npm ci` in " << kSourceDir / "web";
  const std::string cmd = "node '" + (kSourceDir / "tests/tools/validate_gltf.mjs").string() + "' '" +
                          (work() / "cmp" / "difference.glb").string() + "' > '" + (root() / "validator.txt").string() + "' 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << read_text(root() / "validator.txt");
}

TEST_F(CompareCli, RefusesBadInput) {
  make_assessment_folder(work() / "a");
  FixtureOptions far;
  far.shift_x_mm = 4.3;
  make_assessment_folder(work() / "far", far);
  FixtureOptions signal;
  signal.calibrated = false;
  make_assessment_folder(work() / "signal", signal);
  fs::create_directories(work() / "empty");
  expect_input_error({"compare", "a", "empty", "--out", "cmp"}, {"empty", "report.json", "not found"});
  expect_input_error({"compare", "a", "far", "--out", "cmp"}, {"far", "does not correspond", "match-tolerance-mm"});
  expect_input_error({"compare", "signal", "a", "--out", "cmp"}, {"signal", "no pressure calibration"});
}

}  // namespace
}  // namespace clearfit::cli_test
