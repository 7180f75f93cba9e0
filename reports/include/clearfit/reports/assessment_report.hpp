#pragma once
// Writes an assessment's outputs into a folder (docs/assessment-outputs.md):
// heatmap.glb (+ heatmap_signal.glb when calibrated), the chart PNGs, the skin
// pictures, the chart fields as .npy, and report.json last.
#include <clearfit/fit/assessment.hpp>
#include <clearfit/geometry/normals.hpp>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace clearfit {

struct ReportInput {
  std::string role, path, sha256;
};

/// What the assessment does not know about itself: where its inputs came from.
struct AssessmentContext {
  std::string clearfit_version;
  std::string scene;                       ///< scene file path ("" if none)
  nlohmann::json options = nlohmann::json::object();  ///< every option as used
  std::vector<ReportInput> inputs;
  std::string mesh_name;
  double ior = 0, medium_ior = 0;
  std::string fast_path;
  std::string chart_method;
  std::string pose_source;
  std::string camera_source;
  const PressureCalibration* calibration = nullptr;
  double pressure_range_hi_kpa = 30;        ///< colour range top without a calibration range
  double run_time_s = 0;                    ///< filled by the caller before writing
};

/// The report.json document (schema clearfit.report/1).
nlohmann::json assessment_report_json(const Assessment& a, const AssessmentScene& scene, const AssessmentContext& context);

/// Writes every output into `folder` (which must exist), report.json last.
/// Returns the files written (relative names).
std::vector<std::string> write_assessment_outputs(const Assessment& a, const AssessmentScene& scene,
                                                  const CornerNormals& normals, const AssessmentContext& context,
                                                  const std::filesystem::path& folder);

}  // namespace clearfit
