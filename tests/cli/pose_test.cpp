// End-to-end tests of `clearfit pose` on a rendered fixture with a known pose
// (tests/data/boards/README.md): pose file, camera with extrinsics, report, bad input.
#include "cli_support.hpp"

#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>

#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

const std::string kData = std::string(CLEARFIT_TEST_DATA_DIR) + "/boards/";

Rigid3 truth() {
  return Rigid3::from_rt({-0.49831823442222983, 0.1958103722485659, 0.049998596644955109, 5, -8, 230});
}

class PoseCli : public CliTest {};

TEST_F(PoseCli, RecoversTheFixturePose) {
  const RunResult r =
      run({"pose", kData + "pose_fixture.png", "--camera", kData + "opencv8_640x480.cameramodel", "--layout",
           kData + "pose_layout.yaml", "--out", "pose.json", "--write-camera", "cam.cameramodel", "--report",
           "report.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("tags 12, corners 48"), std::string::npos) << r;
  const Rigid3 pose = read_pose_json(work() / "pose.json");
  const double dt = (pose.translation - truth().translation).norm();
  const double dr = rodrigues_from_rotation(pose.rotation * truth().rotation.transpose()).norm() * 180 / M_PI;
  std::printf("pose error %.4f mm, %.5f deg\n", dt, dr);
  EXPECT_LT(dt, 0.1);
  EXPECT_LT(dr, 0.05);
  const CameraModel cam = read_cameramodel(work() / "cam.cameramodel");
  EXPECT_LT((cam.cam_from_part.translation - pose.translation).norm(), 1e-9);
  const auto report = nlohmann::json::parse(read_text(work() / "report.json"));
  EXPECT_EQ(report["schema"], "clearfit.part-pose-report/1");
  EXPECT_EQ(report["tags"].size(), 12u);
  EXPECT_LT(report["rms_px"].get<double>(), 0.1);
  EXPECT_GT(report["sigma_translation_mm"][2].get<double>(), 0.0);
}

TEST_F(PoseCli, BadInput) {
  write_text(work() / "bad_layout.yaml",
             "schema: clearfit.tag-layout/1\ntags:\n  - {id: 10, corners_mm: [[0, 0, 0]]}\n");
  expect_input_error({"pose", kData + "pose_fixture.png", "--camera", kData + "opencv8_640x480.cameramodel",
                      "--layout", "bad_layout.yaml", "--out", "p.json"},
                     {"bad_layout.yaml", "4 corners"});
  write_text(work() / "other.yaml",
             "schema: clearfit.tag-layout/1\ntags:\n  - {id: 3, corners_mm: [[0, 10, 0], [10, 10, 0], [10, "
             "0, 0], [0, 0, 0]]}\n");
  expect_input_error({"pose", kData + "pose_fixture.png", "--camera", kData + "opencv8_640x480.cameramodel",
                      "--layout", "other.yaml", "--out", "p.json"},
                     {"other.yaml", "usable corners"});
  expect_input_error({"pose", "nothing.png", "--camera", kData + "opencv8_640x480.cameramodel", "--layout",
                      kData + "pose_layout.yaml", "--out", "p.json"},
                     {"nothing.png"});
}

}  // namespace
}  // namespace clearfit::cli_test
