// The subcommand registry and the programs' shared main (cli/include/clearfit/cli/commands.hpp).
#include <clearfit/cli/commands.hpp>

#include <clearfit/error.hpp>
#include <clearfit/format.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <map>

namespace clearfit::cli {
namespace {
std::vector<RegisteredCommand>& registry() {
  static std::vector<RegisteredCommand> commands;
  return commands;
}

/// Every subcommand under `root`, nested ones too.
std::vector<CLI::App*> all_subcommands(CLI::App& root) {
  std::vector<CLI::App*> out, todo{&root};
  while (!todo.empty()) {
    CLI::App* a = todo.back();
    todo.pop_back();
    for (CLI::App* s : a->get_subcommands({})) out.push_back(s), todo.push_back(s);
  }
  return out;
}
}  // namespace

Registration::Registration(std::string name, int order, AddCommand add) {
  registry().push_back({std::move(name), order, add});
}

std::vector<RegisteredCommand> registered_commands() {
  auto commands = registry();
  std::sort(commands.begin(), commands.end(), [](const auto& a, const auto& b) { return a.order < b.order; });
  return commands;
}

void add_config_option(CLI::App& app, std::string& config_file) {
  app.set_config("--config", "", "Options from a file (TOML): a [COMMAND] section per command, key = value with the options' long names; the command line wins")
      ->each([&config_file](const std::string& f) { config_file = f; })
      ->check(CLI::ExistingFile);
  app.allow_config_extras(CLI::config_extras_mode::error);
}

std::string fixed(double v, int digits) { return fixed_digits(v, digits); }

int run_program(int argc, char** argv, const std::string& program, const std::string& description) {
  CLI::App app{program + " " CLEARFIT_VERSION " - " + description};
  app.require_subcommand(0, 1);
  app.failure_message(CLI::FailureMessage::help);
  app.set_version_flag("--version", program + " " CLEARFIT_VERSION);
  std::string config_file;
  add_config_option(app, config_file);
  std::map<CLI::App*, Run> runs;
  // Every subcommand a registration adds (nested ones too) runs its Run.
  for (const auto& command : registered_commands()) {
    const auto before = all_subcommands(app);
    Run run = command.add(app);
    for (CLI::App* sub : all_subcommands(app))
      if (std::find(before.begin(), before.end(), sub) == before.end()) runs[sub] = run;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ConfigError& e) {
    std::cerr << program << ": error: " << config_file << ": " << e.what()
              << ": each key of a [COMMAND] section must be one of that command's long options (see " << program << " COMMAND --help)\n";
    return 2;
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
    std::cerr << program << ": error: a subcommand is required\n" << app.help();
    return 2;
  } catch (const InputError& e) {
    std::cerr << program << ": error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << program << ": internal error: " << e.what() << "\n(this is a bug in " << program
              << "; please report it with the command line)\n";
    return 1;
  }
}

}  // namespace clearfit::cli
