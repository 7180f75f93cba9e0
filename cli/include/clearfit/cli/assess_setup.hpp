#pragma once
// What `clearfit assess` and `clearfit-bench assess` share: the assessment's
// options (the scene's sections, scene.hpp) and everything it needs before
// reading the captures (the part, its map and inverse map, the calibration).
#include <clearfit/cli/part_setup.hpp>
#include <clearfit/cli/scene.hpp>
#include <clearfit/fit/assessment.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/refraction/baseline_map.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace clearfit::cli {

/// The assess command line: the scene file and its options, the cache, the output switches.
struct AssessOpts {
  std::string scene_file;
  Scene scene;
  SceneFields::Options options;
  CacheOptions cache;
  bool no_html = false, quiet = false;
};

/// Registers the scene's part, map, outputs, captures, calibration and assess
/// options, --cache/--no-cache, --no-html and --quiet.
void add_assess_options(CLI::App& sub, AssessOpts& o);

/// Everything an assessment needs before reading the captures.
struct Prepared {
  std::unique_ptr<LoadedPart> part;
  RefractionMap map;
  InverseMap inverse;
  InverseMapOptions inverse_options;
  std::unique_ptr<BaselineRays> baseline_rays;  ///< held / absent: the not-worn capture's own rays (baseline_map.hpp)
  BaselinePart baseline_part = BaselinePart::touching;
  std::optional<double> baseline_gap_mm;        ///< nullopt: estimated (auto)
  std::optional<PressureCalibration> calibration;
  std::vector<std::string> notes;
  std::vector<std::string> warnings;  ///< about the scene's settings, for the assessment's warnings (report.json)
  /// Where the skin's blur (AssessSection::skin_blur_mm) came from: "command line", "scene file", "calibration" or "default".
  std::string skin_blur_from = "default";
  std::string cache;
  AssessmentOptions options;
  CaptureSources sources;
  AssessmentScene view() const {
    return {&part->mesh, &part->contact, &*part->chart, &part->camera, part->cam_from_part, &map, &inverse,
            part->pose_covariance ? &*part->pose_covariance : nullptr, baseline_part, baseline_gap_mm, baseline_rays.get(),
            inverse_options, part->projection_uncertainty ? &*part->projection_uncertainty : nullptr};
  }
};

/// Reads the scene (the command line wins), checks the options, loads and
/// traces the part, reads the calibration. Progress on stderr unless quiet.
std::unique_ptr<Prepared> prepare(AssessOpts& o);

}  // namespace clearfit::cli
