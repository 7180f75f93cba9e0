// clearfit: shows where a wearable part presses on the body.
// The front end only parses options, calls the modules and picks exit codes:
//   0 success, 1 internal error (a bug: please report), 2 bad input.
// Each subcommand registers itself from its own cli/<name>.cpp (commands.hpp).
#include <clearfit/cli/commands.hpp>

int main(int argc, char** argv) {
  return clearfit::cli::run_program(argc, argv, "clearfit",
                                    "where a wearable device presses on the body, seen through its clear printed part");
}
