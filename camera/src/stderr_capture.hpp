#pragma once
// What a C library prints on the process's standard error while it runs, taken
// instead of shown: libmrcal reports through fprintf(stderr, ...) ("Threw out
// some outliers ...", parse errors), which a user should not see as noise from
// a library, and which clearfit turns into its own messages. Private to camera/src.
#include <functional>
#include <string>
#include <vector>

namespace clearfit::detail {

/// Runs `f` with file descriptor 2 sent to a temporary file and returns what was written there. One
/// capture at a time in the process (a mutex); what another thread prints meanwhile is captured with the
/// rest. If `f` throws, what was captured is printed on the restored standard error before the exception
/// goes on. Without a temporary file, `f` runs uncaptured and "" is returned.
std::string capture_stderr(const std::function<void()>& f);

/// The messages of mrcal's MSG() lines ("mrcal.c(1234): text"), without their source prefix; other
/// non-empty lines as they are.
std::vector<std::string> mrcal_messages(const std::string& captured);

}  // namespace clearfit::detail
