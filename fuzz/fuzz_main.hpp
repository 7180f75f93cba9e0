#pragma once
// libFuzzer targets for clearfit's readers: each feeds the input, written to a
// file (the readers take paths), to one reader. A reader may refuse the input
// with clearfit::InputError (the exit-2 path); anything else — a crash, a
// sanitizer report, another exception (exit 1), a timeout or unbounded memory —
// is a finding. Each fuzz_<module>.cpp defines readers() for its module's
// formats; CLEARFIT_FUZZ_TARGET (a compile definition) picks one.
#include <clearfit/error.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <system_error>
#include <unistd.h>

namespace clearfit::fuzz {
namespace fs = std::filesystem;
using Reader = std::pair<std::string, std::function<void(const fs::path&)>>;  // file extension, reader
const std::map<std::string, Reader>& readers();
}  // namespace clearfit::fuzz

namespace clearfit::fuzz {
/// The file each input is written to, one per process, removed when the process exits normally (a crash keeps it).
struct InputFile {
  fs::path path;
  ~InputFile() {
    std::error_code ignored;
    fs::remove(path, ignored);
  }
};
}  // namespace clearfit::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto& entry = clearfit::fuzz::readers().at(CLEARFIT_FUZZ_TARGET);
  static const clearfit::fuzz::InputFile input{std::filesystem::temp_directory_path() /
                                               ("clearfit-fuzz-" + std::to_string(::getpid()) + entry.first)};
  const std::filesystem::path& file = input.path;
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    entry.second(file);
  } catch (const clearfit::InputError&) {
    // refused with a message: the expected outcome for bad input
  }
  return 0;
}
