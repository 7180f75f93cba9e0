// libFuzzer targets: the camera readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/camera/tag_pose.hpp>

namespace clearfit::fuzz {

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"cameramodel", {".cameramodel", [](const fs::path& p) { read_cameramodel(p); }}},
      {"pose", {".json", [](const fs::path& p) { read_pose_json(p); }}},
      {"board", {".yaml", [](const fs::path& p) { read_board(p); }}},
      {"tag_layout", {".yaml", [](const fs::path& p) { read_tag_layout(p); }}},
      {"corners", {".vnl", [](const fs::path& p) { read_corners_vnl(p, CalibrationGrid{4, 3, 10}, 640, 480, false); }}},
  };
  return r;
}

}  // namespace clearfit::fuzz
