// libFuzzer targets: the geometry readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/geometry/import.hpp>

namespace clearfit::fuzz {

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"stl", {".stl", [](const fs::path& p) { load_mesh(p); }}},
      {"obj", {".obj", [](const fs::path& p) { load_mesh(p); }}},
      {"ply", {".ply", [](const fs::path& p) { load_mesh(p); }}},
      {"off", {".off", [](const fs::path& p) { load_mesh(p); }}},
      {"3mf", {".3mf", [](const fs::path& p) { load_mesh(p); }}},
      {"gltf", {".gltf", [](const fs::path& p) { load_mesh(p); }}},
      {"glb", {".glb", [](const fs::path& p) { load_mesh(p); }}},
  };
  return r;
}

}  // namespace clearfit::fuzz
