// libFuzzer targets: the study readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/study/manifest.hpp>

namespace clearfit::fuzz {

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"manifest", {".yaml", [](const fs::path& p) { study::read_manifest(p); }}},
  };
  return r;
}

}  // namespace clearfit::fuzz
