#pragma once
// Runs a program and waits for it (posix_spawn, no shell).
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit::study {

struct ProcessResult {
  int exit_code = -1;     ///< exit status; 128 + signal when killed by one; −1 when it could not start
  double max_rss_mb = 0;  ///< its peak resident memory
};

/// Runs `program args...` with stdin from /dev/null and stdout and stderr
/// appended to `log`; waits for it.
ProcessResult run_process(const std::filesystem::path& program, const std::vector<std::string>& args,
                          const std::filesystem::path& log);

}  // namespace clearfit::study
