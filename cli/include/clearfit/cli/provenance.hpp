#pragma once
// Provenance: SHA-256 of the inputs a report names.
#include <filesystem>
#include <string>

namespace clearfit::cli {

/// Hex SHA-256 of a file's bytes; of a folder: of its regular files' names
/// and contents in name order (a capture given as a folder of frames).
/// Throws InputError when the path cannot be read.
std::string sha256_of_path(const std::filesystem::path& path);

}  // namespace clearfit::cli
