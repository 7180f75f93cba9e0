#pragma once
// Subcommands of the clearfit front end. Each registers its options on the
// app and returns the function that runs it (exit code).
#include <CLI/CLI.hpp>
#include <functional>

namespace clearfit::cli {

using Run = std::function<int()>;

Run add_mesh_info(CLI::App& app);
Run add_map(CLI::App& app);
Run add_bench(CLI::App& app);

}  // namespace clearfit::cli
