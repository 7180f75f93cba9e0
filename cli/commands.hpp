#pragma once
// Subcommands of the clearfit front end. Each lives in its own cli/<name>.cpp,
// registers its options on the app and returns the function that runs it
// (exit code). A file registers its subcommand with one line at namespace scope:
//   static const Registration registered{"map", 20, add_map};
// (the order number sets where it shows in --help).
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

}  // namespace clearfit::cli
