// The study manifest's reader on bad input: every input kept in
// fuzz/regressions/manifest/ is read or refused with an InputError naming the file.
#include <clearfit/error.hpp>
#include <clearfit/study/manifest.hpp>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;

TEST(Manifest, AListOrMapAsKeyIsRefusedWithItsLine) {
  const fs::path p = fs::temp_directory_path() / ("clearfit_manifest_" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << "study: s\n[participants]: 1\n";
  try {
    read_manifest(p);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), p.string());
    EXPECT_NE(std::string(e.what()).find("line 2: a key is a list, a map or empty"), std::string::npos) << e.what();
  }
  fs::remove(p);
}

TEST(Manifest, FuzzRegressionInputsAreReadOrRefused) {
  const fs::path root = fs::path(CLEARFIT_TEST_DATA_DIR) / ".." / ".." / "fuzz" / "regressions" / "manifest";
  int inputs = 0;
  for (const auto& entry : fs::directory_iterator(root)) {
    SCOPED_TRACE(entry.path().string());
    ++inputs;
    try {
      read_manifest(entry.path());
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), entry.path().string()) << e.what();
    }
  }
  EXPECT_GT(inputs, 0);
}

}  // namespace
}  // namespace clearfit::study
