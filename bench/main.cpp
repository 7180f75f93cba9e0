// clearfit-bench: benchmarks of clearfit (run time and error side by side),
// kept out of the shipped clearfit program. Each subcommand registers itself
// from its own bench/<name>_command.cpp, as clearfit's do (commands.hpp):
//   static const Registration registered{"map", 10, add_bench_map};
#include <clearfit/cli/commands.hpp>

int main(int argc, char** argv) {
  return clearfit::cli::run_program(argc, argv, "clearfit-bench", "benchmarks: run time against error");
}
