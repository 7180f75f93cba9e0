// report.html in a real browser: tests/tools/check_report.mjs drives Debian's
// chromium through playwright-core (web/node_modules) over file:// and checks
// no console errors, no network, every 3D view renders (screenshot not blank),
// the hotspot table equals report.json and a marker click shows its numbers.
// Needs /usr/bin/chromium (apt: chromium), node and web/node_modules (npm ci
// in web/); the tests FAIL, naming what is missing, when they are not there.
#include <clearfit/reports/report_html.hpp>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <iterator>

#include "report_fixture.hpp"

// Declared by tiny_gltf.h only in its implementation part; libtinygltf.so defines it.
namespace tinygltf {
std::string base64_decode(std::string const& encoded);
}

namespace clearfit {
namespace {

namespace fs = std::filesystem;
using report_test::FixtureOptions;
using report_test::make_assessment_folder;

const fs::path kSourceDir = fs::path(CLEARFIT_TEST_DATA_DIR).parent_path().parent_path();

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

struct Outcome {
  int exit_code = -1;
  std::string output;
};

// Runs a command through the shell, capturing stdout and stderr together.
Outcome run(const std::string& command) {
  Outcome o;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return o;
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, pipe)) o.output.append(buf, n);
  const int status = ::pclose(pipe);
  o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return o;
}

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

class ReportBrowser : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / (std::string("clearfit_report_browser_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override {
    if (!HasFailure() && env_or("CLEARFIT_KEEP_TEST_OUTPUT", "").empty()) fs::remove_all(dir_);
    else std::cerr << "kept " << dir_ << " (report.html, screenshots/)\n";
  }

  // Writes the fixture and its report.html, then checks the page in chromium.
  void check(const FixtureOptions& o, double timeout_s = 60) {
    const fs::path chromium = env_or("CLEARFIT_CHROMIUM", "/usr/bin/chromium");
    const fs::path node = env_or("CLEARFIT_NODE", "node");
    const fs::path web = env_or("CLEARFIT_WEB_DIR", (kSourceDir / "web").string());
    ASSERT_TRUE(fs::exists(chromium)) << chromium << " is missing: install it with `apt-get install -y chromium` "
                                         "(scripts/bootstrap.sh does) or set CLEARFIT_CHROMIUM";
    ASSERT_TRUE(fs::exists(web / "node_modules" / "playwright-core" / "package.json"))
        << web / "node_modules/playwright-core" << " is missing: run `npm ci` in " << web;
    ASSERT_EQ(run(node.string() + " --version").exit_code, 0) << "node is missing: install Node.js 20 or set CLEARFIT_NODE";
    make_assessment_folder(dir_, o);
    const auto t0 = std::chrono::steady_clock::now();
    const auto result = reports::write_report_html(dir_);
    const double gen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const Outcome out = run("CLEARFIT_WEB_DIR=" + quoted(web) + " CLEARFIT_CHROMIUM=" + quoted(chromium) + " " + quoted(node) + " " +
                            quoted(kSourceDir / "tests/tools/check_report.mjs") + " " + quoted(result.html) +
                            " --screenshot-dir " + quoted(dir_ / "screenshots") + " --timeout-ms " +
                            std::to_string(static_cast<int>(timeout_s * 1000)));
    std::cout << "report.html " << fs::file_size(result.html) / 1024 << " KiB, written in " << gen_s << " s; browser: " << out.output;
    for (const auto& n : result.notes) std::cout << "note: " << n << "\n";
    EXPECT_EQ(out.exit_code, 0) << out.output;

    // The models embedded in the page pass the Khronos glTF validator too.
    std::ifstream in(result.html, std::ios::binary);
    const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string open = "class=\"clearfit-model\" data-view=\"";
    for (std::size_t a = html.find(open); a != std::string::npos; a = html.find(open, a + 1)) {
      const std::size_t key_end = html.find('"', a + open.size());
      const std::string key = html.substr(a + open.size(), key_end - a - open.size());
      const std::size_t start = key_end + 2, end = html.find("</script>", start);
      const fs::path glb = dir_ / ("view_" + key + ".glb");
      std::ofstream(glb, std::ios::binary) << tinygltf::base64_decode(html.substr(start, end - start));
      const Outcome v = run(quoted(node) + " " + quoted(kSourceDir / "tests/tools/validate_gltf.mjs") + " " + quoted(glb));
      EXPECT_EQ(v.exit_code, 0) << "view " << key << ": " << v.output.substr(0, 3000);
    }
  }
  fs::path dir_;
};

TEST_F(ReportBrowser, CalibratedReportLoadsRendersAndMatches) { check({}); }

TEST_F(ReportBrowser, SignalOnlyReport) {
  FixtureOptions o;
  o.calibrated = false;
  check(o);
}

TEST_F(ReportBrowser, NoHotspots) {
  FixtureOptions o;
  o.bumps = {{0, 0, 3, 3}};
  check(o);
}

TEST_F(ReportBrowser, InjectedMarkupStaysText) {
  FixtureOptions o;
  o.odd_text = "<script>alert(\"x\")</script><img src=x onerror=alert(1)>";
  check(o);
}

// A part of 1,000,000 triangles (slab with 500 quads per edge): the page still loads and renders.
TEST_F(ReportBrowser, MillionTriangles) {
  FixtureOptions o;
  o.n = 500;
  check(o, 180);
}

}  // namespace
}  // namespace clearfit
