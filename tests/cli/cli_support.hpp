#pragma once
// Helpers for end-to-end tests of the clearfit executable: run it with fixed
// arguments (posix_spawn, no shell), capture stdout, stderr and the exit code,
// and give each test its own scratch folder.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace clearfit::cli_test {

namespace fs = std::filesystem;

/// The executable under test: $CLEARFIT_EXE (set by tests/CMakeLists.txt).
inline fs::path clearfit_exe() {
  const char* exe = std::getenv("CLEARFIT_EXE");
  if (!exe || !*exe) throw std::runtime_error("CLEARFIT_EXE is not set (run the test through ctest)");
  return exe;
}

inline std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

struct RunResult {
  int exit_code = -1;       ///< exit status; 128 + signal if killed by a signal
  std::string out, err;     ///< captured stdout and stderr
  std::string command;      ///< for failure messages
  double seconds = 0;       ///< wall time
  double max_rss_mb = 0;    ///< the process's peak resident memory (getrusage's ru_maxrss)
};

inline std::ostream& operator<<(std::ostream& os, const RunResult& r) {
  return os << "command: " << r.command << "\nexit " << r.exit_code << "\n--- stdout ---\n"
            << r.out << "--- stderr ---\n" << r.err;
}

/// Runs `clearfit args...` (or `program args...`) with working directory `workdir`; stdout and stderr
/// go to files in `capture_dir` (outside the folders the tests inspect).
/// Kills the process after `timeout_s` seconds (exit code 128 + SIGKILL).
inline RunResult run_clearfit(const std::vector<std::string>& args, const fs::path& workdir,
                              const fs::path& capture_dir, double timeout_s = 30, const fs::path& program = {}) {
  RunResult r;
  const fs::path exe = program.empty() ? clearfit_exe() : program;
  std::vector<std::string> argv_s{exe.string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  for (const auto& a : argv_s) r.command += (r.command.empty() ? "" : " ") + a;
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);

  const fs::path out_path = capture_dir / "stdout.txt", err_path = capture_dir / "stderr.txt";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addchdir_np(&actions, workdir.c_str());  // the child starts in workdir
  pid_t pid = 0;
  const auto start = std::chrono::steady_clock::now();
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("posix_spawn " + exe.string() + ": " + std::strerror(rc));

  int status = 0;
  struct rusage usage {};
  for (;;) {
    const pid_t w = wait4(pid, &status, WNOHANG, &usage);
    if (w == pid) break;
    if (w < 0) throw std::runtime_error(std::string("wait4: ") + std::strerror(errno));
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed > timeout_s) {
      kill(pid, SIGKILL);
      wait4(pid, &status, 0, &usage);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.max_rss_mb = usage.ru_maxrss / 1024.0;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  r.out = read_text(out_path);
  r.err = read_text(err_path);
  return r;
}

/// Every path below `dir`, relative to it (files and folders, sorted).
inline std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) names.insert(fs::relative(e.path(), dir).string());
  return names;
}

/// Test fixture: a fresh scratch folder per test, `work()` for inputs and
/// outputs (the clearfit working directory), captured output kept apart.
class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("clearfit_cli_") + info->test_suite_name() + "_" + info->name() + "_XXXXXX";
    for (char& c : name)
      if (c == '/') c = '_';
    std::string templ = (fs::temp_directory_path() / name).string();
    if (!mkdtemp(templ.data())) throw std::runtime_error("mkdtemp failed");
    root_ = templ;
    fs::create_directories(root_ / "work");
    fs::create_directories(root_ / "capture");
  }
  void TearDown() override {
    std::error_code ec;
    if (!HasFailure()) fs::remove_all(root_, ec);
    else std::cerr << "kept scratch folder " << root_ << "\n";
  }
  const fs::path& root() const { return root_; }
  fs::path work() const { return root_ / "work"; }
  RunResult run(const std::vector<std::string>& args) { return run_clearfit(args, work(), root_ / "capture"); }

  /// Runs a command that must fail on bad input: exit code 2, a stderr
  /// mentioning every string in `must_name`, and no file added to or changed
  /// in the working folder (no output, no temporary file left behind).
  void expect_input_error(const std::vector<std::string>& args, const std::vector<std::string>& must_name) {
    expect_input_error_in(work(), root_ / "capture", args, must_name);
  }
  /// The same in the folder `dir` (output captured in `capture`): for tests that run cases side by side.
  static void expect_input_error_in(const fs::path& dir, const fs::path& capture, const std::vector<std::string>& args,
                                    const std::vector<std::string>& must_name) {
    const auto before = listing(dir);
    const RunResult r = run_clearfit(args, dir, capture);
    EXPECT_EQ(r.exit_code, 2) << r;
    for (const auto& s : must_name) EXPECT_NE(r.err.find(s), std::string::npos) << "stderr should name '" << s << "'\n" << r;
    EXPECT_EQ(listing(dir), before) << "files were added or removed by a failed run\n" << r;
  }

 private:
  fs::path root_;
};

}  // namespace clearfit::cli_test
