#pragma once
// Inputs that several tests of a suite need (simulated captures, a calibration), made once for all
// the processes that ctest starts: ctest runs every test in a process of its own, so a suite's
// static fixture was made again by each of its tests (AssessCli's simulation and calibration, about
// 35 s, by each of its 8 tests). The folder is kept in the build tree, keyed by what makes it.
#include <sys/file.h>

#include <cstdio>
#include <functional>

#include "cli_support.hpp"

namespace clearfit::cli_test {

/// The folder CLEARFIT_BINARY_DIR/test-fixtures/NAME-KEY, made by `make` (given an empty folder) the
/// first time and reused after. KEY hashes `recipe` (the text that decides the contents: scene files,
/// commands), the contents of the files in `inputs` and the clearfit executable's size and time, so
/// a rebuilt clearfit or a changed recipe makes the folder anew (older NAME-* folders are removed).
/// Processes that ask at once wait for the first (flock on NAME.lock); a folder whose making failed or
/// was killed is never used (it is made in NAME-KEY.tmp and renamed when complete). Tests read it and
/// must not write into it: copy what is to be changed.
inline fs::path shared_fixture(const std::string& name, const std::string& recipe, const std::vector<fs::path>& inputs,
                               const std::function<void(const fs::path&)>& make) {
  const fs::path root = fs::path(CLEARFIT_BINARY_DIR) / "test-fixtures";
  fs::create_directories(root);
  std::string identity = recipe;
  const fs::path exe = clearfit_exe();
  identity += "\n" + std::to_string(fs::file_size(exe)) + " " +
              std::to_string(fs::last_write_time(exe).time_since_epoch().count());
  for (const fs::path& p : inputs) identity += "\n" + p.string() + "\n" + read_text(p);
  char key[17];
  std::snprintf(key, sizeof key, "%016zx", std::hash<std::string>{}(identity));
  const fs::path dir = root / (name + "-" + key), staging = root / (name + "-" + key + ".tmp");

  const int lock = ::open((root / (name + ".lock")).c_str(), O_RDWR | O_CREAT, 0644);
  if (lock < 0 || ::flock(lock, LOCK_EX) != 0) throw std::runtime_error("cannot lock " + (root / (name + ".lock")).string());
  struct Unlock {
    int fd;
    ~Unlock() { ::close(fd); }  // closing releases the flock
  } unlock{lock};
  if (fs::is_directory(dir)) return dir;
  for (const auto& e : fs::directory_iterator(root)) {  // older versions of this fixture, and unfinished ones: NAME-KEY[.tmp]
    const std::string n = e.path().filename().string(), rest = n.substr(std::min(n.size(), name.size() + 1));
    const bool ours = n.rfind(name + "-", 0) == 0 && (rest.size() == 16 || rest == std::string(rest.substr(0, 16)) + ".tmp") &&
                      rest.find_first_not_of("0123456789abcdef") == std::min<std::size_t>(16, rest.size());
    if (e.is_directory() && ours) fs::remove_all(e.path());
  }
  fs::create_directories(staging);
  make(staging);
  fs::rename(staging, dir);
  return dir;
}

}  // namespace clearfit::cli_test
