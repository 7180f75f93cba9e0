// clearfit: shows where a wearable part presses on the body.
// The front end only parses options, calls the modules and picks exit codes:
//   0 success, 1 internal error (a bug: please report), 2 bad input.
#include "commands.hpp"

#include <clearfit/error.hpp>
#include <iostream>
#include <algorithm>
#include <map>

namespace clearfit::cli {
namespace {
std::vector<RegisteredCommand>& registry() {
  static std::vector<RegisteredCommand> commands;
  return commands;
}
}  // namespace
Registration::Registration(std::string name, int order, AddCommand add) {
  registry().push_back({std::move(name), order, add});
}
std::vector<RegisteredCommand> registered_commands() {
  auto commands = registry();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.order < b.order; });
  return commands;
}
}  // namespace clearfit::cli

int main(int argc, char** argv) {
  CLI::App app{"clearfit " CLEARFIT_VERSION
               " - where a wearable device presses on the body, seen through its clear printed part"};
  app.require_subcommand(0, 1);
  app.failure_message(CLI::FailureMessage::help);
  app.set_version_flag("--version", std::string("clearfit ") + CLEARFIT_VERSION);
  std::map<CLI::App*, clearfit::cli::Run> runs;
  // Every subcommand a registration adds (nested ones too, e.g. "bench assess") runs its Run.
  auto all_subcommands = [](CLI::App& root) {
    std::vector<CLI::App*> out, todo{&root};
    while (!todo.empty()) {
      CLI::App* a = todo.back();
      todo.pop_back();
      for (CLI::App* s : a->get_subcommands({})) out.push_back(s), todo.push_back(s);
    }
    return out;
  };
  auto add = [&](clearfit::cli::AddCommand make) {
    const auto before = all_subcommands(app);
    clearfit::cli::Run run = make(app);
    for (CLI::App* sub : all_subcommands(app))
      if (std::find(before.begin(), before.end(), sub) == before.end()) runs[sub] = run;
  };
  for (const auto& command : clearfit::cli::registered_commands()) add(command.add);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    // The deepest parsed subcommand that has a Run.
    CLI::App* chosen = nullptr;
    for (CLI::App* level = &app; level;) {
      CLI::App* next = nullptr;
      for (CLI::App* sub : level->get_subcommands())
        if (sub->parsed()) next = sub;
      if (next && runs.count(next)) chosen = next;
      level = next;
    }
    if (chosen) return runs[chosen]();
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
