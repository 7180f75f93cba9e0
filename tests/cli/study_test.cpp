// clearfit study end to end: a small study (two simulated trials that run, one
// whose capture is missing, one naming an unknown participant) run on a local
// pool, killed and resumed, its failures listed without stopping the rest; a participant
// without calibration where kPa is asked, a capture too short for the windows and a
// duplicate trial id, each failing its trial alone with its message; and
// the same study as a Slurm job array on a one-node cluster started on
// localhost by the test (slurmctld + slurmd + munged with a private key and
// socket), which must give the same tables.
#include "cli_support.hpp"
#include "shared_fixture.hpp"

#include <nlohmann/json.hpp>

#include <signal.h>

#include <fstream>

namespace clearfit::cli_test {
namespace {

const fs::path kWristband = fs::path(CLEARFIT_SAMPLES_DIR) / "wristband";

class StudyCli : public CliTest {
 protected:
  /// Two simulated captures (seeds 11 and 12) and the wearer's calibration, shared by the suite (made once for
  /// every test process: shared_fixture.hpp).
  static fs::path data() {
    static const fs::path dir = [] {
      auto sim = [](const char* seed) {
        return "mesh: " + (kWristband / "wristband.obj").string() + "\ncontact: {group: contact}\ncamera: " +
               (kWristband / "camera.cameramodel").string() + "\nmap: {mode: adaptive}\nsimulation:\n  seed: " + seed +
               "\n  format: huffyuv\n  scale: 0.25\n  timeline: {fps: 30, baseline_s: 1.5, press_s: 2}\n"
               "  pressure:\n    texel_mm: 0.1\n    sources:\n"
               "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
               "  presses: {diameters_mm: [3], levels: 9, repetitions: 2}\n";
      };
      const std::string scene = "mesh: " + (kWristband / "wristband.obj").string() +
                                "\ncontact: {group: contact}\ncamera: captures-11/camera.cameramodel\n"
                                "map: {mode: adaptive}\noutputs: {texel_mm: 0.1}\ncaptures: {window_frames: 30}\n";
      return shared_fixture("study-data", sim("11") + sim("12") + scene, {kWristband / "wristband.obj", kWristband / "camera.cameramodel"},
                            [&](const fs::path& d) {
        for (const char* seed : {"11", "12"}) {
          write_text(d / "sim.yaml", sim(seed));
          const RunResult r = run_clearfit({"simulate", "sim.yaml", "--out", std::string("captures-") + seed, "--quiet", "--no-cache"}, d, d, 300);
          if (r.exit_code != 0) throw std::runtime_error("simulate failed:\n" + r.err);
        }
        const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "captures-11/presses.csv", "--person", "wearer-1",
                                            "--camera", "captures-11/camera.cameramodel", "--out", "calibration.json"}, d, d, 60);
        if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
        write_text(d / "scene.yaml", scene);
      });
    }();
    return dir;
  }

  fs::path manifest(const std::string& extra_trial_keys = "") {
    const fs::path d = data();
    const std::string c11 = (d / "captures-11").string(), c12 = (d / "captures-12").string();
    write_text(work() / "study.yaml",
               "study: small\nparticipants:\n  - {id: p1, person: wearer-1, calibration: " + (d / "calibration.json").string() +
                   "}\nconditions:\n  - {id: band, scene: " + (d / "scene.yaml").string() + "}\ntrials:\n"
                   "  - {id: t1, participant: p1, condition: band, baseline: " + c11 + "/baseline.mkv, worn: " + c11 + "/worn.mkv}\n"
                   "  - {id: t2, participant: p1, condition: band, baseline: " + c12 + "/baseline.mkv, worn: " + c12 + "/worn.mkv" +
                   extra_trial_keys + "}\n"
                   "  - {id: t3, participant: p1, condition: band, both: " + c11 + "/missing.mkv}\n"
                   "  - {id: t4, participant: nobody, condition: band, both: " + c11 + "/worn.mkv}\n"
                   "analysis: {pressure: true}\n");
    return work() / "study.yaml";
  }
  RunResult study(const std::vector<std::string>& args, double timeout = 240) {
    std::vector<std::string> a{"study"};
    a.insert(a.end(), args.begin(), args.end());
    return run_clearfit(a, work(), root() / "capture", timeout);
  }
  static nlohmann::json rows(const fs::path& out) {
    return nlohmann::json::parse(read_text(out / "study.json"))["trials"];
  }
  static fs::file_time_type stamp(const fs::path& out, const std::string& trial) {
    return fs::last_write_time(out / "jobs" / trial / "job.json");
  }
};

void expect_tables(const fs::path& out) {
  const auto trials = nlohmann::json::parse(read_text(out / "study.json"))["trials"];
  ASSERT_EQ(trials.size(), 4u);
  EXPECT_EQ(trials[0]["status"], "ok") << trials[0];
  EXPECT_EQ(trials[1]["status"], "ok") << trials[1];
  EXPECT_EQ(trials[2]["status"], "failed");
  EXPECT_NE(trials[2]["error"].get<std::string>().find("missing.mkv"), std::string::npos) << trials[2];
  EXPECT_EQ(trials[3]["status"], "failed");
  EXPECT_NE(trials[3]["error"].get<std::string>().find("no participant has the id 'nobody'"), std::string::npos) << trials[3];
  for (int i : {0, 1}) {
    EXPECT_GT(trials[i]["peak_kpa"].get<double>(), 5.0) << trials[i];
    EXPECT_GE(trials[i]["hotspots"].get<int>(), 1) << trials[i];
  }
  for (const char* f : {"trials.csv", "participants.csv", "conditions.csv", "profiles.csv"}) EXPECT_TRUE(fs::exists(out / f)) << f;
}

TEST_F(StudyCli, RunsEveryTrialListsFailuresAndResumes) {
  manifest();
  const RunResult first = study({"run", "study.yaml", "--out", "out", "--jobs", "2", "--quiet"});
  EXPECT_EQ(first.exit_code, 2) << first;  // two trials failed; the others are in the tables
  EXPECT_NE(first.err.find("trial t3 failed"), std::string::npos) << first;
  expect_tables(work() / "out");
  const auto t1 = stamp(work() / "out", "t1"), t2 = stamp(work() / "out", "t2");

  const RunResult again = study({"run", "study.yaml", "--out", "out", "--jobs", "2", "--quiet"});
  EXPECT_EQ(again.exit_code, 2) << again;
  EXPECT_EQ(stamp(work() / "out", "t1"), t1) << "a finished job ran again";
  EXPECT_EQ(stamp(work() / "out", "t2"), t2) << "a finished job ran again";

  manifest(", force_n: 0.5");  // t2's entry changed: its hash differs, it runs again; t1 does not
  const RunResult changed = study({"run", "study.yaml", "--out", "out", "--jobs", "1", "--quiet"});
  EXPECT_EQ(changed.exit_code, 2) << changed;
  EXPECT_EQ(stamp(work() / "out", "t1"), t1);
  EXPECT_NE(stamp(work() / "out", "t2"), t2);
  EXPECT_EQ(rows(work() / "out")[1]["force_n"].get<double>(), 0.5);
}

TEST_F(StudyCli, ResumesAfterBeingKilled) {
  manifest();
  // Start the study in its own process group, kill the whole group once t1 is done.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setpgid(0, 0);
    if (chdir(work().c_str()) != 0) _exit(127);
    const int devnull = open("/dev/null", O_WRONLY);
    dup2(devnull, 1);
    dup2(devnull, 2);
    execl(clearfit_exe().c_str(), "clearfit", "study", "run", "study.yaml", "--out", "out", "--jobs", "1", "--quiet", nullptr);
    _exit(127);
  }
  setpgid(pid, pid);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(180);
  while (!fs::exists(work() / "out" / "jobs" / "t1" / "job.json") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  kill(-pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(fs::exists(work() / "out" / "jobs" / "t1" / "job.json")) << "t1 did not finish in time";
  EXPECT_FALSE(fs::exists(work() / "out" / "study.json")) << "killed before the tables";
  const auto t1 = stamp(work() / "out", "t1");
  const RunResult resumed = study({"run", "study.yaml", "--out", "out", "--jobs", "2", "--quiet"});
  EXPECT_EQ(resumed.exit_code, 2) << resumed;
  EXPECT_EQ(stamp(work() / "out", "t1"), t1) << "t1 was finished before the kill and must be skipped";
  expect_tables(work() / "out");
}

TEST_F(StudyCli, BadManifestIsRefusedWithItsLine) {
  write_text(work() / "study.yaml", "participants:\n  - {id: p1}\nconditions:\n  - {id: c, scene: s.yaml}\n"
                                    "trials:\n  - {id: t, participant: p1, condition: c, baseline: a.mkv}\n");
  expect_input_error({"study", "run", "study.yaml", "--out", "out"}, {"study.yaml", "line 6", "either baseline and worn"});
  write_text(work() / "study.yaml", "participants:\n  - {id: p1}\n  - {id: p1}\nconditions:\n  - {id: c, scene: s.yaml}\n"
                                    "trials:\n  - {id: t, participant: p1, condition: c, both: a.mkv}\n");
  expect_input_error({"study", "run", "study.yaml", "--out", "out"}, {"study.yaml", "line 3", "duplicate id 'p1'"});
  write_text(work() / "study.yaml", "participants:\n  - {id: p1}\nconditions:\n  - {id: c, scene: s.yaml}\n"
                                    "trials:\n  - {id: t, participant: p1, condition: c, both: a.mkv, forse_n: 3}\n");
  expect_input_error({"study", "run", "study.yaml", "--out", "out"}, {"study.yaml", "line 6", "trials[0].forse_n", "unknown key"});
  expect_input_error({"study", "job", "study.yaml", "--out", "out", "--index", "1"}, {"study.yaml", "study.yaml"});
}

TEST_F(StudyCli, TrialsBadInputsFailAloneWithTheirMessage) {
  // A participant without calibration where kPa is asked, a capture too short for the
  // condition's windows and a duplicate trial id: each trial listed with its message, exit 2.
  const fs::path d = data();
  const std::string c11 = (d / "captures-11").string();
  {
    std::string scene = read_text(d / "scene.yaml");
    const std::string from = "window_frames: 30", to = "window_frames: 200";
    scene.replace(scene.find(from), from.size(), to);
    const std::string cam = "camera: captures-11/", abs_cam = "camera: " + c11 + "/";
    scene.replace(scene.find(cam), cam.size(), abs_cam);
    write_text(work() / "long-window.yaml", scene);
  }
  write_text(work() / "study.yaml",
             "study: bad\nparticipants:\n  - {id: p1, person: wearer-1, calibration: " + (d / "calibration.json").string() +
                 "}\n  - {id: p2}\nconditions:\n  - {id: band, scene: " + (d / "scene.yaml").string() +
                 "}\n  - {id: long, scene: long-window.yaml}\ntrials:\n"
                 "  - {id: t1, participant: p2, condition: band, baseline: " + c11 + "/baseline.mkv, worn: " + c11 + "/worn.mkv}\n"
                 "  - {id: t2, participant: p1, condition: long, baseline: " + c11 + "/baseline.mkv, worn: " + c11 + "/worn.mkv}\n"
                 "  - {id: t2, participant: p1, condition: band, baseline: " + c11 + "/baseline.mkv, worn: " + c11 + "/worn.mkv}\n"
                 "analysis: {pressure: true}\n");
  const RunResult r = study({"run", "study.yaml", "--out", "out", "--jobs", "1", "--quiet"});
  EXPECT_EQ(r.exit_code, 2) << r;
  const auto trials = rows(work() / "out");
  ASSERT_EQ(trials.size(), 3u) << trials.dump(1);
  const char* expected[] = {"p2' has no calibration", "fewer than the 200 asked for", "duplicate trial id 't2'"};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(trials[i]["status"], "failed") << trials[i];
    EXPECT_NE(trials[i]["error"].get<std::string>().find(expected[i]), std::string::npos) << trials[i];
  }
  for (const char* id : {"t1", "t2"}) EXPECT_NE(r.err.find(std::string("trial ") + id + " failed"), std::string::npos) << r;
}

/// A one-node Slurm cluster on localhost with its own munge key and socket.
class LocalSlurm {
 public:
  /// `dir` holds its state, or /tmp/clearfit-slurm-PID when `dir` is long: munge's and slurmstepd's Unix sockets
  /// live there, and a socket's path holds at most 107 characters.
  explicit LocalSlurm(const fs::path& dir)
      : dir_(dir.string().size() <= 60 ? dir : fs::path("/tmp") / ("clearfit-slurm-" + std::to_string(::getpid()))), own_(dir_ != dir) {
    fs::create_directories(dir_ / "state");
    fs::create_directories(dir_ / "spool");
    fs::permissions(dir_, fs::perms::owner_all);
    {
      std::ofstream key(dir_ / "munge.key", std::ios::binary);
      for (int i = 0; i < 1024; ++i) key.put(static_cast<char>((i * 2654435761u) >> 13));
    }
    fs::permissions(dir_ / "munge.key", fs::perms::owner_read | fs::perms::owner_write);
    const int port = 20000 + (::getpid() % 5000) * 2;
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    const std::string d = dir_.string();
    write_text(dir_ / "slurm.conf",
               "ClusterName=clearfit\nSlurmctldHost=" + std::string(host) + "(127.0.0.1)\nSlurmUser=root\nSlurmdUser=root\n"
               "AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket=" + d + "/munge.socket\n"
               "StateSaveLocation=" + d + "/state\nSlurmdSpoolDir=" + d + "/spool\nSlurmctldPidFile=" + d +
               "/slurmctld.pid\nSlurmdPidFile=" + d + "/slurmd.pid\nSlurmctldLogFile=" + d + "/slurmctld.log\nSlurmdLogFile=" + d +
               "/slurmd.log\nSlurmctldPort=" + std::to_string(port) + "\nSlurmdPort=" + std::to_string(port + 1) +
               "\nProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n"
               "AccountingStorageType=accounting_storage/none\nJobCompType=jobcomp/none\nSchedulerType=sched/builtin\n"
               "SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\nReturnToService=2\nMpiDefault=none\n"
               "NodeName=" + std::string(host) + " NodeAddr=127.0.0.1 CPUs=2 RealMemory=8000 State=UNKNOWN\n"
               "PartitionName=local Nodes=" + std::string(host) + " Default=YES MaxTime=INFINITE State=UP\n");
    setenv("SLURM_CONF", (dir_ / "slurm.conf").c_str(), 1);
    started_ = sh("/usr/sbin/munged --force --socket=" + d + "/munge.socket --key-file=" + d + "/munge.key --pid-file=" + d +
                  "/munged.pid --log-file=" + d + "/munged.log --seed-file=" + d + "/munge.seed") &&
               sh("/usr/sbin/slurmctld -c") && sh("/usr/sbin/slurmd");
    for (int i = 0; started_ && i < 100 && !ready(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    started_ = started_ && ready();
  }
  ~LocalSlurm() {
    for (const char* daemon : {"slurmd", "slurmctld", "munged"}) {
      std::ifstream pid_file(dir_ / (std::string(daemon) + ".pid"));
      pid_t pid = 0;
      if (pid_file >> pid && pid > 0) kill(pid, SIGTERM);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    unsetenv("SLURM_CONF");
    std::error_code ignored;
    if (own_) fs::remove_all(dir_, ignored);
  }
  bool started() const { return started_; }
  std::string logs() const {
    return read_text(dir_ / "slurmctld.log") + read_text(dir_ / "slurmd.log") + read_text(dir_ / "munged.log");
  }

 private:
  static bool sh(const std::string& command) { return std::system((command + " > /dev/null 2>&1").c_str()) == 0; }
  bool ready() const { return sh("sinfo -h -o %T | grep -q idle"); }
  fs::path dir_;
  bool own_ = false;  ///< dir_ is not the caller's folder (removed at the end)
  bool started_ = false;
};

TEST_F(StudyCli, SlurmArrayOnLocalhostGivesTheSameTables) {
  manifest();
  LocalSlurm slurm(root() / "slurm");
  if (!slurm.started()) {
    std::cerr << "\n*** SKIPPED: could not start a local Slurm cluster (slurm-wlm and munge; scripts/bootstrap.sh installs them) ***\n"
              << slurm.logs() << "\n";
    GTEST_SKIP() << "no local Slurm cluster";
  }
  const RunResult submitted = study({"slurm", "study.yaml", "--out", "array", "--mem-mb", "1000", "--submit"});
  ASSERT_EQ(submitted.exit_code, 0) << submitted;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  while (!fs::exists(work() / "array" / "study.json") && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  ASSERT_TRUE(fs::exists(work() / "array" / "study.json")) << "the array's reduce step did not finish\n" << slurm.logs();
  const RunResult local = study({"run", "study.yaml", "--out", "local", "--jobs", "2", "--quiet"});
  EXPECT_EQ(local.exit_code, 2) << local;
  expect_tables(work() / "array");
  auto a = rows(work() / "array"), b = rows(work() / "local");
  for (auto* t : {&a, &b})
    for (auto& row : *t) row.erase("seconds"), row.erase("max_rss_mb");
  EXPECT_EQ(a, b);
  EXPECT_EQ(read_text(work() / "array" / "participants.csv"), read_text(work() / "local" / "participants.csv"));
  EXPECT_EQ(read_text(work() / "array" / "profiles.csv"), read_text(work() / "local" / "profiles.csv"));
}

}  // namespace
}  // namespace clearfit::cli_test
