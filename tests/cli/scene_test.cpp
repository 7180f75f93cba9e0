// clearfit map --scene: a scene file gives the options, the command line wins,
// bad keys and types are named with their line.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

using namespace clearfit;
using namespace clearfit::cli_test;

namespace {
class Scene : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    fs::create_directories(work() / "part");
    save_mesh(shapes::slab(40, 30, 3, 2), work() / "part" / "slab.obj");
    CameraModel cam;
    cam.lensmodel = "LENSMODEL_PINHOLE";
    cam.intrinsics = {60, 60, 31.5, 23.5};
    cam.width = 64;
    cam.height = 48;
    cam.cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    cam.cam_from_part.translation = Vec3(0, 0, 60);
    write_cameramodel(cam, work() / "part" / "cam.cameramodel");
  }
  void scene(const std::string& text) { write_text(work() / "part" / "scene.yaml", text); }
};
const char* kScene = R"(mesh: slab.obj
ior: 1.49
contact:
  group: contact
camera: cam.cameramodel
map:
  mode: adaptive
  tolerance_um: 2.0
  exact_reasons: true
outputs:
  map: out/map.npy
  stats: out/stats.json
)";
}  // namespace

TEST_F(Scene, PathsAreRelativeToTheSceneAndTheCommandLineWins) {
  scene(kScene);
  RunResult r = run({"map", "--scene", "part/scene.yaml", "--no-cache"});
  ASSERT_EQ(r.exit_code, 0) << r;
  ASSERT_TRUE(fs::exists(work() / "part" / "out" / "map.npy"));
  auto stats = nlohmann::json::parse(read_text(work() / "part" / "out" / "stats.json"));
  EXPECT_EQ(stats["mode"], "adaptive");
  EXPECT_EQ(stats["tolerance_um"], 2.0);
  EXPECT_EQ(stats["exact_reasons"], true);
  EXPECT_EQ(stats["indices"]["part"], 1.49);
  EXPECT_EQ(stats["fast_path"], "flat-slab");
  r = run({"map", "--scene", "part/scene.yaml", "--no-cache", "--mode", "exact", "--ior", "1.55", "--stats", "s.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  stats = nlohmann::json::parse(read_text(work() / "s.json"));
  EXPECT_EQ(stats["mode"], "exact");
  EXPECT_EQ(stats["indices"]["part"], 1.55);
}

TEST_F(Scene, BadKeysAndTypesAreNamedWithTheirLine) {
  scene("mesh: slab.obj\nmapp:\n  mode: exact\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "line 2", "'mapp'"});
  scene("mesh: slab.obj\nior: glass\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "line 2", "'ior'", "number"});
  scene("mesh: slab.obj\ncontact:\n  normal: [0, 0]\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"line 3", "contact.normal"});
  scene("mesh: [slab.obj\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "not valid YAML"});
  scene("mesh: slab.obj\nmap:\n  mode: fast\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"map.mode", "'fast'"});
  scene("mesh: slab.obj\nmap:\n  exact_reasons: sometimes\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"line 3", "map.exact_reasons", "true or false"});
  expect_input_error({"map", "--scene", "part/missing.yaml"}, {"missing.yaml"});
  scene("");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "empty"});
  scene("mesh: slab.obj\n[map]: 1\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "line 2", "a key is a list, a map or empty"});
}

TEST_F(Scene, RulesNameTheKeyOrTheOptionWithTheValue) {
  // A value breaking a rule names where it came from: the scene's key, or the option that overrode it.
  scene(std::string(kScene) + "skin_ior: 0.5\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "'skin_ior'", "got 0.5", "from 1 to 3"});
  expect_input_error({"map", "--scene", "part/scene.yaml", "--skin-ior", "0.75"}, {"--skin-ior", "got 0.75"});
  scene("mesh: slab.obj\nmap:\n  grid_step: 3\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"'map.grid_step'", "got 3", "power of two"});
  scene("mesh: slab.obj\ncontact: {normal: [0, 0, 1], angle_deg: 0}\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"'contact.angle_deg'", "got 0"});
  // The signal's keys keep their rules in one place each (fit/skin_blur.hpp, BlanchingOptions), named by the scene's key.
  scene(std::string(kScene) + "assess: {skin_blur_mm: 7}\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "'assess.skin_blur_mm'", "= 7:", "from 0 to 5"});
  scene(std::string(kScene) + "assess: {curvature_smoothing_mm: 0}\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "'assess.curvature_smoothing_mm'", "= 0:", "(0, 20) mm"});
  scene(std::string(kScene) + "assess: {smoothing_mm: -1}\n");
  expect_input_error({"map", "--scene", "part/scene.yaml"}, {"scene.yaml", "'assess.smoothing_mm'", "= -1:"});
  scene(kScene);
  expect_input_error({"assess", "part/scene.yaml", "--skin-blur-mm", "-0.5"}, {"--skin-blur-mm", "= -0.5:"});
  // A key the command line gave is not read from the file: the scene's bad value is never seen.
  scene(std::string(kScene) + "skin_ior: 0.5\n");
  const RunResult r = run({"map", "--scene", "part/scene.yaml", "--no-cache", "--skin-ior", "1.38", "--stats", "s.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(nlohmann::json::parse(read_text(work() / "s.json"))["indices"]["skin"], 1.38);
}
