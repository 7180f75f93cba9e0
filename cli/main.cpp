// clearfit: shows where a wearable part presses on the body.
// The front end only parses options, calls the modules and picks exit codes:
//   0 success, 1 internal error (a bug: please report), 2 bad input.
#include "commands.hpp"

#include <clearfit/error.hpp>
#include <iostream>
#include <map>

int main(int argc, char** argv) {
  CLI::App app{"clearfit " CLEARFIT_VERSION
               " - where a wearable device presses on the body, seen through its clear printed part"};
  app.require_subcommand(0, 1);
  app.failure_message(CLI::FailureMessage::help);
  app.set_version_flag("--version", std::string("clearfit ") + CLEARFIT_VERSION);
  std::map<CLI::App*, clearfit::cli::Run> runs;
  auto add = [&](clearfit::cli::Run (*make)(CLI::App&)) {
    const auto before = app.get_subcommands({});
    clearfit::cli::Run run = make(app);
    for (CLI::App* sub : app.get_subcommands({}))
      if (std::find(before.begin(), before.end(), sub) == before.end()) runs[sub] = std::move(run);
  };
  add(clearfit::cli::add_mesh_info);
  add(clearfit::cli::add_map);
  add(clearfit::cli::add_bench);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    for (CLI::App* sub : app.get_subcommands())
      if (auto it = runs.find(sub); it != runs.end()) return it->second();
    std::cerr << "clearfit: error: a subcommand is required\n" << app.help();
    return 2;
  } catch (const clearfit::InputError& e) {
    std::cerr << "clearfit: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "clearfit: internal error: " << e.what() << "\n(this is a bug in clearfit; please report it with the command line)\n";
    return 1;
  }
}
