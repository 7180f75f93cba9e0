// Results that repeat: the same inputs give bit-identical outputs across runs
// and across thread counts. simulate, map and assess each run three times on
// the small slab part: twice on every CPU the test may use and once on a single
// CPU (the child inherits the test's CPU affinity, and oneTBB sizes its thread
// pool from it). Every file of the outputs must be byte for byte the same, but
// the JSON files (report.json, truth.json), compared as JSON without the keys
// that hold the clock: when it ran ("created_utc") and how long it took
// ("run_time_s", "time_ms", "timings_ms").
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <sched.h>

#include <nlohmann/json.hpp>

namespace clearfit::cli_test {
namespace {

/// Runs with the process (and so the clearfit it spawns) confined to `cpus` CPUs of those it may use (0: all).
class CpuLimit {
 public:
  explicit CpuLimit(int cpus) {
    sched_getaffinity(0, sizeof(saved_), &saved_);
    if (cpus <= 0) return;
    cpu_set_t one;
    CPU_ZERO(&one);
    for (int c = 0, taken = 0; c < CPU_SETSIZE && taken < cpus; ++c)
      if (CPU_ISSET(c, &saved_)) CPU_SET(c, &one), ++taken;
    if (sched_setaffinity(0, sizeof(one), &one) != 0) throw std::runtime_error("sched_setaffinity failed");
  }
  ~CpuLimit() { sched_setaffinity(0, sizeof(saved_), &saved_); }
  CpuLimit(const CpuLimit&) = delete;
  CpuLimit& operator=(const CpuLimit&) = delete;
  static int available() {
    cpu_set_t s;
    sched_getaffinity(0, sizeof(s), &s);
    return CPU_COUNT(&s);
  }

 private:
  cpu_set_t saved_{};
};

/// Drops every key that holds the clock.
void drop_timings(nlohmann::json& j) {
  static const std::set<std::string> clock{"created_utc", "run_time_s", "time_ms", "timings_ms"};
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end();) {
      if (clock.count(it.key())) it = j.erase(it);
      else drop_timings(*it++);
    }
  } else if (j.is_array()) {
    for (auto& v : j) drop_timings(v);
  }
}

/// Every file below `dir` (relative path -> contents; JSON files without the clock).
std::map<std::string, std::string> contents(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::string text = read_text(e.path());
    if (e.path().extension() == ".json") {
      auto j = nlohmann::json::parse(text);
      drop_timings(j);
      text = j.dump(1);
    }
    files[fs::relative(e.path(), dir).string()] = std::move(text);
  }
  return files;
}

/// The files of `a` and `b` that differ (or are in one only).
std::vector<std::string> differences(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b) {
  std::vector<std::string> d;
  for (const auto& [name, text] : a)
    if (!b.count(name) || b.at(name) != text) d.push_back(name);
  for (const auto& [name, text] : b)
    if (!a.count(name)) d.push_back(name);
  return d;
}

class Repeat : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    write_slab_part(work());
    write_text(work() / "scene.yaml", slab_scene("", ", map: map.npy"));
  }
  /// Runs `args` on `cpus` CPUs (0: all) and returns the contents of `out` (a folder or a file) afterwards.
  std::map<std::string, std::string> run_on(int cpus, const std::vector<std::string>& args, const std::string& out) {
    CpuLimit limit(cpus);
    const RunResult r = run_clearfit(args, work(), root() / "capture", 300);
    EXPECT_EQ(r.exit_code, 0) << r;
    const fs::path p = work() / out;
    if (fs::is_directory(p)) return contents(p);
    return {{out, read_text(p)}};
  }
  /// Runs `args` twice on every CPU and once on one; every output must be the same.
  void expect_repeats(const std::vector<std::string>& args, const std::string& out) {
    SCOPED_TRACE(args[0]);
    const auto first = run_on(0, args, out);
    ASSERT_FALSE(first.empty());
    EXPECT_EQ(differences(first, run_on(0, args, out)), std::vector<std::string>{}) << "differ between two runs";
    if (CpuLimit::available() < 2) {
      std::cerr << "one CPU only: the thread-count comparison of " << args[0] << " is skipped\n";
      return;
    }
    EXPECT_EQ(differences(first, run_on(1, args, out)), std::vector<std::string>{})
        << "differ between " << CpuLimit::available() << " CPUs and one";
  }
};

TEST_F(Repeat, SimulateMapAndAssessGiveTheSameBytesOnAnyNumberOfThreads) {
  expect_repeats({"simulate", "scene.yaml", "--out", "sim", "--quiet"}, "sim");
  expect_repeats({"map", "--scene", "scene.yaml"}, "map.npy");
  expect_repeats({"assess", "scene.yaml", "--quiet", "--no-html"}, "out");
  const auto out = contents(work() / "out");
  int npy = 0, glb = 0;
  for (const auto& [name, text] : out) npy += name.ends_with(".npy"), glb += name.ends_with(".glb");
  EXPECT_TRUE(out.count("report.json"));
  EXPECT_GT(npy, 0);
  EXPECT_GT(glb, 0);
}

}  // namespace
}  // namespace clearfit::cli_test
