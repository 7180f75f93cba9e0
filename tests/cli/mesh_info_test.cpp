// End-to-end tests of `clearfit mesh-info`: the bundled wristband sample against
// the closed forms of its tessellated band, --json/--out, --repair, and bad input.
#include "cli_support.hpp"

#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <cfloat>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <regex>

namespace clearfit::cli_test {
namespace {

using nlohmann::json;

const std::string kSample = std::string(CLEARFIT_SAMPLES_DIR) + "/wristband/wristband.obj";

// samples/README.md: cylindrical_shell(32, 34.5, 100, 24, 96, 12).
constexpr double kRin = 32, kRout = 34.5, kSpanDeg = 100, kWidth = 24;
constexpr int kAround = 96, kAcross = 12;
double step_rad() { return kSpanDeg * std::numbers::pi / 180 / kAround; }
// Inner surface of the tessellated band: n flat strips, each a chord 2·r·sin(δ/2) wide.
double contact_area() { return kWidth * kAround * 2 * kRin * std::sin(step_rad() / 2); }
double outer_area() { return kWidth * kAround * 2 * kRout * std::sin(step_rad() / 2); }
// One edge face (y = ±w/2): n trapezoids between the two polygons.
double edge_area() { return kAround * 0.5 * (kRout * kRout - kRin * kRin) * std::sin(step_rad()); }
// Chord planes of inner and outer strip are parallel, (r_out − r_in)·cos(δ/2) apart.
double wall() { return (kRout - kRin) * std::cos(step_rad() / 2); }

class MeshInfo : public CliTest {};

TEST_F(MeshInfo, SampleText) {
  const RunResult r = run({"mesh-info", kSample, "--contact-group", "contact"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(r.err.empty()) << r;
  EXPECT_NE(r.out.find("closed"), std::string::npos) << r;
  EXPECT_NE(r.out.find("orientation consistent"), std::string::npos) << r;
  EXPECT_NE(r.out.find("normals point out"), std::string::npos) << r;
  EXPECT_NE(r.out.find("verdict   usable"), std::string::npos) << r;
  // "contact   group 'contact': 2304 faces, 1340.39 mm², 1 component"
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(contact +[^\n]*: (\d+) faces, ([0-9.eE+-]+) mm)"))) << r;
  EXPECT_EQ(std::stoi(m[1]), kAround * kAcross * 2);
  EXPECT_NEAR(std::stod(m[2]), contact_area(), 1e-5 * contact_area()) << r;  // 6 significant digits
  ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(thickness ([0-9.]+) \.\. ([0-9.]+) mm)"))) << r;
  EXPECT_NEAR(std::stod(m[1]), wall(), 1e-3);
  EXPECT_NEAR(std::stod(m[2]), wall(), 1e-3);
}

TEST_F(MeshInfo, SampleJsonMatchesClosedForms) {
  const RunResult r = run({"mesh-info", kSample, "--contact-group", "contact", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const json j = json::parse(r.out);
  EXPECT_EQ(j.at("schema"), "clearfit.mesh-info/1");
  EXPECT_EQ(j.at("faces"), 5040);
  EXPECT_EQ(j.at("closed"), true);
  EXPECT_EQ(j.at("consistently_oriented"), true);
  EXPECT_EQ(j.at("outward"), true);
  EXPECT_EQ(j.at("components"), 1);
  EXPECT_EQ(j.at("ok"), true);
  EXPECT_EQ(j.at("groups"), json({"contact", "outer", "side"}));

  // The OBJ holds the doubles exactly, but the OBJ importer reads single
  // precision (import.hpp): coordinates up to 34.5 mm carry ~2e-6 mm rounding.
  const double tol = 1e-6;  // relative, for areas and the volume
  const double ulp = 34.5 * FLT_EPSILON;  // absolute, for coordinates and lengths
  EXPECT_NEAR(j.at("contact").at("area_mm2").get<double>(), contact_area(), tol * contact_area());
  EXPECT_EQ(j.at("contact").at("faces"), kAround * kAcross * 2);
  EXPECT_EQ(j.at("contact").at("components"), 1);
  const double area = contact_area() + outer_area() + 2 * edge_area() + 2 * (kRout - kRin) * kWidth;
  EXPECT_NEAR(j.at("area_mm2").get<double>(), area, tol * area);
  const double volume = edge_area() * kWidth;  // a prism over the edge polygon
  EXPECT_NEAR(j.at("volume_mm3").get<double>(), volume, tol * volume);
  EXPECT_NEAR(j.at("thickness_mm").at("min").get<double>(), wall(), 2 * ulp);
  EXPECT_NEAR(j.at("thickness_mm").at("max").get<double>(), wall(), 2 * ulp);
  // Band about the y axis, symmetric about +z: x = ±r_out·sin(50°), z from r_in·cos(50°) to r_out.
  const double half = kSpanDeg / 2 * std::numbers::pi / 180;
  const json& bb = j.at("bbox_mm");
  EXPECT_NEAR(bb["min"][0].get<double>(), -kRout * std::sin(half), ulp);
  EXPECT_NEAR(bb["max"][0].get<double>(), kRout * std::sin(half), ulp);
  EXPECT_NEAR(bb["min"][1].get<double>(), -kWidth / 2, ulp);
  EXPECT_NEAR(bb["max"][1].get<double>(), kWidth / 2, ulp);
  EXPECT_NEAR(bb["min"][2].get<double>(), kRin * std::cos(half), ulp);
  EXPECT_NEAR(bb["max"][2].get<double>(), kRout, ulp);
}

TEST_F(MeshInfo, OutWritesTheSameJsonAndNothingElse) {
  const RunResult r = run({"mesh-info", kSample, "--contact-group", "contact", "--json", "--out", "report.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(json::parse(read_text(work() / "report.json")), json::parse(r.out));
  EXPECT_EQ(listing(work()), std::set<std::string>{"report.json"});  // no temporary file left

  // Text on stdout, the JSON in the file; an existing report is replaced.
  const RunResult t = run({"mesh-info", kSample, "--contact-group", "contact", "--out", "report.json"});
  ASSERT_EQ(t.exit_code, 0) << t;
  EXPECT_NE(t.out.find("contact "), std::string::npos) << t;
  EXPECT_EQ(json::parse(read_text(work() / "report.json")), json::parse(r.out));
  EXPECT_EQ(listing(work()), std::set<std::string>{"report.json"});
}

// A box whose faces all wind clockwise seen from outside.
Mesh inside_out_box() {
  Mesh m = shapes::box(Vec3(10, 20, 30));
  for (auto& f : m.faces) std::swap(f[1], f[2]);
  return m;
}

TEST_F(MeshInfo, InsideOutBoxIsReported) {
  save_mesh(inside_out_box(), work() / "inside_out.obj");
  const RunResult text = run({"mesh-info", "inside_out.obj"});
  ASSERT_EQ(text.exit_code, 0) << text;
  EXPECT_NE(text.out.find("normals point IN"), std::string::npos) << text;
  EXPECT_NE(text.out.find("needs attention"), std::string::npos) << text;
  const RunResult r = run({"mesh-info", "inside_out.obj", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const json j = json::parse(r.out);
  EXPECT_EQ(j.at("outward"), false);
  EXPECT_EQ(j.at("ok"), false);
  EXPECT_TRUE(j.at("repairs").empty());
}

TEST_F(MeshInfo, RepairTurnsAnInsideOutBoxAndSaysSo) {
  save_mesh(inside_out_box(), work() / "inside_out.obj");
  const RunResult text = run({"mesh-info", "inside_out.obj", "--repair"});
  ASSERT_EQ(text.exit_code, 0) << text;
  EXPECT_NE(text.out.find("repaired: "), std::string::npos) << text;
  EXPECT_NE(text.out.find("normals point out"), std::string::npos) << text;

  const RunResult r = run({"mesh-info", "inside_out.obj", "--repair", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const json j = json::parse(r.out);
  ASSERT_EQ(j.at("repairs").size(), 1u) << j.dump(2);
  const std::string said = j["repairs"][0];
  EXPECT_TRUE(said.find("revers") != std::string::npos || said.find("orient") != std::string::npos) << said;
  EXPECT_NE(said.find("12"), std::string::npos) << "should count the 12 turned faces: " << said;
  EXPECT_EQ(j.at("outward"), true);
  EXPECT_EQ(j.at("ok"), true);
  EXPECT_NEAR(j.at("volume_mm3").get<double>(), 6000.0, 1e-9);
  EXPECT_EQ(j.at("faces"), 12);  // nothing dropped
  EXPECT_EQ(read_text(work() / "inside_out.obj").find("# clearfit mesh"), 0u);  // the input is left alone
}

TEST_F(MeshInfo, RepairOfASoundMeshSaysNothing) {
  save_mesh(shapes::box(Vec3(10, 20, 30)), work() / "box.obj");
  const std::string before = read_text(work() / "box.obj");
  const RunResult ok = run({"mesh-info", "box.obj", "--repair"});
  ASSERT_EQ(ok.exit_code, 0) << ok;
  EXPECT_EQ(ok.out.find("repaired:"), std::string::npos) << ok;
  EXPECT_EQ(read_text(work() / "box.obj"), before);
}

// ---- bad input: exit 2, the message names the culprit, no output left behind ----

class MeshInfoBadInput : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    save_mesh(shapes::box(Vec3(10, 20, 30), 2), work() / "box.obj");
  }
};

TEST_F(MeshInfoBadInput, MissingMesh) {
  expect_input_error({"mesh-info", "no_such_part.stl", "--out", "report.json"}, {"no_such_part.stl"});
}

TEST_F(MeshInfoBadInput, EmptyFile) {
  write_text(work() / "empty.stl", "");
  expect_input_error({"mesh-info", "empty.stl", "--out", "report.json"}, {"empty.stl"});
  write_text(work() / "empty.obj", "");
  expect_input_error({"mesh-info", "empty.obj", "--out", "report.json"}, {"empty.obj"});
}

TEST_F(MeshInfoBadInput, UnknownExtension) {
  fs::copy_file(work() / "box.obj", work() / "box.xyz");
  expect_input_error({"mesh-info", "box.xyz", "--out", "report.json"}, {"box.xyz"});
}

TEST_F(MeshInfoBadInput, DirectoryInsteadOfFile) {
  fs::create_directory(work() / "part.stl");
  expect_input_error({"mesh-info", "part.stl", "--out", "report.json"}, {"part.stl"});
}

TEST_F(MeshInfoBadInput, ContactGroupThatDoesNotExist) {
  expect_input_error({"mesh-info", "box.obj", "--contact-group", "wrist", "--out", "report.json"},
                     {"box.obj", "wrist"});
}

TEST_F(MeshInfoBadInput, NormalConeSelectingNothing) {
  // Box faces point along ±x, ±y, ±z: a 10° cone about (1,1,0) holds none of them.
  expect_input_error({"mesh-info", "box.obj", "--contact-normal", "1,1,0", "--contact-angle", "10", "--out",
                      "report.json"},
                     {"box.obj", "selects no faces"});
}

TEST_F(MeshInfoBadInput, BogusUnits) {
  expect_input_error({"mesh-info", "box.obj", "--units", "bogus", "--out", "report.json"}, {"--units", "bogus"});
}

TEST_F(MeshInfoBadInput, OutInAFolderThatDoesNotExist) {
  expect_input_error({"mesh-info", "box.obj", "--out", "no_such_dir/report.json"}, {"no_such_dir/report.json"});
}

TEST_F(MeshInfoBadInput, GarbageFaceFile) {
  write_text(work() / "faces.txt", "0 1 two 3\n");
  expect_input_error({"mesh-info", "box.obj", "--contact-faces", "faces.txt", "--out", "report.json"},
                     {"faces.txt", "two"});
}

}  // namespace
}  // namespace clearfit::cli_test
