// libFuzzer targets: the cli readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/scene.hpp>

#include <CLI/CLI.hpp>

#include <array>

namespace clearfit::fuzz {

// The scene as `clearfit assess` reads it (every section).
void read_scene_file(const fs::path& p) {
  CLI::App app;
  cli::Scene scene;
  CLI::App* sub = app.add_subcommand("assess");
  const auto options = cli::add_scene_options(*sub, scene, {""});
  cli::read_scene(p, scene, options);
}

// A `--config FILE` (TOML) as the programs read it (cli::add_config_option), for a command holding every scene
// option, then the scene those options override (a fixed, valid one) read and checked as `clearfit assess` does.
// A file the parser refuses (CLI::ParseError: the programs' exit 2 with its message) is a refusal.
void read_config_file(const fs::path& p) {
  static const InputFile scene_file{fs::temp_directory_path() / ("clearfit-fuzz-" + std::to_string(::getpid()) + "-scene.yaml")};
  static const bool written = static_cast<bool>(
      std::ofstream(scene_file.path) << "mesh: part.obj\nunits: mm\ncontact:\n  group: contact\ncamera: camera.cameramodel\n");
  (void)written;
  CLI::App app;
  std::string config_file;
  cli::add_config_option(app, config_file);
  cli::Scene scene;
  CLI::App* sub = app.add_subcommand("assess");
  const auto options = cli::add_scene_options(*sub, scene, {""});
  std::string program = "clearfit", flag = "--config", file = p.string(), command = "assess";
  std::array<char*, 4> argv{program.data(), flag.data(), file.data(), command.data()};
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError&) {
    return;
  }
  cli::read_scene(scene_file.path, scene, options);
}

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"scene", {".yaml", read_scene_file}},
      {"config", {".toml", read_config_file}},
  };
  return r;
}

}  // namespace clearfit::fuzz
