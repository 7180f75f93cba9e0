#pragma once
// Subcommands of the command-line programs: clearfit (cli/) and clearfit-bench
// (bench/). Each lives in its own <name>.cpp of the program's folder, registers
// its options on the app and returns the function that runs it (exit code). A
// file registers its subcommand with one line at namespace scope:
//   static const Registration registered{"map", 20, add_map};
// (the order number sets where it shows in --help). A program holds the
// subcommands of the files linked into it; its main() is run_program().
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace clearfit::cli {

using Run = std::function<int()>;
using AddCommand = Run (*)(CLI::App&);

struct Registration {
  Registration(std::string name, int order, AddCommand add);
};

struct RegisteredCommand {
  std::string name;
  int order;
  AddCommand add;
};
/// Every registered subcommand, sorted by order.
std::vector<RegisteredCommand> registered_commands();

/// The program's `--config FILE` option: a TOML file of a [COMMAND] section per command, `key = value` lines
/// with the options' long names (without dashes); the command line wins and keys that name no option are
/// refused (CLI::ConfigError). `config_file` receives the file's name, for messages.
void add_config_option(CLI::App& app, std::string& config_file);

/// Parses the command line, runs the chosen subcommand and picks the exit code:
/// 0 success, 1 internal error (a bug: please report), 2 bad input.
int run_program(int argc, char** argv, const std::string& program, const std::string& description);

/// `v` with `digits` digits after the point (for printed summaries).
std::string fixed(double v, int digits = 1);

}  // namespace clearfit::cli
