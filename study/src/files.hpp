#pragma once
// Study outputs are written whole or not at all: a temporary beside the file, then a rename.
#include <clearfit/error.hpp>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace clearfit::study {

inline void write_text_atomically(const std::filesystem::path& path, const std::string& text, bool executable = false) {
  const std::filesystem::path tmp = path.parent_path() / ("." + path.filename().string() + ".tmp");
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw InputError(tmp.string(), "", "cannot be written", "check the free space and permissions of the output folder");
  }
  if (executable) ::chmod(tmp.c_str(), 0755);
  std::filesystem::rename(tmp, path);
}

}  // namespace clearfit::study
