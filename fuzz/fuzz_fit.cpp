// libFuzzer targets: the fit readers (see fuzz_main.hpp).
#include "fuzz_main.hpp"

#include <clearfit/fit/force_log.hpp>
#include <clearfit/fit/pressure_model.hpp>

namespace clearfit::fuzz {

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> r = {
      {"calibration", {".json", [](const fs::path& p) { read_pressure_calibration(p); }}},
      {"presses", {".csv", [](const fs::path& p) {
                     std::vector<std::string> notes;
                     read_presses_csv(p, &notes);
                   }}},
      {"force_log", {".csv", [](const fs::path& p) { read_force_log(p); }}},
  };
  return r;
}

}  // namespace clearfit::fuzz
