#pragma once
// report.html: the fit report a designer opens, generated from an assessment
// output folder (docs/assessment-outputs.md). One self-contained file: the
// 3D viewer script (@google/model-viewer, vendored by web/scripts/vendor-viewer.sh),
// the heatmap models (base64, loaded through blob: URLs because browsers refuse
// fetch() of file:// URLs), the PNGs (data: URIs), styles and scripts are all
// inside, so it opens from the file system with no network and can be mailed.
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace clearfit::reports {

struct HtmlReportOptions {
  /// Folder with report.html's template, CSS, JS and vendor/model-viewer-umd.min.js.
  /// Empty: $CLEARFIT_REPORT_ASSETS_DIR, else the folder compiled in
  /// (CLEARFIT_REPORT_ASSETS_DIR, default reports/assets of the source tree).
  std::filesystem::path assets_dir;
  /// The 3D view shows at most this many triangles; a larger heatmap is
  /// simplified for the page only (reports/src/report_view.cpp: OpenMesh's
  /// quadric decimater, halfedge collapses that keep original vertices and so
  /// their colours; the part's rim and the heatmap's seams are kept exactly),
  /// with a note in HtmlReportResult::notes; heatmap.glb itself is untouched.
  /// 0: never simplify.
  std::size_t max_view_triangles = 400000;
  /// Title above the report; empty: "Fit report: <part mesh file name>".
  std::string title;
};

/// What write_report_html did, for the CLI to print.
struct HtmlReportResult {
  std::filesystem::path html;       ///< the file written (<folder>/report.html)
  std::vector<std::string> notes;   ///< e.g. "3D view simplified from 1000000 to 400000 triangles"
};

/// Reads <output_folder>/report.json (schema clearfit.report/1) and the files
/// it names in "outputs", and writes <output_folder>/report.html atomically.
/// Sections: summary, 3D view (pressure ↔ blanching-signal toggle, colour bar,
/// clickable hotspot markers), warnings, hotspots, chart images, raw and
/// undistorted skin, coverage, calibration (with the study's R² 0.439 as
/// reference), captures, signal, part and chart, provenance. Every string taken
/// from report.json is HTML-escaped. A missing optional output (an image, the
/// .glb) leaves its section with a note instead of failing.
/// Throws InputError when report.json is missing, is not JSON or has another
/// schema (naming the key), or when the assets (template, viewer) are missing
/// (naming the file and how to vendor it).
HtmlReportResult write_report_html(const std::filesystem::path& output_folder, const HtmlReportOptions& options = {});

/// `text` with & < > " ' replaced by character references (safe in element
/// content and in quoted attribute values).
std::string html_escape(std::string_view text);

/// The folder write_report_html reads its assets from when options.assets_dir is empty.
std::filesystem::path default_report_assets_dir();

}  // namespace clearfit::reports
