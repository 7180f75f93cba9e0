// End-to-end tests of the clearfit front end itself: --version, --help, and
// command lines it cannot parse (exit 2 with the usage).
#include "cli_support.hpp"

#include <regex>

namespace clearfit::cli_test {
namespace {

// The version from the project() call of the top CMakeLists.txt.
std::string project_version() {
  const std::string cmake = read_text(fs::path(CLEARFIT_SAMPLES_DIR) / ".." / "CMakeLists.txt");
  std::smatch m;
  if (!std::regex_search(cmake, m, std::regex(R"(project\(clearfit\s+VERSION\s+([0-9.]+))")))
    throw std::runtime_error("no project(clearfit VERSION ...) in CMakeLists.txt");
  return m[1];
}

class Usage : public CliTest {};

TEST_F(Usage, VersionPrintsTheProjectVersion) {
  const RunResult r = run({"--version"});
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(r.out, "clearfit " + project_version() + "\n") << r;
}

TEST_F(Usage, HelpListsTheCommands) {
  const RunResult r = run({"--help"});
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("mesh-info"), std::string::npos) << r;
  EXPECT_NE(r.out.find("map"), std::string::npos) << r;
  const RunResult m = run({"map", "--help"});
  EXPECT_EQ(m.exit_code, 0) << m;
  for (const char* option : {"--mesh", "--camera", "--pose", "--ior", "--out", "--stats", "--contact-group"})
    EXPECT_NE(m.out.find(option), std::string::npos) << option << "\n" << m;
}

// Both the message and the usage (what the commands are) must reach the user.
void expect_usage_error(const RunResult& r, const std::string& complaint) {
  EXPECT_EQ(r.exit_code, 2) << r;
  const std::string all = r.out + r.err;
  EXPECT_NE(all.find(complaint), std::string::npos) << "should say '" << complaint << "'\n" << r;
  EXPECT_NE(all.find("mesh-info"), std::string::npos) << "should show the usage with the commands\n" << r;
  EXPECT_NE(all.find("map"), std::string::npos) << r;
}

TEST_F(Usage, NoSubcommand) {
  expect_usage_error(run({}), "subcommand");
}

TEST_F(Usage, UnknownSubcommand) {
  const RunResult r = run({"frobnicate"});
  expect_usage_error(r, "frobnicate");
}

TEST_F(Usage, UnknownOption) {
  expect_usage_error(run({"--frobnicate"}), "--frobnicate");
  const RunResult r = run({"mesh-info", "part.obj", "--frobnicate"});
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE((r.out + r.err).find("--frobnicate"), std::string::npos) << r;
  EXPECT_NE((r.out + r.err).find("--contact-group"), std::string::npos) << "should show mesh-info's usage\n" << r;
}

TEST_F(Usage, ConflictingContactOptions) {
  const RunResult r = run({"mesh-info", "part.obj", "--contact-group", "a", "--contact-faces", "f.txt"});
  EXPECT_EQ(r.exit_code, 2) << r;
  EXPECT_NE(r.err.find("--contact-group"), std::string::npos) << r;
  EXPECT_TRUE(listing(work()).empty());
}

// --config FILE: a [COMMAND] section's keys are that command's long options; the command line wins;
// a key that names no option is refused with exit 2, naming the file and the key.
TEST_F(Usage, ConfigFileGivesOptionsTheCommandLineWins) {
  const std::string mesh = (fs::path(CLEARFIT_SAMPLES_DIR) / "wristband" / "wristband.obj").string();
  write_text(work() / "c.toml", "# options\n[mesh-info]\njson = true\ncontact-group = \"outer\"\n");
  const RunResult from_file = run({"--config", "c.toml", "mesh-info", mesh});
  ASSERT_EQ(from_file.exit_code, 0) << from_file;
  EXPECT_NE(from_file.out.find("\"chosen_by\": \"group 'outer'\""), std::string::npos) << from_file;
  const RunResult wins = run({"--config", "c.toml", "mesh-info", mesh, "--contact-group", "contact"});
  ASSERT_EQ(wins.exit_code, 0) << wins;
  EXPECT_NE(wins.out.find("\"chosen_by\": \"group 'contact'\""), std::string::npos) << wins;
  write_text(work() / "typo.toml", "[mesh-info]\njsn = true\n");
  const RunResult typo = run({"--config", "typo.toml", "mesh-info", mesh});
  EXPECT_EQ(typo.exit_code, 2) << typo;
  EXPECT_NE(typo.err.find("typo.toml"), std::string::npos) << typo;
  EXPECT_NE(typo.err.find("mesh-info.jsn"), std::string::npos) << typo;
}

// The benchmarks are a separate program (clearfit-bench), not subcommands of the shipped clearfit.
TEST_F(Usage, BenchmarksAreASeparateProgram) {
  const RunResult r = run({"--help"});
  EXPECT_EQ(r.out.find("bench"), std::string::npos) << r;
  const fs::path bench = CLEARFIT_BENCH_EXE;
  const RunResult h = run_clearfit({"--help"}, work(), work(), 30, bench);
  EXPECT_EQ(h.exit_code, 0) << h;
  for (const char* command : {"map", "assess"}) EXPECT_NE(h.out.find(command), std::string::npos) << command << "\n" << h;
  const RunResult m = run_clearfit({"map", "--sizes", "64x48", "--shapes", "slab", "--modes", "exact,grid:8", "--repeat", "1"},
                                   work(), work(), 60, bench);
  EXPECT_EQ(m.exit_code, 0) << m;
  EXPECT_NE(m.out.find("grid:8"), std::string::npos) << m;
  const RunResult bad = run_clearfit({"assess", "missing.yaml"}, work(), work(), 30, bench);
  EXPECT_EQ(bad.exit_code, 2) << bad;
  EXPECT_NE(bad.err.find("clearfit-bench: error: missing.yaml"), std::string::npos) << bad;
}

}  // namespace
}  // namespace clearfit::cli_test
