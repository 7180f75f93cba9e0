// compare_assessments on hand-made assessment folders: the per-vertex
// difference equals the analytic fields' difference, hotspots are called
// better / unchanged / new, shifted meshes are matched by nearest vertex, and
// non-corresponding or uncalibrated assessments are refused.
#include <clearfit/error.hpp>
#include <clearfit/reports/compare.hpp>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include "report_fixture.hpp"

namespace clearfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using report_test::FixtureOptions;
using report_test::fixture_pressure;
using report_test::make_assessment_folder;

class Compare : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / (std::string("clearfit_compare_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(root_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(root_);
  }
  fs::path root_;
};

// A float vertex attribute of the first mesh primitive of a .glb.
std::vector<float> attribute(const tinygltf::Model& m, const std::string& name) {
  const tinygltf::Accessor& acc = m.accessors.at(m.meshes.at(0).primitives.at(0).attributes.at(name));
  const tinygltf::BufferView& bv = m.bufferViews[acc.bufferView];
  const float* p = reinterpret_cast<const float*>(m.buffers[bv.buffer].data.data() + bv.byteOffset + acc.byteOffset);
  return {p, p + acc.count * tinygltf::GetNumComponentsInType(acc.type)};
}

TEST_F(Compare, SameAssessmentHasZeroDifference) {
  make_assessment_folder(root_ / "a");
  const auto r = reports::compare_assessments(root_ / "a", root_ / "a", root_ / "out");
  EXPECT_EQ(r.summary["schema"], "clearfit.compare/1");
  EXPECT_EQ(r.summary["correspondence"]["method"], "same_vertices");
  EXPECT_EQ(r.summary["difference"]["max_increase_kpa"], 0.0);
  EXPECT_EQ(r.summary["difference"]["max_decrease_kpa"], 0.0);
  ASSERT_EQ(r.summary["hotspots"].size(), 2u);
  for (const auto& h : r.summary["hotspots"]) EXPECT_EQ(h["verdict"], "unchanged") << h;
  for (const char* f : {"compare.json", "difference.glb", "compare.html"}) EXPECT_TRUE(fs::exists(root_ / "out" / f)) << f;
}

TEST_F(Compare, LowerBumpIsBetterAndDifferenceMatchesTheFields) {
  FixtureOptions a, b;
  b.bumps = {{-8, 4, 14, 3}, {10, -5, 9, 2.5}, {0, -10, 8, 2}};  // first bump lower, a new third one
  make_assessment_folder(root_ / "a", a);
  make_assessment_folder(root_ / "b", b);
  const auto r = reports::compare_assessments(root_ / "a", root_ / "b", root_ / "out");
  std::map<std::string, json> by_verdict;
  for (const auto& h : r.summary["hotspots"]) by_verdict[h["verdict"]] = h;
  ASSERT_TRUE(by_verdict.count("better")) << r.summary.dump(2);
  EXPECT_EQ(by_verdict["better"]["a_id"], 1);
  EXPECT_NEAR(by_verdict["better"]["delta_peak_kpa"].get<double>(), -6.0, 1e-12);
  ASSERT_TRUE(by_verdict.count("unchanged"));
  EXPECT_EQ(by_verdict["unchanged"]["b_id"], 2);
  ASSERT_TRUE(by_verdict.count("new"));
  EXPECT_EQ(by_verdict["new"]["b_id"], 3);

  // Every vertex of difference.glb holds B − A of the analytic fields at its position.
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, (root_ / "out" / "difference.glb").string())) << err;
  const auto pos = attribute(m, "POSITION");
  const auto diff = attribute(m, "_PRESSURE_DIFF_KPA");
  const auto seen = attribute(m, "_SEEN");
  int checked = 0;
  double lowest = 0;
  for (std::size_t v = 0; v < seen.size(); ++v) {
    if (seen[v] < 0.5f) continue;
    const double x = pos[3 * v], y = pos[3 * v + 1];
    const double expected = fixture_pressure(b, x, y) - fixture_pressure(a, x, y);
    ASSERT_NEAR(diff[v], expected, 1e-4) << "vertex " << v << " at " << x << ", " << y;
    lowest = std::min(lowest, expected);
    ++checked;
  }
  EXPECT_GT(checked, 300);
  EXPECT_NEAR(r.summary["difference"]["max_decrease_kpa"].get<double>(), lowest, 1e-4);
  const std::string html = [&] {
    std::ifstream in(r.html);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  EXPECT_NE(html.find("better: peak 6.0 kPa lower"), std::string::npos);
  EXPECT_NE(html.find("new in B (8.0 kPa)"), std::string::npos);
}

TEST_F(Compare, ShiftedMeshIsMatchedByNearestVertex) {
  FixtureOptions b;
  b.shift_x_mm = 0.2;  // the whole plate (and its pressure field) moved by 0.2 mm
  make_assessment_folder(root_ / "a");
  make_assessment_folder(root_ / "b", b);
  const auto r = reports::compare_assessments(root_ / "a", root_ / "b", root_ / "out");
  EXPECT_EQ(r.summary["correspondence"]["method"], "nearest_vertex");
  EXPECT_NEAR(r.summary["correspondence"]["max_distance_mm"].get<double>(), 0.2, 1e-5);
  EXPECT_GE(r.summary["correspondence"]["matched_fraction"].get<double>(), 0.95);
  EXPECT_NEAR(r.summary["difference"]["max_increase_kpa"].get<double>(), 0.0, 1e-4);
  EXPECT_NEAR(r.summary["difference"]["max_decrease_kpa"].get<double>(), 0.0, 1e-4);
  ASSERT_FALSE(r.notes.empty());
  EXPECT_NE(r.notes[0].find("nearest seen vertex"), std::string::npos);
}

TEST_F(Compare, DifferentContactRegionsAreRefused) {
  FixtureOptions b;
  b.shift_x_mm = 4.3;  // vertices 0.7 mm from any of A (grid step 40/24 mm)
  make_assessment_folder(root_ / "a");
  make_assessment_folder(root_ / "b", b);
  try {
    reports::compare_assessments(root_ / "a", root_ / "b", root_ / "out");
    FAIL() << "a 4.3 mm shift was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not correspond"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(root_ / "out"));
}

TEST_F(Compare, SignalOnlyAssessmentIsRefused) {
  FixtureOptions b;
  b.calibrated = false;
  make_assessment_folder(root_ / "a");
  make_assessment_folder(root_ / "b", b);
  try {
    reports::compare_assessments(root_ / "a", root_ / "b", root_ / "out");
    FAIL() << "a signal-only assessment was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no pressure calibration"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace clearfit
