#pragma once
// Outputs are written atomically: into a temporary file beside the target,
// then renamed over it, so a reader never sees half a file and a failure
// leaves nothing behind.
#include <filesystem>
#include <functional>
#include <ostream>
#include <string_view>

namespace clearfit {

/// Calls `write` with a binary stream on a temporary file next to `path`, then
/// renames it to `path`. On any failure (cannot create, stream error, exception
/// from `write`) removes the temporary file and throws InputError naming `path`.
void write_file_atomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write);
void write_file_atomically(const std::filesystem::path& path, std::string_view contents);

/// Same for writers that need a file name (libraries that open the file
/// themselves): `write(temp_path)` must create temp_path; it is renamed to
/// `path` afterwards. `temp_path` keeps the extension of `path`.
void write_path_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path&)>& write);

}  // namespace clearfit
