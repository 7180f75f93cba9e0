// libFuzzer targets: the cli readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/cli/scene.hpp>

#include <CLI/CLI.hpp>

namespace clearfit::fuzz {

// The scene as `clearfit assess` reads it (every section).
void read_scene_file(const fs::path& p) {
  CLI::App app;
  cli::Scene scene;
  CLI::App* sub = app.add_subcommand("assess");
  const auto options = cli::add_scene_options(*sub, scene, {""});
  cli::read_scene(p, scene, options);
}

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"scene", {".yaml", read_scene_file}},
  };
  return r;
}

}  // namespace clearfit::fuzz
