// libFuzzer targets: the geometry readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/geometry/import.hpp>

// lib3mf 1.8 leaks a few hundred bytes inside libzip on every 3MF it reads, a valid
// one included (fuzz/seeds/3mf/tetra.3mf: 648 bytes in 6 allocations): third-party,
// bounded by the file's zip entries. LeakSanitizer is told to ignore leaks from
// libzip, as tests/geometry/import_test.cpp does.
extern "C" const char* __lsan_default_suppressions() { return "leak:libzip.so\n"; }

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
