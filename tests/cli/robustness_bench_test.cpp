// clearfit-bench robustness --quick: a smoke test (the wristband at scale 0.2, the mild
// strength of each effect, corrections on). It asserts only that the bench runs and writes
// its table with finite numbers; the accuracy bars are the per-effect tests'
// (photometric_test.cpp, motion_test.cpp and the others).
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace clearfit::cli_test {
namespace {

TEST_F(CliTest, RobustnessBenchQuickWritesItsTable) {
  const RunResult r = run_clearfit({"robustness", "--quick", "--out", "rob", "--clearfit", clearfit_exe().string()}, work(), work(), 240,
                                   CLEARFIT_BENCH_EXE);
  ASSERT_EQ(r.exit_code, 0) << r;
  for (const char* f : {"robustness.csv", "robustness.json", "robustness.md"}) EXPECT_TRUE(fs::exists(work() / "rob" / f)) << f;
  const auto j = nlohmann::json::parse(read_text(work() / "rob" / "robustness.json"));
  ASSERT_EQ(j["rows"].size(), 5u) << r;  // none, motion, glare, exposure, flicker
  int scored = 0;
  for (const auto& row : j["rows"]) {
    if (row["refused"].get<bool>()) continue;
    ++scored;
    EXPECT_TRUE(row["pearson_vertex"].is_number() && std::isfinite(row["pearson_vertex"].get<double>())) << row;
    EXPECT_GE(row["misses"].get<int>(), 0);
    EXPECT_GE(row["false_hotspots"].get<int>(), 0);
    EXPECT_GT(row["assess_s"].get<double>(), 0);
  }
  EXPECT_GE(scored, 1) << r;
  EXPECT_NE(r.out.find("| wristband | none | 0 |"), std::string::npos) << r;
}

}  // namespace
}  // namespace clearfit::cli_test
