#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/output_folder.hpp>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <unistd.h>

namespace clearfit {
namespace {
std::filesystem::path temporary_beside(const std::filesystem::path& path) {
  static std::atomic<unsigned> counter{0};
  std::filesystem::path tmp = path;
  tmp.replace_filename("." + path.stem().string() + ".tmp" + std::to_string(::getpid()) + "_" +
                       std::to_string(counter++) + path.extension().string());
  return tmp;
}
}  // namespace

void write_path_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path&)>& write) {
  if (path.empty()) throw InputError("", "output path", "is empty");
  if (std::filesystem::is_directory(path))
    throw InputError(path.string(), "", "is a directory, expected a file name for the output");
  check_output_folder(path);
  remove_stale_temporaries(path);
  const auto tmp = temporary_beside(path);
  try {
    write(tmp);
    pause_point("file-written");
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw OutputError(path.string(), "", "cannot write the output: " + ec.message());
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
}

void write_file_atomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write) {
  write_path_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw OutputError(path.string(), "", "cannot create the output file", "check the folder's permissions");
    errno = 0;
    write(out);
    out.flush();
    if (!out) {
      // The stream keeps no reason; the failed write(2) left it in errno (ENOSPC, EFBIG, EDQUOT, EIO).
      const std::string why = errno != 0 ? std::strerror(errno) : "the stream failed";
      throw OutputError(path.string(), "", "writing failed: " + why, "free space on its disk or write the outputs elsewhere");
    }
  });
}

void write_file_atomically(const std::filesystem::path& path, std::string_view contents) {
  write_file_atomically(path, [&](std::ostream& out) { out.write(contents.data(), static_cast<std::streamsize>(contents.size())); });
}

}  // namespace clearfit
