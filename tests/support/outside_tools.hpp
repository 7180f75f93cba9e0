#pragma once
// Cross-checks against outside tools (/usr/bin/python3 with mrcal's Python module or NumPy).
// scripts/bootstrap.sh installs them (python3-mrcal, python3-numpy) and CI runs it, so a missing tool is a broken
// install: the test fails, naming what is missing and how to install it. On a machine set up by hand,
// CLEARFIT_ALLOW_MISSING_TOOLS=1 lets these tests skip instead.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <map>
#include <string>

namespace clearfit::test {

/// True when CLEARFIT_ALLOW_MISSING_TOOLS=1: a missing outside tool skips its cross-check instead of failing it.
inline bool missing_tools_allowed() {
  const char* v = std::getenv("CLEARFIT_ALLOW_MISSING_TOOLS");
  return v != nullptr && std::strcmp(v, "1") == 0;
}

/// True when /usr/bin/python3 imports every module in `modules` (space-separated, e.g. "mrcal" or "numpy";
/// "sys" asks only for the interpreter). Otherwise false, after recording a test failure that names the modules and
/// the Debian package `package` that brings them, unless missing tools are allowed. Asked once per program and list.
inline bool python_ready(const std::string& modules, const std::string& package) {
  static std::map<std::string, bool> known;
  auto [it, fresh] = known.try_emplace(modules, false);
  if (fresh) {
    std::string imports;
    for (char c : modules) imports += c == ' ' ? ',' : c;
    it->second = std::system(("/usr/bin/python3 -c 'import " + imports + "' >/dev/null 2>&1").c_str()) == 0;
  }
  if (!it->second && !missing_tools_allowed())
    ADD_FAILURE() << "/usr/bin/python3 cannot import " << modules << ", which this cross-check needs: install it with "
                  << "`apt-get install -y " << package << "` (scripts/bootstrap.sh deps does), or set "
                  << "CLEARFIT_ALLOW_MISSING_TOOLS=1 to skip the cross-checks that need outside tools";
  return it->second;
}

}  // namespace clearfit::test

/// Ends the current test when /usr/bin/python3 cannot import `modules`: failed (python_ready's message) or, with
/// CLEARFIT_ALLOW_MISSING_TOOLS=1, skipped.
#define CLEARFIT_REQUIRE_PYTHON(modules, package)                                  \
  do {                                                                              \
    if (!::clearfit::test::python_ready(modules, package))                          \
      GTEST_SKIP() << "/usr/bin/python3 cannot import " << (modules);            \
  } while (0)
