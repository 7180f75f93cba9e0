#pragma once
// `clearfit compare A B`: two assessments of the same part, or of two
// revisions with the same contact region. Per-vertex pressure difference
// (B − A, read back from the two heatmap.glb's _PRESSURE_KPA), a difference
// .glb with a diverging colormap, compare.json (schema clearfit.compare/1) and
// compare.html saying which hotspots got better or worse and by how much.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace clearfit::reports {

struct CompareOptions {
  /// Same mesh: equal vertex counts and every position within this (mm).
  double same_position_tolerance_mm = 1e-3;
  /// Otherwise each seen vertex of B takes the pressure of the nearest seen
  /// vertex of A within this distance (mm) ...
  double match_tolerance_mm = 0.5;
  /// ... and at least this share of B's seen vertices must find one, else the
  /// contact regions differ and the comparison is refused.
  double min_matched_fraction = 0.8;
  /// Hotspots of A and B are the same hotspot when their centroids are this close (mm).
  double hotspot_match_mm = 5.0;
  /// A hotspot's peak changed when |Δ| exceeds this many combined standard
  /// deviations sqrt(σ_A² + σ_B²) (and at least 0.1 kPa).
  double significance_sigmas = 2.0;
  /// Folder with report.html's assets (see HtmlReportOptions::assets_dir).
  std::filesystem::path assets_dir;
  /// Throws std::invalid_argument naming the field when a value is not positive and finite.
  void validate() const;
};

struct CompareResult {
  nlohmann::json summary;            ///< the content of compare.json
  std::filesystem::path json, html, glb;
  std::vector<std::string> notes;    ///< e.g. how the vertices were matched
};

/// Compares assessment folders `a` (before) and `b` (after) and writes
/// compare.json, difference.glb and compare.html into `out` (created),
/// each atomically. Throws InputError (naming the folder and what differs)
/// when a folder is not a finished assessment, either has no pressure
/// calibration (_PRESSURE_KPA), or the contact regions do not correspond.
CompareResult compare_assessments(const std::filesystem::path& a, const std::filesystem::path& b,
                                  const std::filesystem::path& out, const CompareOptions& options = {});

}  // namespace clearfit::reports
