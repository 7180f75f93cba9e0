// Outputs survive a crash: `simulate`, `assess` and `calibrate` are killed
// with SIGKILL at every named point of their output swap (the process stops
// itself there when CLEARFIT_TEST_PAUSE_AT names it) and at moments spread
// over a whole run; after each kill the output path holds a complete folder
// (or file), the old one or the new one, and the next run removes what the
// killed one left beside it.
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

/// How a run ended.
enum class Ended { exited, paused_and_killed, killed };

/// Starts clearfit in `workdir` with CLEARFIT_TEST_PAUSE_AT=`stage` (none when
/// empty). If the process stops itself there it is killed; when `kill_after_s`
/// >= 0 it is killed after that time, wherever it is.
Ended run_and_kill(const std::vector<std::string>& args, const fs::path& workdir, const fs::path& capture,
                   const std::string& stage, double kill_after_s = -1) {
  std::vector<std::string> env_s;
  for (char** e = environ; *e; ++e)
    if (std::string(*e).rfind("CLEARFIT_TEST_PAUSE_AT=", 0) != 0) env_s.emplace_back(*e);
  if (!stage.empty()) env_s.push_back("CLEARFIT_TEST_PAUSE_AT=" + stage);
  std::vector<char*> env;
  for (auto& e : env_s) env.push_back(e.data());
  env.push_back(nullptr);
  std::vector<std::string> argv_s{clearfit_exe().string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, (capture / "stdout.txt").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, (capture / "stderr.txt").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addchdir_np(&actions, workdir.c_str());
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), env.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error(std::string("posix_spawn: ") + std::strerror(rc));
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    int status = 0;
    const pid_t w = waitpid(pid, &status, WNOHANG | WUNTRACED);
    if (w == pid && WIFSTOPPED(status)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return Ended::paused_and_killed;
    }
    if (w == pid) return Ended::exited;
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if ((kill_after_s >= 0 && t >= kill_after_s) || t > 120) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return Ended::killed;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

/// Entries of `dir` whose names start with ".<name>." (staging and old folders, temporary files).
std::vector<std::string> leftovers(const fs::path& dir, const std::string& name) {
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("." + name + ".", 0) == 0 || n.rfind("." + fs::path(name).stem().string() + ".tmp", 0) == 0) found.push_back(n);
  }
  return found;
}

class CrashSafety : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_slab_part(work());
    write_text(work() / "scene.yaml", slab_scene(", motion_compensation: false", "", "  motion: {step_px: 0}\n"));
  }
  Ended kill_at(const std::vector<std::string>& args, const std::string& stage, double after_s = -1) {
    return run_and_kill(args, work(), root() / "capture", stage, after_s);
  }
  double timed_run(const std::vector<std::string>& args) {
    const RunResult r = run(args);
    EXPECT_EQ(r.exit_code, 0) << r;
    return r.seconds;
  }

  /// Kills `args` at every stage and at `moments` times spread over `seconds`;
  /// after each kill, `complete()` must hold; the next good run (`reset`)
  /// leaves no leftovers of `name` in work().
  template <class Check>
  void kill_everywhere(const std::vector<std::string>& args, const std::vector<std::string>& reset, const std::string& name,
                       const std::vector<std::string>& stages, double seconds, int moments, Check complete) {
    int paused = 0;
    for (const auto& stage : stages) {
      SCOPED_TRACE("stage " + stage);
      const Ended e = kill_at(args, stage);
      paused += e == Ended::paused_and_killed;
      EXPECT_EQ(e, Ended::paused_and_killed) << "the run never reached " << stage;
      complete();
      timed_run(reset);
      complete();
      EXPECT_EQ(leftovers(work(), name), std::vector<std::string>{});
    }
    for (int k = 0; k < moments; ++k) {
      const double t = seconds * (k + 0.5) / moments;
      SCOPED_TRACE("killed after " + std::to_string(t) + " s");
      kill_at(args, "", t);
      complete();
      timed_run(reset);
      EXPECT_EQ(leftovers(work(), name), std::vector<std::string>{});
    }
    EXPECT_EQ(paused, static_cast<int>(stages.size()));
  }
};

const std::vector<std::string> kFolderStages{"staged", "file-written", "written", "swapped"};

TEST_F(CrashSafety, SimulateAndAssessAlwaysLeaveAWholeFolder) {
  const std::vector<std::string> sim_old{"simulate", "scene.yaml", "--out", "sim", "--seed", "3", "--quiet"};
  const std::vector<std::string> sim_new{"simulate", "scene.yaml", "--out", "sim", "--seed", "4", "--quiet"};
  const double sim_s = timed_run(sim_old);
  const auto sim_listing = listing(work() / "sim");
  auto sim_complete = [&] {
    ASSERT_TRUE(fs::is_directory(work() / "sim")) << "no output folder after the kill";
    EXPECT_EQ(listing(work() / "sim"), sim_listing);
    const auto truth = nlohmann::json::parse(read_text(work() / "sim" / "truth.json"));
    EXPECT_TRUE(truth.at("seed") == 3 || truth.at("seed") == 4) << truth.at("seed");
  };
  kill_everywhere(sim_new, sim_old, "sim", kFolderStages, sim_s, 4, sim_complete);

  const std::vector<std::string> assess_args{"assess", "scene.yaml", "--quiet", "--no-html"};
  const double assess_s = timed_run(assess_args);
  const auto out_listing = listing(work() / "out");
  ASSERT_TRUE(out_listing.count("report.json")) << ::testing::PrintToString(out_listing);
  auto out_complete = [&] {
    ASSERT_TRUE(fs::is_directory(work() / "out")) << "no output folder after the kill";
    EXPECT_EQ(listing(work() / "out"), out_listing);
    EXPECT_NO_THROW(nlohmann::json::parse(read_text(work() / "out" / "report.json")));
  };
  kill_everywhere(assess_args, assess_args, "out", kFolderStages, assess_s, 4, out_complete);
}

/// `args` run with every file it writes limited to `blocks` (the shell's `ulimit -f`; SIGXFSZ ignored, so a write
/// past the limit fails as on a full disk, with EFBIG in place of ENOSPC).
RunResult run_with_file_limit(const std::vector<std::string>& args, const fs::path& workdir, const fs::path& capture, long blocks) {
  std::vector<std::string> sh{"-c", "trap '' XFSZ; ulimit -f " + std::to_string(blocks) + "; exec \"$0\" \"$@\"", clearfit_exe().string()};
  sh.insert(sh.end(), args.begin(), args.end());
  return run_clearfit(sh, workdir, capture, 120, "/bin/sh");
}

/// The largest file under `dir`, bytes.
std::uintmax_t largest_file(const fs::path& dir) {
  std::uintmax_t most = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) most = std::max(most, e.file_size());
  return most;
}

// A write that fails (a full disk; here a file size limit, which fails the same writes) is an error naming the
// file and the reason, exit 2, and the previous output stays whole in place, with nothing left beside it. FFV1
// and MJPG are written by OpenCV's writer, which reports no failed write: a cut-short FFV1 file once ended a run
// with exit 0 (its videos 6 MB each, 29 of their 120 frames), so its files are counted back.
TEST_F(CrashSafety, AFullDiskIsAClearErrorAndTheOldOutputStays) {
  const std::vector<std::string> sim_old{"simulate", "scene.yaml", "--out", "sim", "--seed", "3", "--quiet"};
  timed_run(sim_old);
  const auto sim_listing = listing(work() / "sim");
  const long half = static_cast<long>(largest_file(work() / "sim") / 2048);  // blocks of 512 or 1024 bytes: under the largest file
  for (const std::string format : {"huffyuv", "ffv1", "png"})
    for (const long blocks : {1L, half}) {
      SCOPED_TRACE(format + ", files limited to " + std::to_string(blocks) + " blocks");
      const RunResult r = run_with_file_limit({"simulate", "scene.yaml", "--out", "sim", "--seed", "4", "--quiet", "--format", format},
                                              work(), root() / "capture", blocks);
      EXPECT_EQ(r.exit_code, 2) << r;
      EXPECT_NE(r.err.find("free space on its disk"), std::string::npos) << r;
      EXPECT_NE(r.err.find("sim"), std::string::npos) << r;
      EXPECT_EQ(listing(work() / "sim"), sim_listing);
      EXPECT_EQ(leftovers(work(), "sim"), std::vector<std::string>{});
    }
  const std::vector<std::string> assess_args{"assess", "scene.yaml", "--quiet"};
  timed_run(assess_args);
  const auto out_listing = listing(work() / "out");
  const long out_half = static_cast<long>(largest_file(work() / "out") / 2048);
  for (const long blocks : {1L, out_half}) {
    SCOPED_TRACE("assess, files limited to " + std::to_string(blocks) + " blocks");
    const RunResult r = run_with_file_limit(assess_args, work(), root() / "capture", blocks);
    EXPECT_EQ(r.exit_code, 2) << r;
    EXPECT_NE(r.err.find("writing failed: File too large"), std::string::npos) << r;
    EXPECT_NE(r.err.find("free space on its disk"), std::string::npos) << r;
    EXPECT_EQ(listing(work() / "out"), out_listing);
    EXPECT_EQ(leftovers(work(), "out"), std::vector<std::string>{});
  }
}

TEST_F(CrashSafety, CalibrateAlwaysLeavesAWholeModel) {
  const CalibrationGrid grid{8, 6, 20};
  SyntheticViewsOptions o;
  o.views = 10;
  o.noise_px = 0.2;
  CameraModel lens;
  lens.lensmodel = "LENSMODEL_OPENCV4";
  lens.width = 640, lens.height = 480;
  lens.intrinsics = {500, 502, 320.5, 239.5, -0.1, 0.02, 0.001, -0.001};
  o.seed = 5;
  write_corners_levels_vnl(synthesize_views(lens, grid, o), work() / "a.vnl");
  o.seed = 6;
  write_corners_levels_vnl(synthesize_views(lens, grid, o), work() / "b.vnl");
  auto args = [](const char* corners) {
    return std::vector<std::string>{"calibrate", "--grid", "8", "6", "--spacing-mm", "20", "--corners", corners, "--imagersize",
                                    "640", "480", "--lensmodel", "LENSMODEL_OPENCV4", "--out", "cam2.cameramodel"};
  };
  const double s = timed_run(args("a.vnl"));
  const auto old_model = read_cameramodel(work() / "cam2.cameramodel").intrinsics;
  timed_run(args("b.vnl"));
  const auto new_model = read_cameramodel(work() / "cam2.cameramodel").intrinsics;
  ASSERT_NE(old_model, new_model);
  auto complete = [&] {
    ASSERT_TRUE(fs::exists(work() / "cam2.cameramodel"));
    const auto m = read_cameramodel(work() / "cam2.cameramodel").intrinsics;
    EXPECT_TRUE(m == old_model || m == new_model);
  };
  kill_everywhere(args("b.vnl"), args("a.vnl"), "cam2.cameramodel", {"file-written"}, s, 6, complete);
}

}  // namespace
}  // namespace clearfit::cli_test
