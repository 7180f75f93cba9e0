// stderr_capture.hpp: file descriptor 2 redirected to a temporary file around a call.
#include "stderr_capture.hpp"

#include <cstdio>
#include <mutex>
#include <sstream>

#include <unistd.h>

namespace clearfit::detail {
namespace {

std::mutex& capture_mutex() {
  static std::mutex m;
  return m;
}

/// fd 2 sent to `to` until restore(); restores on destruction.
class Redirect {
 public:
  explicit Redirect(int to) : saved_(::dup(2)) {
    std::fflush(stderr);
    if (saved_ >= 0 && ::dup2(to, 2) < 0) {
      ::close(saved_);
      saved_ = -1;
    }
  }
  Redirect(const Redirect&) = delete;
  Redirect& operator=(const Redirect&) = delete;
  ~Redirect() { restore(); }
  void restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    saved_ = -1;
  }

 private:
  int saved_;
};

std::string read_all(std::FILE* f) {
  std::string out;
  std::rewind(f);
  char buf[4096];
  while (const std::size_t n = std::fread(buf, 1, sizeof buf, f)) out.append(buf, n);
  return out;
}

}  // namespace

std::string capture_stderr(const std::function<void()>& f) {
  const std::lock_guard lock(capture_mutex());
  std::FILE* tmp = std::tmpfile();
  if (!tmp) {
    f();
    return "";
  }
  Redirect redirect(::fileno(tmp));
  try {
    f();
  } catch (...) {
    redirect.restore();
    std::fputs(read_all(tmp).c_str(), stderr);
    std::fclose(tmp);
    throw;
  }
  redirect.restore();
  std::string captured = read_all(tmp);
  std::fclose(tmp);
  return captured;
}

std::vector<std::string> mrcal_messages(const std::string& captured) {
  std::vector<std::string> out;
  std::istringstream in(captured);
  for (std::string line; std::getline(in, line);) {
    // "file.c(123): " : a name without blanks, a line number in parentheses, a colon.
    const auto open = line.find('('), close = line.find("): ");
    if (open != std::string::npos && close != std::string::npos && open < close && line.find(' ') > open &&
        line.find_first_not_of("0123456789", open + 1) == close)
      line.erase(0, close + 3);
    if (line.find_first_not_of(" \t\r") != std::string::npos) out.push_back(line);
  }
  return out;
}

}  // namespace clearfit::detail
