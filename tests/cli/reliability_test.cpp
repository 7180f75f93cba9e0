// Regression tests of defects found by feeding clearfit damaged inputs from
// outside: each once crashed, allocated without bound, exited 1 (internal
// error) or left an empty folder behind; each must now exit 2 with a message
// naming the file and the defect, and leave nothing.
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

namespace clearfit::cli_test {
namespace {

class Reliability : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_slab_part(work());
  }
  std::vector<std::string> map_args(const std::string& ior) {
    return {"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--contact-group", "contact", "--ior", ior, "--out", "m.npy"};
  }
  void scene(const std::string& extra) {
    write_text(work() / "scene.yaml", "mesh: slab.obj\ncamera: cam.cameramodel\ncontact: {group: contact}\n" + extra);
  }
};

TEST_F(Reliability, IndexOfRefractionIsBoundedOnTheCommandLineAndInTheScene) {
  for (const char* ior : {"1e9", "0", "-1.5", "nan", "3.5"}) {
    SCOPED_TRACE(ior);
    expect_input_error(map_args(ior), {"--ior", "an index of refraction from 1 to 3"});
  }
  scene("ior: 1e9\noutputs: {map: m.npy}\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"scene.yaml", "key 'ior'", "from 1 to 3", "got 1e+09"});
  // An index equal to the medium's is valid: the index-matched fast path.
  const RunResult r = run(map_args("1.0"));
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("fast path"), std::string::npos) << r;
}

TEST_F(Reliability, DuplicateSceneKeysAreRefused) {
  scene("ior: 1.49\nior: 1.2\noutputs: {map: m.npy}\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"scene.yaml", "line 5, key 'ior'", "is given twice"});
  scene("ior: 1.49\noutputs:\n  map: m.npy\n  map: n.npy\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"line 7, key 'outputs.map'", "is given twice"});
}

TEST_F(Reliability, FailingMapWithASceneLeavesNoFolder) {
  scene("ior: 1.49\noutputs: {map: out/deep/m.npy, stats: out/s.json}\nmap: {mode: grd}\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"scene.yaml", "map.mode"});
  // Fails when the part is loaded: a contact group the mesh does not have.
  write_text(work() / "scene.yaml", "mesh: slab.obj\ncamera: cam.cameramodel\ncontact: {group: nope}\nior: 1.49\n"
                                    "outputs: {map: out/deep/m.npy, stats: out/s.json}\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"nope"});
  // A folder that is a file.
  write_text(work() / "file", "x");
  scene("ior: 1.49\noutputs: {map: file/m.npy}\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"file/m.npy", "is a file, not a folder"});
  // The good run creates the folders.
  scene("ior: 1.49\noutputs: {map: out/deep/m.npy, stats: out/s.json}\n");
  const RunResult r = run({"map", "--scene", "scene.yaml"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(fs::exists(work() / "out/deep/m.npy"));
}

TEST_F(Reliability, SimulateOutUnderAFile) {
  scene("ior: 1.49\nsimulation:\n  presses: {diameters_mm: [2], levels: 4, repetitions: 1}\n");
  write_text(work() / "file", "x");
  expect_input_error({"simulate", "scene.yaml", "--presses-only", "--out", "file/sim"}, {"file", "is a file, not a folder"});
  expect_input_error({"simulate", "scene.yaml", "--presses-only", "--out", "file"}, {"file", "is a file, expected a folder"});
  expect_input_error({"simulate", "scene.yaml", "--presses-only", "--out", "."}, {"is the current folder"});
  const RunResult r = run({"simulate", "scene.yaml", "--presses-only", "--out", "a/b/sim"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(fs::exists(work() / "a/b/sim/presses.csv"));
}

TEST_F(Reliability, HugeImagerSizeIsRefusedBeforeAllocating) {
  std::string text = read_text(work() / "cam.cameramodel");
  const auto at = text.find("'imagersize'");
  ASSERT_NE(at, std::string::npos) << text;
  const auto open = text.find('[', at), close = text.find(']', at);
  text.replace(open, close - open + 1, "[ 100000000, 100000000 ]");
  write_text(work() / "huge.cameramodel", text);
  auto a = map_args("1.49");
  a[4] = "huge.cameramodel";
  expect_input_error(a, {"huge.cameramodel", "imagersize", "larger than any camera's imager"});
}

TEST_F(Reliability, NumberBeyondDoubleInACalibrationJson) {
  scene("ior: 1.49\ncaptures: {baseline: b.mkv, worn: w.mkv}\ncalibration: {pressure: cal.json, person: p}\noutputs: {folder: out}\n");
  write_text(work() / "cal.json", "{\"schema\": \"clearfit.pressure-calibration/1\", \"p50_kpa\": 1e309}\n");
  write_text(work() / "pose.json", "{\"schema\": \"clearfit.pose/1\", \"units\": \"mm\", \"x\": 1e309}\n");
  auto a = map_args("1.49");
  a.insert(a.end(), {"--pose", "pose.json"});
  expect_input_error(a, {"pose.json", "not valid JSON", "1e309"});
  expect_input_error({"assess", "scene.yaml", "--quiet", "--no-cache"}, {"cal.json", "not valid JSON", "1e309"});
}

TEST_F(Reliability, PressesCsvThatIsNotUtf8) {
  write_text(work() / "presses.csv", "trial,mean_pressure_kpa,signal\nt\xff\xfe,1,0.1\n");
  expect_input_error({"calibrate-pressure", "--presses", "presses.csv", "--person", "p", "--out", "cal.json"},
                     {"presses.csv", "line 2, column 2", "is not UTF-8 text"});
  write_text(work() / "scene.yaml", "mesh: slab.obj\nior: 1.49 # caf\xe9\n");
  expect_input_error({"map", "--scene", "scene.yaml"}, {"scene.yaml", "line 2", "is not UTF-8 text"});
}

TEST_F(Reliability, CalibrateCornerFarOutsideTheImager) {
  const CalibrationGrid grid{10, 10, 30};
  std::string vnl = "# filename x y level\n";
  for (int i = 0; i < 100; ++i)
    vnl += "a.png " + std::to_string(i == 7 ? 4e7 : 100.0 + 20 * (i % 10)) + " " + std::to_string(100.0 + 20 * (i / 10)) + " 0\n";
  write_text(work() / "c.vnl", vnl);
  expect_input_error({"calibrate", "--grid", "10", "10", "--spacing-mm", "30", "--corners", "c.vnl", "--imagersize", "640", "480",
                      "--out", "x.cameramodel"},
                     {"a.png", "corner 7", "lies far outside the 640 x 480 imager"});
}

}  // namespace
}  // namespace clearfit::cli_test
